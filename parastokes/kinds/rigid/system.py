"""A rigid or prescribed-motion body in the MRS fluid (docs/bodies.md, "Rigid bodies").

**State** (docs/contracts.md), (1 + M, 8) for a surface of M points:

- row 0, the pose: ``[c(3), q(4), φ]``: the reference point c, the unit quaternion q = (w, x,
  y, z) of the orientation (body -> lab, :mod:`.rotation`), and the phase φ of the moving part
  (a bacterium's flagellum; 0 for other shapes);
- rows 1..M: the lab-frame surface points x_i = c + R(q) X_i(φ) in the columns 0-2, zeros in
  3-7. They are a function of the pose, kept in the state so that the output writes the
  surface and the error measure (eq. 34) sees the orientation: ``positions`` is every row's
  columns 0-2 (the centre and the surface).

**Rates**, (1 + M, 7): row 0 ``[U, Ω, dφ/dt]``, rows 1..M the velocity of each surface point,
U + Ω × (x − c) + its prescribed surface velocity (informative: ``advance`` does not use them).
The trajectory writes U and Ω of every frame from row 0 (the kind's layout: ``velocity`` and
``angular_velocity`` of the centre), since the state holds the pose only.
Each evaluation solves the mobility problem (:func:`.solve.mobility`): the surface forces and
(U, Ω) such that the surface moves with the body plus its slip and the forces balance the
external force and torque (the augmented system of Khatri & Cortez).

**advance**: c + dt U; q turned exactly by dt Ω (the exponential map); φ + dt dφ/dt; the
surface rebuilt from the new pose. **project**: q renormalized, the surface rebuilt (as the
rod re-orthonormalizes its frames). **bracket**: Ω1 × Ω2 on the pose row (RKMK4, as rods).
**monitor**: the drift ``|‖q‖ − 1|`` (limit 1e-3); infinite when a point is on or below the wall.

**coarsened(factor)**: the same body on a surface of ``factor`` times fewer points, ε scaled with
the spacing, and the exact grid transfer through the pose (:mod:`.coarse`; Remark 4).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from ...bodies.base import replace_params, require_positive
from ...bodies.geometry import crossed_wall
from ...bodies.sources import FluidSources
from ...mobility import ResistanceResult, SolveError, solve_resistance
from ...mobility.checks import MAX_SPACING_OVER_EPS
from ...mobility.errors import OVERFLOW
from ...mrs.velocity import thread_count
from . import rotation
from .coarse import RigidTransfer, coarse_shape
from .shapes import Sphere, spacing
from .slip import Squirmer, UserSlip
from .solve import MobilitySolution, Surface, mobility, placed

__all__ = ["POSE_COLUMNS", "RATE_COLUMNS", "RigidBody"]

#: Columns of the state: c (0-2), q (3-6), φ (7).
POSE_COLUMNS = 8
#: Columns of the rates: U (0-2), Ω (3-5), dφ/dt (6).
RATE_COLUMNS = 7


def _vector(name: str, value: Any, n: int) -> tuple[float, ...]:
    out = tuple(float(v) for v in value)
    if len(out) != n or not all(math.isfinite(v) for v in out):
        raise ValueError(f"{name}: need {n} finite numbers, got {value!r}")
    return out


@dataclass(frozen=True)
class RigidBody:
    """A rigid ``shape`` (:mod:`.shapes`) with an optional surface ``slip`` (:mod:`.slip`) at
    ``position`` with ``orientation`` (a quaternion, normalized), moved by the fluid of
    ``viscosity`` (free space or above the ``wall`` z = 0, background shear u∞ = (γ̇ z, 0, 0))
    under the external ``force`` and ``torque`` (about its reference point; e.g. gravity, a
    magnetic torque); blobs of width ``epsilon`` (absolute) at its surface points."""

    shape: Any = Sphere()  # noqa: RUF009 (a frozen, hashable value)
    slip: Squirmer | UserSlip | None = None
    epsilon: float = 0.05
    viscosity: float = 1.0
    wall: bool = False
    shear_rate: float = 0.0
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    orientation: tuple[float, float, float, float] = rotation.IDENTITY
    force: tuple[float, float, float] = (0.0, 0.0, 0.0)
    torque: tuple[float, float, float] = (0.0, 0.0, 0.0)
    n_threads: int | None = None
    #: The blobs' width over the parameter ε of ``params`` (1; a coarse surface's h_c / h, so
    #: that Lagrange nodes in ε mean the same on both surfaces: :meth:`coarsened`).
    epsilon_scale: float = 1.0

    #: Rates include angular velocities (for scenes); the surface forces come from a solve.
    angular: ClassVar[bool] = True
    rate_columns: ClassVar[int] = RATE_COLUMNS

    def __post_init__(self) -> None:
        require_positive(epsilon=self.epsilon, viscosity=self.viscosity,
                         epsilon_scale=self.epsilon_scale)
        for name, n in (("position", 3), ("force", 3), ("torque", 3), ("orientation", 4)):
            object.__setattr__(self, name, _vector(name, getattr(self, name), n))
        q = rotation.normalized(np.array(self.orientation))
        if abs(float(np.linalg.norm(self.orientation)) - 1.0) > 1e-15:  # keep unit input's bits
            object.__setattr__(self, "orientation", tuple(float(v) for v in q))
        if not math.isfinite(self.shear_rate):
            raise ValueError(f"shear_rate: must be finite, got {self.shear_rate!r}")
        if self.slip is not None and not isinstance(self.slip, Squirmer | UserSlip):
            raise ValueError(f"slip: a Squirmer, a UserSlip or None, got {self.slip!r}")
        if isinstance(self.slip, Squirmer) and not isinstance(self.shape, Sphere):
            raise ValueError("slip: the squirmer's slip is defined on a sphere; use "
                             f"shape = Sphere, not {type(self.shape).__name__}")
        thread_count(self.n_threads)
        gap = spacing(self.shape)  # (the one rule of mobility.checks.check_surface)
        if gap > MAX_SPACING_OVER_EPS * self.epsilon:
            raise ValueError(
                f"epsilon: the surface is too coarse for ε = {self.epsilon:g}: its largest gap "
                f"between neighbouring points is {gap:.3g} > {MAX_SPACING_OVER_EPS:g} ε, so the "
                f"fluid leaks between the blobs; use more points or ε >= "
                f"{gap / MAX_SPACING_OVER_EPS:.3g}")
        if self.wall and crossed_wall(self.initial_state(), True):
            low = float(self.initial_state()[:, 2].min())
            raise ValueError(
                f"position: the body reaches z = {low:.3g} <= 0, on or below the wall z = 0; "
                f"raise position[2] by more than {-low:.3g}")
        if self.wall and self._inside_at_wall():
            raise ValueError(
                f"position: the body's shape reaches below the wall z = 0 between its surface "
                f"points (its centre is at z = {self.position[2]:.4g}); raise position[2]")

    def _inside_at_wall(self, samples: int = 41) -> bool:
        """Whether the wall plane z = 0 cuts the body's shape (not only its points: a sphere of
        radius 1 at z = 0.997 has all its points above the wall): the plane's points under the
        body, on a grid as wide as the body, tested with the shape's ``contains``."""
        state = self.initial_state()
        c, q, _ = self.pose(state)
        reach = float(np.max(np.linalg.norm(self.shape.points(0.0), axis=1)))
        side = np.linspace(-reach, reach, samples)
        u, v = np.meshgrid(side, side)
        plane = np.stack([c[0] + u.ravel(), c[1] + v.ravel(), np.zeros(u.size)], axis=1)
        return bool(self.shape.contains((plane - c) @ rotation.matrix(q)).any())

    # ---- geometry --------------------------------------------------------------------------
    @property
    def n_surface(self) -> int:
        return len(self.shape.points(0.0))

    def pose(self, state: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """(c, q, φ) of a state."""
        return state[0, :3], state[0, 3:7], float(state[0, 7])

    def surface_points(self, center: np.ndarray, q: np.ndarray, phase: float) -> np.ndarray:
        """The lab-frame surface points c + R(q) X(φ), (M, 3)."""
        return center + self.shape.points(phase) @ rotation.matrix(q).T

    def state_of(self, center: np.ndarray, q: np.ndarray, phase: float) -> np.ndarray:
        """The state of a pose (see the module)."""
        out = np.zeros((1 + self.n_surface, POSE_COLUMNS))
        out[0, :3], out[0, 3:7], out[0, 7] = center, q, phase
        out[1:, :3] = self.surface_points(center, q, phase)
        return out

    def inside(self, state: np.ndarray, points: np.ndarray) -> np.ndarray:
        """Which lab-frame ``points`` lie inside this body at ``state``."""
        c, q, _ = self.pose(state)
        return self.shape.contains((points - c) @ rotation.matrix(q))

    def state_entries(self) -> np.ndarray:
        """Which entries of the state carry data (the pose row, the surface points' columns
        0-2); the others are zero by construction (``parastokes flow`` rebuilds a state from
        the saved data entries, :mod:`parastokes.flow.run`)."""
        out = np.zeros((1 + self.n_surface, POSE_COLUMNS), dtype=bool)
        out[0], out[1:, :3] = True, True
        return out

    def initial_state(self) -> np.ndarray:
        return self.state_of(np.array(self.position), np.array(self.orientation), 0.0)

    def positions(self, state: np.ndarray) -> np.ndarray:
        """The centre and the surface points (every row's columns 0-2)."""
        return np.array(state[:, :3])

    # ---- the mobility problem --------------------------------------------------------------
    def surface(self, t: float, state: np.ndarray) -> Surface:
        """This body's :class:`.solve.Surface` at ``(t, state)``: lab points, prescribed surface
        velocity (slip and moving parts, rotated to the lab frame), external loads."""
        c, q, phase = self.pose(state)
        body = self.shape.points(phase)
        moving = self.shape.moving(phase)
        if self.slip is not None:
            moving = moving + self.slip.velocity(t, body)
        r = rotation.matrix(q)
        fixed = self.shape.phase_rate == 0.0  # the surface does not move in the body frame
        return Surface(np.ascontiguousarray(state[1:, :3]), np.array(c), float(self.epsilon),
                       moving @ r.T, np.array(self.force), np.array(self.torque), r, body,
                       self.shape if fixed else None, type(self.shape).__name__.lower())

    def background(self, points: np.ndarray) -> np.ndarray | None:
        """u∞ = (γ̇ z, 0, 0) at ``points`` (None without shear)."""
        if self.shear_rate == 0.0:
            return None
        out = np.zeros_like(points)
        out[:, 0] = self.shear_rate * points[:, 2]
        return out

    def solve(self, t: float, state: np.ndarray) -> MobilitySolution:
        """The mobility problem at ``(t, state)`` (:func:`.solve.mobility`)."""
        surface = self.surface(t, state)
        return mobility([surface], self.viscosity, self.wall, self.background(surface.points),
                        self.n_threads)

    def resistance(self, t: float, state: np.ndarray, u: Any, omega: Any) -> ResistanceResult:
        """The resistance problem at ``(t, state)``: the surface forces (and their total force
        and torque) that make the body move at (``u``, ``omega``) with its slip, in its
        background (:func:`parastokes.mobility.solve_resistance`)."""
        surface = self.surface(t, state)
        return solve_resistance(placed(surface), u, omega, mu=self.viscosity, wall=self.wall,
                                slip=surface.slip, background=self.background(surface.points),
                                n_threads=self.n_threads)

    def motion_rates(self, state: np.ndarray, u: np.ndarray, omega: np.ndarray,
                     prescribed: np.ndarray) -> np.ndarray:
        """The rates (see the module) of the body moving at (``u``, ``omega``), its surface
        points moving with it plus ``prescribed`` (lab frame)."""
        out = np.zeros((len(state), RATE_COLUMNS))
        out[0, :3], out[0, 3:6], out[0, 6] = u, omega, self.shape.phase_rate
        out[1:, :3] = u + np.cross(omega, state[1:, :3] - state[0, :3]) + prescribed
        return out

    def rates(self, t: float, state: np.ndarray) -> np.ndarray:
        """(U, Ω) of the mobility solve, dφ/dt, and the surface velocities; a state that is not
        finite (a stage after a motion that overflowed) is a :class:`SolveError`."""
        if not np.isfinite(state).all():
            raise SolveError(f"the state of the rigid body is not finite at t = {t:.6g} (its "
                             f"motion in the step overflowed): {OVERFLOW}")
        solution = self.solve(t, state)
        return self.motion_rates(state, solution.U[0], solution.Omega[0],
                                 self.surface(t, state).slip)

    def fluid_sources(self, t: float, state: np.ndarray) -> FluidSources:
        """The surface forces of the mobility solve at the surface points."""
        points = np.array(state[1:, :3])
        return FluidSources(points, self.solve(t, state).forces, None,
                            np.full(len(points), float(self.epsilon)))

    # ---- stepping --------------------------------------------------------------------------
    def advance(self, state: np.ndarray, rates: np.ndarray, dt: float) -> np.ndarray:
        """c + dt U, q turned by dt Ω exactly, φ + dt dφ/dt; the surface rebuilt."""
        c, q, phase = self.pose(state)
        u, omega, phase_rate = rates[0, :3], rates[0, 3:6], float(rates[0, 6])
        return self.state_of(c + dt * u, rotation.exp_rotate(q, omega, dt),
                             phase + dt * phase_rate)

    @staticmethod
    def bracket(r1: np.ndarray, r2: np.ndarray) -> np.ndarray:
        """[U, Ω, φ̇] x [U', Ω', φ̇'] -> [0, Ω × Ω', 0] on the pose row (R³ × SO(3) × R)."""
        out = np.zeros_like(r1)
        out[0, 3:6] = np.cross(r1[0, 3:6], r2[0, 3:6])
        return out

    def project(self, state: np.ndarray) -> np.ndarray:
        """q renormalized and the surface rebuilt from the pose."""
        c, q, phase = self.pose(state)
        return self.state_of(np.array(c), rotation.normalized(q), phase)

    # ---- parameters and monitor ------------------------------------------------------------
    @property
    def params(self) -> dict[str, float]:
        """ε (the blobs' width over ``epsilon_scale``: the fine surface's ε on a coarse one) and
        the viscosity."""
        if self.epsilon_scale == 1.0:
            return {"epsilon": self.epsilon, "viscosity": self.viscosity}
        return {"epsilon": self.epsilon / self.epsilon_scale, "viscosity": self.viscosity}

    def with_params(self, **theta: float) -> RigidBody:
        """A copy with ``epsilon`` and/or ``viscosity`` changed (each solver its own operator);
        the blobs' width is ``epsilon_scale`` times the given ε."""
        if "epsilon" in theta and self.epsilon_scale != 1.0:
            theta = {**theta, "epsilon": float(theta["epsilon"]) * self.epsilon_scale}
        return replace_params(self, theta)

    def coarsened(self, factor: int) -> tuple[RigidBody, RigidTransfer]:
        """The same body on a coarser surface (``factor`` times fewer points per part, ε scaled
        with the spacing) and the grid transfer (Remark 4; :mod:`.coarse`)."""
        shape = coarse_shape(self.shape, factor)
        ratio = spacing(shape) / spacing(self.shape)
        coarse = dataclasses.replace(self, shape=shape, epsilon=self.epsilon * ratio,
                                     epsilon_scale=self.epsilon_scale * ratio)
        return coarse, RigidTransfer(self, coarse)

    @property
    def monitor_limit(self) -> float:
        """1e-3: the exponential map keeps ``|q| = 1`` to round-off, but Parareal's corrections
        (linear combinations of states, before ``project``) move it by about their error."""
        return 1e-3

    def monitor(self, state: np.ndarray) -> float:
        """``|‖q‖ − 1|``; infinite when a point is on or below the wall."""
        if crossed_wall(state, self.wall):
            return math.inf
        return abs(float(np.linalg.norm(state[0, 3:7])) - 1.0)

