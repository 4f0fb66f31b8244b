"""The public face of the rigid-body library (docs/design.md, "Added in round 3"; its engine is
:mod:`parastokes.mobility`): rigid surfaces of the built-in shapes, and the resistance and mobility
problems of one body.

::

    from parastokes import rigid
    body = rigid.sphere(radius=1.0, n_points=2000)          # a rigid surface in its body frame
    F, T = rigid.resistance(body, U=(1, 0, 0), Omega=(0, 0, 0), center=(0, 0, 5.0), mu=1.0,
                            wall=True)      # total force and torque the body exerts on the fluid
    U, Omega = rigid.mobility(body, force=(0, 0, -1), torque=(0, 0, 0), center=(0, 0, 5.0),
                              mu=1.0, wall=True)   # its motion under an external force, torque
    R = rigid.resistance_matrix(body, center=(0, 0, 5.0), mu=1.0, wall=True)   # (6, 6)

A shape's ``epsilon`` defaults to :data:`EPSILON_PER_SPACING` times its :func:`spacing` (the
largest gap between neighbouring points), as a configuration's ``epsilon_unit = "spacing"`` does;
a surface too coarse for its ε is refused (:func:`parastokes.mobility.check_surface`). A body
built from a configuration (:func:`parastokes.config.build_body`, or a run configuration's
``cfg.model.build()``) is accepted too: its surface at phase 0 and its ε, and by default its own
pose, viscosity and wall (its slip is not applied: these are the problems of the rigid surface).
Forces and torques are those on the fluid, torques about ``center``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from .kinds.rigid import rotation as quaternion
from .kinds.rigid.shapes import Helix, Rod, Sphere, Spheroid
from .kinds.rigid.system import RigidBody
from .mobility import RigidSurface, solve_mobility, solve_resistance
from .mobility import resistance_matrix as _resistance_matrix
from .mobility.checks import nearest_spacing

__all__ = ["EPSILON_PER_SPACING", "helix", "mobility", "resistance", "resistance_matrix", "rod",
           "spacing", "sphere", "spheroid"]

#: The default ε of a shape, in units of its :func:`spacing` (a configuration's default too).
EPSILON_PER_SPACING = 0.5


def spacing(shape: Any) -> float:
    """The largest distance from a point of ``shape`` (a :class:`RigidSurface`, a body built from
    a configuration, a shape of :mod:`parastokes.kinds.rigid.shapes`, or an (N, 3) array of
    points) to its nearest neighbour: the coarsest gap the blobs of width ε must cover."""
    if isinstance(shape, RigidBody):
        shape = shape.shape
    if isinstance(shape, RigidSurface):
        points = shape.points
    elif callable(getattr(shape, "points", None)):
        points = shape.points(0.0)
    else:
        points = np.asarray(shape, dtype=float)
    return float(nearest_spacing(points).max())


def _surface(shape: Any, epsilon: float | None, name: str) -> RigidSurface:
    points = shape.points(0.0)
    eps = EPSILON_PER_SPACING * spacing(points) if epsilon is None else epsilon
    return RigidSurface(points, eps, name=name)


def sphere(radius: float = 1.0, n_points: int = 400, *,
           epsilon: float | None = None) -> RigidSurface:
    """``n_points`` on the sphere of ``radius`` about the origin (a Fibonacci spiral)."""
    return _surface(Sphere(radius, n_points), epsilon, "sphere")


def spheroid(axial: float = 2.0, radius: float = 1.0, n_points: int = 400, *,
             epsilon: float | None = None) -> RigidSurface:
    """``n_points`` on the spheroid of semi-axes (``axial`` along x, ``radius``, ``radius``)."""
    return _surface(Spheroid(axial, radius, n_points), epsilon, "spheroid")


def rod(length: float = 10.0, radius: float = 0.5, rings: int = 40, around: int = 8, *,
        epsilon: float | None = None) -> RigidSurface:
    """A tube along x: ``rings`` rings of ``around`` points and one point on each end."""
    return _surface(Rod(length, radius, rings, around), epsilon, "rod")


def helix(radius: float = 0.2, pitch: float = 1.0, turns: float = 3.0, n_points: int = 120,
          handedness: int = 1, *, epsilon: float | None = None) -> RigidSurface:
    """A slender helical filament along x (``n_points`` on its centre line; ``handedness`` 1
    right-handed, -1 left-handed)."""
    return _surface(Helix(radius, pitch, turns, n_points, handedness), epsilon, "helix")


def _placed(body: Any, center: Sequence[float] | None, rotation: Any, mu: float | None,
            wall: bool | None) -> tuple[Any, float, bool]:
    """``body`` placed at ``center`` (rotated by the 3x3 ``rotation``), with the fluid: a body
    built from a configuration gives its surface at phase 0, and by default its pose, viscosity
    and wall; a :class:`RigidSurface` the origin, μ = 1 and free space."""
    where: Any = center
    if isinstance(body, RigidBody):
        state = body.initial_state()
        own_center, q, _ = body.pose(state)
        surface = RigidSurface(body.shape.points(0.0), float(body.epsilon),
                               name=type(body.shape).__name__.lower())
        where = own_center if center is None else center
        rotation = quaternion.matrix(q) if rotation is None else rotation
        mu = float(body.viscosity) if mu is None else mu
        wall = bool(body.wall) if wall is None else wall
    elif isinstance(body, RigidSurface):
        surface = body
    else:
        raise TypeError(f"body: a rigid surface (rigid.sphere, ...) or a rigid body built from a "
                        f"configuration, got {type(body).__name__}")
    at = np.zeros(3) if where is None else np.asarray(where, dtype=float)
    return surface.place(at, rotation), 1.0 if mu is None else mu, bool(wall)


def resistance(body: Any, U: Sequence[float] = (0.0, 0.0, 0.0),
               Omega: Sequence[float] = (0.0, 0.0, 0.0), *,
               center: Sequence[float] | None = None, rotation: Any = None,
               mu: float | None = None, wall: bool | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The total force and torque (about ``center``) that ``body`` moving at (U, Ω) exerts on
    the fluid: two (3,) arrays."""
    placed, viscosity, on_wall = _placed(body, center, rotation, mu, wall)
    result = solve_resistance(placed, U, Omega, mu=viscosity, wall=on_wall)
    return result.force[0], result.torque[0]


def mobility(body: Any, force: Sequence[float] = (0.0, 0.0, 0.0),
             torque: Sequence[float] = (0.0, 0.0, 0.0), *,
             center: Sequence[float] | None = None, rotation: Any = None,
             mu: float | None = None, wall: bool | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The velocity U and angular velocity Ω of ``body`` under the external ``force`` and
    ``torque`` (about ``center``): two (3,) arrays."""
    placed, viscosity, on_wall = _placed(body, center, rotation, mu, wall)
    result = solve_mobility(placed, mu=viscosity, wall=on_wall, external_force=force,
                            external_torque=torque)
    return result.U[0], result.Omega[0]


def resistance_matrix(body: Any, *, center: Sequence[float] | None = None, rotation: Any = None,
                      mu: float | None = None, wall: bool | None = None) -> np.ndarray:
    """The 6x6 resistance matrix of ``body``: (F, T) on the fluid = R (U, Ω), torque about
    ``center``."""
    placed, viscosity, on_wall = _placed(body, center, rotation, mu, wall)
    return _resistance_matrix(placed.surface, placed.center, placed.rotation, mu=viscosity,
                              wall=on_wall)
