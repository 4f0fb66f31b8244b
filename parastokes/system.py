"""Systems: bodies + fluid + background flow + physical parameters Θ (docs/contracts.md).

- :class:`RodSystem`: Kirchhoff rods (paper section 5.1; physics.md section 3) in free space or
  above the no-slip wall z = 0; point forces and torques (eq. 12) drive u and w through the
  regularized Stokeslet/rotlet kernels with images (physics.md (1)-(8)); Θ = (ε, μ, a).
- :class:`VesicleSystem`: the spring-network sphere (section 5.2; physics.md section 4) in free
  space and the shear flow u∞ = (γ̇ z, 0, 0) (eq. 6 and physics.md (15)); Θ = (ε, μ, κ).

Systems are frozen dataclasses of scalars (the rod's initial shape and the vesicle's mesh are
rebuilt from them on demand, the mesh cached per process), so they pickle in a few hundred bytes.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, ClassVar

import numpy as np

from .bodies import frames, geometry, rod, vesicle
from .bodies.rod_transfer import RodTransfer
from .fluid import MRS, BlockedMRS, TargetBlocks
from .mrs.velocity import thread_count
from .stepping import loop, registry
from .stepping.registry import RunSteps
from .stepping.rod import rod_data
from .stepping.vesicle import vesicle_data

__all__ = ["FluidBody", "PointsInShear", "RodSystem", "VesicleSystem", "replace_params"]


def _require_positive(**values: float) -> None:
    for name, value in values.items():
        if not (isinstance(value, int | float | np.number) and math.isfinite(value) and value > 0):
            raise ValueError(f"{name}: must be a finite number > 0, got {value!r}")


@lru_cache(maxsize=64)
def _wave_table(n_half: int, ds: float, wavenumber: float) -> np.ndarray:
    table = rod.wave_table(n_half, ds, wavenumber)
    table.flags.writeable = False
    return table


class FluidBody:
    """A body whose point loads act on the MRS fluid of its ``viscosity``, ``wall`` (if it has
    one), ``n_threads`` and ``target_blocks`` (:mod:`parastokes.fluid`)."""

    @property
    def fluid(self) -> MRS:
        """:class:`~parastokes.fluid.MRS`, or :class:`~parastokes.fluid.BlockedMRS` with
        ``target_blocks`` (the spatially parallel fine solver of Remark 1)."""
        wall = bool(getattr(self, "wall", False))
        if self.target_blocks is None:
            return MRS(self.viscosity, wall, self.n_threads)
        return BlockedMRS(self.viscosity, wall, self.n_threads, self.target_blocks)


class PointsInShear(FluidBody):
    """Points that move with the fluid under the forces ``forces(state)`` they exert (no frames,
    no torques), in the background shear u∞ = (γ̇ z, 0, 0), γ̇ = ``shear_rate`` (physics.md (15)).
    The state is the positions, ``project`` the identity."""

    #: Rates are velocities only (no angular part); for :class:`parastokes.scene.Scene`.
    angular: ClassVar[bool] = False

    def loads(self, t: float, state: np.ndarray) -> tuple[np.ndarray, None]:
        """The point forces on the fluid, no torques."""
        return self.forces(state), None

    @staticmethod
    def body_rates(u: np.ndarray, w: np.ndarray) -> np.ndarray:
        """The rates from the fluid velocity at the points (background included): ``u``."""
        return u

    def rates(self, t: float, state: np.ndarray) -> np.ndarray:
        """u∞(X) + Stokeslet velocities (eq. 6) of the forces."""
        u = self.fluid.velocity(state, self.forces(state), epsilon=self.epsilon)
        u[:, 0] += self.shear_rate * state[:, 2]
        return u

    def advance(self, state: np.ndarray, rates: np.ndarray, dt: float) -> np.ndarray:
        return state + dt * rates

    def project(self, state: np.ndarray) -> np.ndarray:
        """The identity (no frames); returns ``state`` itself."""
        return state

    def positions(self, state: np.ndarray) -> np.ndarray:
        return np.array(state)


def replace_params(system: Any, theta: dict[str, float]) -> Any:
    """``dataclasses.replace`` restricted to the names of ``system.params``."""
    unknown = sorted(set(theta) - set(system.params))
    if unknown:
        raise ValueError(
            f"with_params: unknown parameter(s) {unknown}; allowed: {sorted(system.params)}"
        )
    return dataclasses.replace(system, **{k: float(v) for k, v in theta.items()})


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
    target_blocks: TargetBlocks | None = None

    def __post_init__(self) -> None:
        for name in ("n_rods", "n_points"):
            value = getattr(self, name)
            if not isinstance(value, int | np.integer) or value < (1 if name == "n_rods" else 3):
                raise ValueError(
                    f"{name}: must be an integer >= {1 if name == 'n_rods' else 3}, got {value!r}"
                )
        _require_positive(
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
            _require_positive(height=self.height)
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
        cached (read-only) :func:`parastokes.bodies.rod.wave_table` of the half points and the
        rest those of :func:`parastokes.bodies.rod.preferred_strain` (eq. 36)."""
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
        return rod.preferred_strain(table, float(t), *wave)

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
        return rod.rod_loads(state, n_rods, ds, a, b, rod.preferred_strain(table, float(t), *wave))

    #: Rates carry angular velocities (for :class:`parastokes.scene.Scene`).
    angular: ClassVar[bool] = True

    @staticmethod
    def body_rates(u: np.ndarray, w: np.ndarray) -> np.ndarray:
        """``[u, w]`` per node from the fluid's linear and angular velocity at the nodes."""
        return np.concatenate([u, w], axis=1)

    def rates(self, t: float, state: np.ndarray) -> np.ndarray:
        """``[u, w]`` per node (physics.md (13)): velocities from all points of all rods."""
        f, n = self.loads(t, state)
        u, w = self.fluid.velocity(state[:, :3], f, epsilon=self.epsilon, torques=n, angular=True)
        return self.body_rates(u, w)

    def advance(self, state: np.ndarray, rates: np.ndarray, dt: float) -> np.ndarray:
        """X + dt u; frames rotated by |w| dt about w (Rodrigues, eq. 13)."""
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
    def run_steps(self) -> RunSteps | None:
        """The compiled loop of :mod:`parastokes.stepping` registered for this exact type (None
        for a subclass: it may compute other rates; see :mod:`parastokes.stepping.registry`)."""
        return registry.compiled_loop(self)

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
        """Largest relative change of a rod's length Σ|X_{k+1} - X_k| from L (section 5.1)."""
        return float(rod.length_change(state, self.n_rods, self.length))

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


@lru_cache(maxsize=8)
def _spring_network(subdivisions: int) -> tuple[np.ndarray, np.ndarray, float]:
    """Edges, rest lengths and area of the initial icosphere (cached, read-only)."""
    verts, tris = geometry.icosphere(subdivisions)
    edges = geometry.mesh_edges(tris)
    rest = geometry.edge_lengths(verts, edges)
    edges.setflags(write=False)
    rest.setflags(write=False)
    return edges, rest, geometry.surface_area(verts, tris)


@dataclass(frozen=True)
class VesicleSystem(PointsInShear):
    """Unit icosphere (``subdivisions`` levels) with springs on its edges in a shear flow.

    Rest lengths are the initial edge lengths; ε is absolute (the paper quotes ε = 0.3 l_max, see
    :func:`parastokes.models.vesicle`); κ = ``stiffness``; u∞ = (γ̇ z, 0, 0), γ̇ = ``shear_rate``.
    """

    subdivisions: int
    epsilon: float
    viscosity: float
    stiffness: float
    shear_rate: float
    n_threads: int | None = None
    target_blocks: TargetBlocks | None = None
    center: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        geometry.icosphere(self.subdivisions)  # validates subdivisions
        _require_positive(epsilon=self.epsilon, viscosity=self.viscosity, stiffness=self.stiffness)
        if not math.isfinite(self.shear_rate):
            raise ValueError(f"shear_rate: must be finite, got {self.shear_rate!r}")
        thread_count(self.n_threads)  # ValueError now, not at the first step

    @property
    def mesh(self) -> tuple[np.ndarray, np.ndarray]:
        """(vertices, triangles) of the initial sphere (cached, read-only)."""
        return geometry.icosphere(self.subdivisions)

    @property
    def edges(self) -> np.ndarray:
        return _spring_network(self.subdivisions)[0]

    @property
    def rest_lengths(self) -> np.ndarray:
        return _spring_network(self.subdivisions)[1]

    @property
    def initial_area(self) -> float:
        return _spring_network(self.subdivisions)[2]

    def initial_state(self) -> np.ndarray:
        """The icosphere's vertices around ``center``."""
        return self.mesh[0] + np.asarray(self.center, dtype=float)

    def forces(self, state: np.ndarray) -> np.ndarray:
        """Spring forces on the fluid (physics.md (14))."""
        return vesicle.spring_forces(state, self.edges, self.rest_lengths, self.stiffness)

    run_steps = RodSystem.run_steps

    @property
    def params(self) -> dict[str, float]:
        return {"epsilon": self.epsilon, "viscosity": self.viscosity, "stiffness": self.stiffness}

    def with_params(self, **theta: float) -> VesicleSystem:
        """A copy with some of ``epsilon``, ``viscosity``, ``stiffness`` (κ) changed."""
        return replace_params(self, theta)

    @property
    def monitor_limit(self) -> float:
        return 1e-4

    def monitor(self, state: np.ndarray) -> float:
        """Relative change of the surface area from the initial sphere's (section 5.2)."""
        area = geometry.surface_area(state, self.mesh[1])
        return abs(area - self.initial_area) / self.initial_area


loop.register_parts(RodSystem, rod_data, fluid=MRS, in_scenes=True)
loop.register_parts(VesicleSystem, vesicle_data, fluid=MRS, in_scenes=True)
