"""The rod system: Kirchhoff rods in Stokes flow (paper section 5.1; docs/physics.md section 3),
and its public factories (:func:`rod`, :func:`rod_swimmer`, defaults = Table 2).

Rods in free space or above the no-slip wall z = 0; point forces and torques (eq. 12) drive u and w
through the regularized Stokeslet/rotlet kernels with images (docs/physics.md (1)-(8));
Θ = (ε, μ, a). The system is a frozen dataclass of scalars (the initial shape is rebuilt on
demand), so it pickles in a few hundred bytes. Importing this module registers its compiled loop
(:mod:`.compiled`) and its GPU device parts (:mod:`.device`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import ClassVar, TypedDict

import numpy as np
import scipy.sparse as sp

from ...bodies import frames, geometry
from ...bodies.base import FluidBody, replace_params, require_positive
from ...bodies.geometry import crossed_wall
from ...fluid import MRS, Blocks
from ...integrate import loop
from ...mrs.velocity import thread_count
from ...registry import loops as registry
from ...stiff.coloring import banded
from ...stiff.jacobian import fd_step
from . import mechanics as kirchhoff
from .compiled import rod_data
from .jacobian import load_blocks
from .transfer import RodTransfer

__all__ = ["TABLE2", "RodSystem", "rod", "rod_swimmer"]


@lru_cache(maxsize=64)
def _wave_table(n_half: int, ds: float, wavenumber: float) -> np.ndarray:
    table = kirchhoff.wave_table(n_half, ds, wavenumber)
    table.flags.writeable = False
    return table


@dataclass(frozen=True)
class RodSystem(FluidBody):
    """``n_rods`` Kirchhoff rods of ``n_points`` nodes each, interacting through the fluid.

    Rods start straight along x (geometry.straight_rods), side by side in y, at ``height`` above the
    wall. The preferred strain is ``preferred + (0, -k² A sin(k s + f t), 0)`` (eq. 36), k = 2π/λ.
    ``bending`` is the common value a of a1 = a2 = a3 (section 5.1); ``shear`` = (b1, b2, b3).
    State rows: ``[X, D1, D2, D3]``; rates rows ``[u, w]``.
    """

    n_rods: int = 1
    n_points: int = 301
    length: float = 60.0
    epsilon: float = 1.0
    viscosity: float = 1e-6
    bending: float = 1.0
    shear: tuple[float, float, float] = (0.6, 0.6, 0.6)
    preferred: tuple[float, float, float] = (0.0, 0.0, 0.0)
    amplitude: float = 0.0
    wavelength: float = 30.0
    frequency: float = 0.0
    wall: bool = True
    height: float = 10.0
    spacing: float = 5.0
    n_threads: int | None = None
    target_blocks: Blocks | None = None

    def __post_init__(self) -> None:
        for name in ("n_rods", "n_points"):
            value = getattr(self, name)
            if not isinstance(value, int | np.integer) or value < (1 if name == "n_rods" else 3):
                raise ValueError(
                    f"{name}: must be an integer >= {1 if name == 'n_rods' else 3}, got {value!r}"
                )
        require_positive(
            length=self.length,
            epsilon=self.epsilon,
            viscosity=self.viscosity,
            bending=self.bending,
            wavelength=self.wavelength,
            spacing=self.spacing,
        )
        if len(self.shear) != 3 or min(self.shear) <= 0:
            raise ValueError(f"shear: need three moduli > 0, got {self.shear!r}")
        if len(self.preferred) != 3:
            raise ValueError(f"preferred: need three strains, got {self.preferred!r}")
        if self.wall:
            require_positive(height=self.height)
        thread_count(self.n_threads)  # ValueError now, not at the first step

    # ---- geometry --------------------------------------------------------------------------
    @property
    def ds(self) -> float:
        """Node spacing Δs = σ."""
        return self.length / (self.n_points - 1)

    @property
    def mechanics(self) -> tuple:
        """The arguments of the compiled mechanics: ``(n_rods, ds, a, b, table, constant,
        amplitude, wavenumber, frequency)``, with a = (a, a, a) and b the moduli, ``table`` the
        cached (read-only) :func:`.mechanics.wave_table` of the half points and the rest those of
        :func:`.mechanics.preferred_strain` (eq. 36)."""
        wavenumber = 2.0 * math.pi / self.wavelength
        return (
            self.n_rods,
            self.ds,
            np.full(3, float(self.bending)),
            np.asarray(self.shear, dtype=float),
            _wave_table(self.n_points - 1, self.ds, wavenumber),
            tuple(float(v) for v in self.preferred),
            float(self.amplitude),
            wavenumber,
            float(self.frequency),
        )

    def preferred_strain(self, t: float) -> np.ndarray:
        """Ω̂ at the half points s_{k+½} at time t, shape (M - 1, 3) (eq. 36)."""
        table, *wave = self.mechanics[4:]
        return kirchhoff.preferred_strain(table, float(t), *wave)

    def initial_state(self) -> np.ndarray:
        return geometry.straight_rods(
            self.n_rods, self.n_points, self.length, self.height, self.spacing
        )

    def positions(self, state: np.ndarray) -> np.ndarray:
        return np.array(state[:, :3])

    # ---- physics ---------------------------------------------------------------------------
    def loads(self, t: float, state: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Point forces and torques on the fluid (eq. 12), two (n, 3) arrays."""
        n_rods, ds, a, b, table, *wave = self.mechanics
        omega_hat = kirchhoff.preferred_strain(table, float(t), *wave)
        return kirchhoff.rod_loads(state, n_rods, ds, a, b, omega_hat)

    def load_coupling(self):
        """The loads at a node depend on the node and its two neighbours on its rod (eq. 12:
        the segments on either side); the pattern of the coloured finite-difference Jacobian of
        :mod:`parastokes.stiff`."""
        return banded(self.n_rods, self.n_points, 1)

    def load_jacobian(self, t: float, state: np.ndarray) -> sp.bsr_array:
        """The Jacobian of :meth:`loads` (rows [f, n] per node) in the rates' coordinates
        (columns [u, w] per node): 6 x 6 blocks on the pattern of :meth:`load_coupling`, by the
        compiled segment-wise central differences of :mod:`.jacobian` (the hook of
        :func:`parastokes.stiff.jacobian.load_jacobian`)."""
        n_rods, ds, a, b, table, *wave = self.mechanics
        state = np.ascontiguousarray(state, dtype=float)
        pattern = banded(self.n_rods, self.n_points, 1)  # the rod's own, not a subclass's
        blocks = load_blocks(state, n_rods, ds, a, b,
                             kirchhoff.preferred_strain(table, float(t), *wave),
                             fd_step(state), pattern.indptr, pattern.indices)
        return sp.bsr_array((blocks, pattern.indices, pattern.indptr),
                            shape=(6 * len(state), 6 * len(state)))

    #: Rates carry angular velocities (for :class:`parastokes.scene.Scene`).
    angular: ClassVar[bool] = True

    @staticmethod
    def body_rates(u: np.ndarray, w: np.ndarray) -> np.ndarray:
        """``[u, w]`` per node from the fluid's linear and angular velocity at the nodes."""
        return np.concatenate([u, w], axis=1)

    def rates(self, t: float, state: np.ndarray) -> np.ndarray:
        """``[u, w]`` per node (docs/physics.md (13)): velocities from all points of all rods."""
        f, n = self.loads(t, state)
        u, w = self.fluid.velocity(state[:, :3], f, epsilon=self.epsilon, torques=n, angular=True)
        return self.body_rates(u, w)

    def advance(self, state: np.ndarray, rates: np.ndarray, dt: float) -> np.ndarray:
        """X + dt u; frames rotated by ``|w| dt`` about w (Rodrigues, eq. 13)."""
        return frames.advance_rod(state, rates, dt)

    @staticmethod
    def bracket(r1: np.ndarray, r2: np.ndarray) -> np.ndarray:
        """Lie bracket of two rates: [u, w] x [u', w'] -> [0, w × w'] (so(3) per node; RKMK4)."""
        out = np.zeros_like(r1)
        out[:, 3:] = np.cross(r1[:, 3:], r2[:, 3:])
        return out

    def project(self, state: np.ndarray) -> np.ndarray:
        """Re-orthonormalize every frame (nearest rotation); positions unchanged."""
        return frames.orthonormalize(np.ascontiguousarray(state, dtype=float))

    # ---- parameters and monitor ------------------------------------------------------------
    @property
    def params(self) -> dict[str, float]:
        return {"epsilon": self.epsilon, "viscosity": self.viscosity, "bending": self.bending}

    def with_params(self, **theta: float) -> RodSystem:
        """A copy with some of ``epsilon``, ``viscosity``, ``bending`` (= a1 = a2 = a3) changed."""
        return replace_params(self, theta)

    @property
    def monitor_limit(self) -> float:
        return 0.01

    def monitor(self, state: np.ndarray) -> float:
        """Largest relative change of a rod's length Σ|X_{k+1} - X_k| from L (section 5.1);
        infinite when a node is on or below the wall."""
        if crossed_wall(state, self.wall):
            return math.inf
        return float(kirchhoff.length_change(state, self.n_rods, self.length))

    # ---- coarse grid (Remark 4) ------------------------------------------------------------
    def coarsened(self, factor: int) -> tuple[RodSystem, RodTransfer]:
        """The same rods on nodes σ_c = factor·σ_f (same ε in absolute units) and the transfer.

        ``factor`` must divide M - 1 (e.g. 6: 301 -> 51 nodes).
        """
        if not isinstance(factor, int | np.integer) or factor < 1:
            raise ValueError(f"factor: must be a positive integer, got {factor!r}")
        if (self.n_points - 1) % factor or (self.n_points - 1) // factor < 2:
            raise ValueError(
                f"factor: {factor} must divide n_points - 1 = {self.n_points - 1} "
                "and leave at least 3 nodes"
            )
        m_c = (self.n_points - 1) // factor + 1
        coarse = dataclasses.replace(self, n_points=m_c)
        return coarse, RodTransfer(self.n_rods, self.n_points, m_c)


class _Table2(TypedDict):
    length: float
    amplitude: float
    frequency: float
    wavelength: float
    bending: float
    shear: tuple[float, float, float]
    height: float
    viscosity: float


#: Table 2 of the paper (units μm, s, g).
TABLE2: _Table2 = {
    "length": 60.0,
    "amplitude": 1.0,
    "frequency": 40.0 * math.pi,
    "wavelength": 30.0,
    "bending": 1.0,
    "shear": (0.6, 0.6, 0.6),
    "height": 10.0,
    "viscosity": 1e-6,
}


def _three(name: str, values: Sequence[float], what: str) -> tuple[float, float, float]:
    """``values`` as three floats; any other length is RodSystem's ValueError, raised here."""
    if len(values) != 3:
        raise ValueError(f"{name}: need three {what}, got {tuple(float(v) for v in values)!r}")
    a, b, c = values
    return float(a), float(b), float(c)


def rod(
    n_rods: int = 1,
    n_points: int = 301,
    epsilon: float = 1.0,
    *,
    length: float = TABLE2["length"],
    preferred: tuple[float, float, float] = (0.0, 0.0, 0.0),
    amplitude: float = 0.0,
    wavelength: float = TABLE2["wavelength"],
    frequency: float = 0.0,
    bending: float = TABLE2["bending"],
    shear: tuple[float, float, float] = TABLE2["shear"],
    viscosity: float = TABLE2["viscosity"],
    wall: bool = True,
    height: float = TABLE2["height"],
    spacing: float = 5.0,
    n_threads: int | None = None,
) -> RodSystem:
    """Kirchhoff rods, initially straight along x: X(s) = (s, y_j, height), D3 = e_x, D1 = e_y,
    D2 = e_z, with preferred strain ``preferred + (0, -k² A sin(k s + f t), 0)``, k = 2π/λ.

    ``epsilon`` is absolute (μm); ``bending`` = a1 = a2 = a3; ``shear`` = (b1, b2, b3); rods are
    ``spacing`` apart in y. ``wall=False`` puts the rods in free space.
    """
    return RodSystem(
        n_rods=n_rods,
        n_points=n_points,
        length=float(length),
        epsilon=epsilon,
        viscosity=viscosity,
        bending=bending,
        shear=_three("shear", shear, "moduli > 0"),
        preferred=_three("preferred", preferred, "strains"),
        amplitude=float(amplitude),
        wavelength=wavelength,
        frequency=float(frequency),
        wall=wall,
        height=float(height),
        spacing=spacing,
        n_threads=n_threads,
    )


def rod_swimmer(
    n_rods: int = 1,
    n_points: int = 301,
    epsilon: float = 1.0,
    *,
    amplitude: float = TABLE2["amplitude"],
    frequency: float = TABLE2["frequency"],
    wavelength: float = TABLE2["wavelength"],
    **kwargs,
) -> RodSystem:
    """The paper's swimmer (section 5.1): Table 2 values, M = 301 (Δs = σ_f = 0.2), ε = 5 σ_f,
    above the wall z = 0 at height 10, preferred strain Ω̂ = (0, -k² A sin(k s + f t), 0) (eq. 36).

    ``frequency`` may be negative (the authors' own code uses sin(k s - f t)). ``n_rods`` rods lie
    side by side in y, 5 μm apart (section 5.1.4 uses five). Other keywords go to :func:`rod`.
    """
    return rod(
        n_rods,
        n_points,
        epsilon,
        amplitude=amplitude,
        frequency=frequency,
        wavelength=wavelength,
        **kwargs,
    )


loop.register_parts(RodSystem, rod_data, fluid=MRS, in_scenes=True)
registry.register_device(RodSystem, "parastokes.kinds.rod.device:PARTS")
