"""The rigid body kinds: ``rigid`` (a shape with an optional user slip), ``squirmer`` and
``bacterium`` (docs/bodies.md, "Rigid bodies"; config keys in docs/config.md).

All three share the pose, the fluid and the loads (:class:`RigidBase`) and build a
:class:`.system.RigidBody`; ε may be given in the unit ``"spacing"``, the largest gap between
neighbouring surface points. Resolving a section builds the body (which refuses a surface too
coarse for its ε and a body on or below the wall) and solves its mobility problem once, so that
``parastokes check`` names a singular system before the run. Output: the centre (one point,
``<name>_center``, with the rest of the pose as its node data ``orientation``, the quaternion,
and ``phase``, φ, so that ``parastokes flow`` rebuilds the full state) and the surface
(``<name>_surface``) as point clouds.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import Field, field_validator

from ...core.contracts import StepFailure
from ...registry.kinds import (
    BodyKind,
    BodyLayout,
    BodyResolution,
    BodySection,
    PlannedSize,
    Positive,
    axis_stretch,
    draw_over_time,
    point_layout,
)
from .coarse import coarse_shape
from .shapes import (
    MOTOR_RATE,
    Bacterium,
    Helix,
    PointCloud,
    Rod,
    Sphere,
    Spheroid,
    spacing,
)
from .slip import Squirmer, UserSlip
from .system import RigidBody

__all__ = ["BACTERIUM", "RIGID", "SQUIRMER", "SQUIRMER_MIN_POINTS", "BacteriumModel", "RigidModel",
           "SquirmerModel", "check_solvable"]

Finite = Annotated[float, Field(allow_inf_nan=False)]
#: Largest relative residual of the trial solve that ``check`` accepts.
SOLVE_TOLERANCE = 1e-6
#: Bytes per (surface point)² of a rigid body's factorization: M, (3N)² doubles, and its LU.
DENSE_BYTES = 2 * 9 * 8
#: Fewest surface points of a squirmer: below it the free speed is off Blake's 2 B1 / 3 by an
#: amount that does not fall as points are added, and the points' asymmetry makes it drift
#: sideways and turn (measured in docs/validation.md, "A squirmer's fewest points").
SQUIRMER_MIN_POINTS = 50


def _three(default: list[float], what: str) -> Any:
    return Field(default, min_length=3, max_length=3, description=what)


def check_solvable(body: RigidBody, name: str = "model") -> None:
    """ValueError naming ``name`` when the mobility solve of ``body`` at its initial state fails
    (:class:`~parastokes.mobility.SolveError`: non-finite, or a residual beyond the solver's
    tolerance) or its system is singular or ill-conditioned (a trial solve with a residual above
    :data:`SOLVE_TOLERANCE`)."""
    try:
        solution = body.solve(0.0, body.initial_state())
    except np.linalg.LinAlgError as error:
        residual, reason = math.inf, str(error)
    except StepFailure as error:  # a SolveError, or a slip that is not finite
        raise ValueError(f"{name}: at the initial state, {error}") from None
    else:
        residual = solution.residual
        reason = f"relative residual {residual:.3g}"
    if not residual <= SOLVE_TOLERANCE:
        raise ValueError(
            f"{name}: the mobility system is singular or ill-conditioned ({reason}): the surface "
            "cannot resist every rigid motion (e.g. points on one line cannot resist a turn "
            "about it); use a shape with points off its axis, or a larger epsilon")


class RigidBase(BodySection):
    """The keys every rigid body has: ε, the fluid, the pose and the external loads."""

    epsilon: Positive = Field(0.5, description="Regularization ε⁰, in the unit `epsilon_unit`.")
    epsilon_unit: Literal["absolute", "spacing"] = Field(
        "spacing", description='"spacing": ε⁰ = epsilon · (largest gap between neighbouring '
        'surface points); "absolute": μm.')
    viscosity: Positive = Field(1.0, description="Fluid viscosity μ⁰ (g μm⁻¹ s⁻¹).")
    wall: bool = Field(False, description="Plane wall at z = 0 (method of images).")
    shear_rate: float = Field(0.0, allow_inf_nan=False, description="Shear rate γ̇ of u∞ (1/s).")
    position: list[Finite] = _three([0.0, 0.0, 0.0], "Initial centre [x, y, z] (μm).")
    orientation: list[Finite] = Field(
        [1.0, 0.0, 0.0, 0.0], min_length=4, max_length=4,
        description="Initial orientation, a quaternion [w, x, y, z] (normalized); the body "
        "axis e1 is the x axis of the body frame.")
    force: list[Finite] = _three(
        [0.0, 0.0, 0.0], "External force on the body [Fx, Fy, Fz] (g μm s⁻²), e.g. its "
        "buoyancy-corrected weight.")
    torque: list[Finite] = _three(
        [0.0, 0.0, 0.0], "External torque about the centre (g μm² s⁻²), e.g. a magnetic torque.")

    def surface_shape(self) -> Any:
        """The body-frame surface (:mod:`.shapes`) of this section."""
        raise NotImplementedError

    def surface_slip(self) -> Squirmer | UserSlip | None:
        """The prescribed surface slip (:mod:`.slip`) of this section, or None."""
        return None

    def _epsilon(self, shape: Any) -> tuple[float, float]:
        """ε⁰ in μm and the surface's largest gap; ValueError naming the keys of a surface
        with fewer than 2 points or one too large for floating point."""
        gap = spacing(shape)
        if not 0.0 < gap < math.inf:
            count = self.planned_size().rows - 1
            if count < 2:
                raise ValueError(f"{self.size_keys()}: the surface has {count} point; a rigid "
                                 "body needs at least 2 (and enough to cover it for its ε)")
            raise ValueError(f"the surface's points are {gap:g} apart: its sizes (radius, "
                             "length, ...) are beyond what floating point holds; give them in "
                             "μm, e.g. radius = 1")
        return self.epsilon * (gap if self.epsilon_unit == "spacing" else 1.0), gap

    def build(self, threads: int = 1) -> RigidBody:
        shape = self.surface_shape()
        x, y, z = self.position
        fx, fy, fz = self.force
        tx, ty, tz = self.torque
        w, qx, qy, qz = self.orientation
        return RigidBody(shape=shape, slip=self.surface_slip(), epsilon=self._epsilon(shape)[0],
                         viscosity=self.viscosity, wall=self.wall, shear_rate=self.shear_rate,
                         position=(x, y, z), orientation=(w, qx, qy, qz), force=(fx, fy, fz),
                         torque=(tx, ty, tz), n_threads=threads)

    def size_keys(self) -> str:
        """The keys that set the number of surface points (named when there are too many)."""
        return "n_points"

    def planned_size(self) -> PlannedSize:
        """The pose row and the surface points, counted from the keys (nothing built): the
        body-frame factorization of the surface is a dense (3N)² matrix."""
        shape = self.surface_shape()
        if isinstance(shape, Bacterium):
            count = shape.head.n_points + shape.tail.n_points
        elif isinstance(shape, PointCloud):
            count = len(shape.points(0.0))
        else:
            count = int(shape.n_points)
        return PlannedSize(1 + count, DENSE_BYTES * float(count) ** 2, self.size_keys())

    def coarse_points(self, factor: int) -> int:
        """Rows of the state on the coarse surface of ``coarse.grid_factor`` (the pose row and
        ``factor`` times fewer points per part, :meth:`RigidBody.coarsened`)."""
        return 1 + len(coarse_shape(self.surface_shape(), factor).points(0.0))

    def resolve(self) -> BodyResolution:
        body = self.build()
        check_solvable(body, self.kind)
        epsilon, gap = self._epsilon(body.shape)
        theta0 = {"epsilon": epsilon, "viscosity": self.viscosity}
        return BodyResolution(theta0, 1 + body.n_surface, gap, "spacing")


class RigidModel(RigidBase):
    """A rigid body of a built-in shape or a user's point cloud, with an optional user slip."""

    kind: Literal["rigid"] = Field(description='"rigid" for a rigid body.')
    shape: Literal["sphere", "spheroid", "rod", "helix", "points"] = Field(
        "sphere", description="The surface: sphere, spheroid, rod (a tube), helix "
        "(a slender filament) or points (a user's cloud, key `points`).")
    radius: Positive = Field(1.0, description="Sphere, spheroid (equatorial), rod, helix radius.")
    axial: Positive = Field(2.0, description="Spheroid semi-axis along the body axis x (μm).")
    n_points: int = Field(400, ge=4, description="Points of a sphere, spheroid or helix.")
    length: Positive = Field(10.0, description="Rod length (μm).")
    rings: int = Field(40, ge=2, description="Rings of points along a rod.")
    around: int = Field(8, ge=3, description="Points around each ring of a rod.")
    pitch: Positive = Field(2.0, description="Helix pitch λ (μm).")
    turns: Positive = Field(3.0, description="Helix turns (its length along x: turns · λ).")
    handedness: Literal[1, -1] = Field(1, description="Helix: 1 right-handed, -1 left-handed.")
    points: str = Field("", description="shape = \"points\": a .npy or text file of (N, 3) "
                        "body-frame points, or a \"module:function\" returning them.")
    slip: str = Field(
        "", description='A surface slip "module:function", function(t, points) -> '
        "(N, 3) body-frame velocities relative to the body (empty: none).")

    def surface_shape(self) -> Any:
        if self.shape == "sphere":
            return Sphere(self.radius, self.n_points)
        if self.shape == "spheroid":
            return Spheroid(self.axial, self.radius, self.n_points)
        if self.shape == "rod":
            return Rod(self.length, self.radius, self.rings, self.around)
        if self.shape == "helix":
            return Helix(self.radius, self.pitch, self.turns, self.n_points, self.handedness)
        if not self.points:
            raise ValueError('points: shape = "points" needs a file or "module:function"')
        return PointCloud(source=self.points)

    def surface_slip(self) -> UserSlip | None:
        return UserSlip(self.slip) if self.slip else None

    def size_keys(self) -> str:
        return {"rod": "rings, around", "points": "points"}.get(self.shape, "n_points")


class SquirmerModel(RigidBase):
    """Blake's spherical squirmer: u_s = (B1 sin θ + B2 sin θ cos θ) e_θ, swimming along e1."""

    kind: Literal["squirmer"] = Field(description='"squirmer" for a spherical squirmer.')
    radius: Positive = Field(1.0, description="Radius a (μm).")
    n_points: int = Field(400, description="Surface points, at least 50 (fewer cannot "
                          "represent the slip: docs/validation.md).")
    b1: Finite = Field(1.0, description="First mode B1 (μm/s): free speed 2 B1 / 3.")
    b2: Finite = Field(0.0, description="Second mode B2 (μm/s): > 0 puller, < 0 pusher.")

    @field_validator("n_points")
    @classmethod
    def _enough_points(cls, n: int) -> int:
        if n < SQUIRMER_MIN_POINTS:
            raise ValueError(
                f"a squirmer needs at least n_points = {SQUIRMER_MIN_POINTS} surface points to "
                f"represent its slip and its sphere, got {n} (its swimming speed and direction "
                "would be wrong)")
        return n

    def surface_shape(self) -> Sphere:
        return Sphere(self.radius, self.n_points)

    def surface_slip(self) -> Squirmer:
        return Squirmer(self.b1, self.b2)


class BacteriumModel(RigidBase):
    """A head and a helical flagellum turning at ``motor_rate`` relative to it, free of force
    and torque (the head counter-rotates); by default E. coli's: a left-handed flagellum turning
    counter-clockwise seen from behind, so that it swims head first and, above a wall, circles
    clockwise seen from above."""

    kind: Literal["bacterium"] = Field(description='"bacterium" for a head with a flagellum.')
    head: Literal["sphere", "spheroid"] = Field("spheroid", description="Head shape.")
    head_radius: Positive = Field(0.5, description="Head (equatorial) radius (μm).")
    head_axial: Positive = Field(1.0, description="Spheroidal head's semi-axis along x (μm).")
    head_points: int = Field(200, ge=4, description="Head surface points.")
    tail_radius: Positive = Field(0.25, description="Flagellum helix radius (μm).")
    pitch: Positive = Field(2.0, description="Flagellum helix pitch (μm).")
    turns: Positive = Field(3.0, description="Flagellum turns.")
    tail_points: int = Field(100, ge=2, description="Points on the flagellum's centre line.")
    handedness: Literal[1, -1] = Field(
        -1, description="Flagellum helix: -1 left-handed (E. coli's), 1 right-handed.")
    gap: Positive = Field(0.25, description="Gap between the head's rear and the flagellum.")
    motor_rate: Finite = Field(MOTOR_RATE, description="Flagellum's rotation rate about the "
                               "body axis x relative to the head (rad/s, right-hand rule; x "
                               "points from the flagellum to the head): < 0 turns it "
                               "counter-clockwise seen from behind the cell, as E. coli's motor "
                               "in a run (with handedness = -1 it then swims head first).")

    def surface_shape(self) -> Bacterium:
        head: Sphere | Spheroid = (
            Sphere(self.head_radius, self.head_points) if self.head == "sphere"
            else Spheroid(self.head_axial, self.head_radius, self.head_points))
        tail = Helix(self.tail_radius, self.pitch, self.turns, self.tail_points, self.handedness)
        return Bacterium(head, tail, self.gap, self.motor_rate)

    def size_keys(self) -> str:
        return "head_points, tail_points"


def layout(section: Any, system: RigidBody, frames: bool,
           tracked: Sequence[int] | None) -> list[BodyLayout]:
    """The centre (row 0, with the quaternion and the phase of the pose as node data: written
    whatever ``frames`` says, since the state cannot be rebuilt without them; and the body's
    motion at the frame, its ``velocity`` U and ``angular_velocity`` Ω, the columns 0:3 and 3:6
    of the rates' row 0, which the state does not hold) and the surface (rows 1..M), each a cloud
    of points."""
    kind = system_kind(section)
    center = point_layout("center", kind, 0, 1)
    pose = {"orientation": slice(3, 7), "phase": slice(7, 8)}
    return [dataclasses.replace(center, vectors=pose, rate_vectors=MOTION),
            point_layout("surface", kind, 1, system.n_surface)]


#: The centre's motion written with every frame: U and Ω, columns of the rates' row 0
#: (:class:`~.system.RigidBody`'s ``rates``).
MOTION = {"velocity": slice(0, 3), "angular_velocity": slice(3, 6)}


def system_kind(section: Any) -> str:
    return str(getattr(section, "kind", "rigid"))


def draw(fig: Any, bodies: Mapping[str, Mapping[str, np.ndarray]], times: np.ndarray,
         run: str) -> None:
    """The path of every centre in the x-y and x-z planes, by time, and the surface at the last
    frame in grey, at true scale."""
    fig.set_size_inches(7, 6.5)
    centers = {k: v for k, v in bodies.items() if k.endswith("center")}
    planes = ((0, 1, "y (μm)"), (0, 2, "z (μm)"))
    draw_over_time(fig, centers or bodies, times, planes, run, marker=".", lw=0, ms=3)
    for ax, (i, j, _) in zip(fig.axes, planes, strict=False):
        for name, body in bodies.items():
            if name.endswith("surface"):
                last = body["positions"][-1]
                ax.plot(last[:, i], last[:, j], ".", color="0.6", ms=1.5)
        ax.relim()
        ax.autoscale_view()
        ax.set_aspect("equal", adjustable="box")
        ax.set_title(f"{'xyz'[i]}-{'xyz'[j]} plane ({run}), {axis_stretch(fig, ax)}", fontsize=8)


def _example_rigid() -> tuple[RigidBody, np.ndarray, float | None]:
    """A sphere of 40 points sedimenting under gravity and turned by a torque, with a user slip
    (the squirmer's, as a function), tilted: translation, rotation and slip all act."""
    body = RigidBody(shape=Sphere(1.0, 40), slip=UserSlip("parastokes.kinds.rigid.kind:"
                                                          "example_slip"),
                     epsilon=0.3, viscosity=1.0, force=(0.0, 0.0, -3.0),
                     torque=(0.0, 2.0, 1.0), orientation=(0.9, 0.1, 0.3, 0.2))
    return body, body.initial_state(), 0.5


def example_slip(t: float, points: np.ndarray) -> np.ndarray:
    """A squirmer slip (B1 = 1, B2 = 0.5) that pulses in time: (1 + sin 4t) u_s (the example)."""
    return (1.0 + np.sin(4.0 * t)) * Squirmer(1.0, 0.5).velocity(t, points)


def _example_bacterium() -> tuple[RigidBody, np.ndarray, float | None]:
    """A small bacterium (30 head points, a 24-point flagellum) with weight: every part acts."""
    shape = Bacterium(Sphere(0.5, 30), Helix(0.2, 1.0, 1.5, 24), 0.2, 2 * math.pi)
    body = RigidBody(shape=shape, epsilon=0.15, force=(0.0, 0.0, -0.5))
    return body, body.initial_state(), 0.2


def _example_squirmer() -> tuple[RigidBody, np.ndarray, float | None]:
    """A bottom-heavy puller squirmer (40 points) near the wall, tilted, in shear: slip,
    weight, torque, wall and background flow all act."""
    body = RigidBody(shape=Sphere(1.0, 40), slip=Squirmer(2.0, 3.0), epsilon=0.3, wall=True,
                     shear_rate=1.0, position=(0.0, 0.0, 1.8), force=(0.0, 0.0, -2.0),
                     torque=(3.0, 0.0, 0.0), orientation=(0.95, 0.0, -0.3, 0.1))
    return body, body.initial_state(), 0.5


RIGID = BodyKind("rigid", RigidModel, layout, draw, example=_example_rigid)
SQUIRMER = BodyKind("squirmer", SquirmerModel, layout, draw, example=_example_squirmer)
BACTERIUM = BodyKind("bacterium", BacteriumModel, layout, draw, example=_example_bacterium)
