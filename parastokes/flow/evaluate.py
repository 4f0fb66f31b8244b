"""The fluid's velocity anywhere: eq. 6 at arbitrary points from a system's point loads.

``velocity(system, state, points)`` sums the regularized Stokeslets and rotlets of every source of
the system (:func:`parastokes.bodies.sources.fluid_sources`: rods with their torques, vesicles,
chains, users' bodies with ``loads``, scenes of all of them, each source with its own ε) at the
target ``points``, above the wall with the images (docs/physics.md (1)-(8)), through the compiled
kernels (:func:`parastokes.mrs.velocity`, threads over tiles of targets), plus the background
shear u∞ = (γ̇ z, 0, 0) of the system's ``shear_rate`` (eq. 15; ``background=False`` leaves it out).

Below the wall (z < 0) there is no fluid: the velocity there is zero (the image system's values
below the plane are a mathematical continuation, not a flow). On the plane z = 0 itself the
images cancel the sources (to round-off: tests/test_flow.py).
"""

from __future__ import annotations

import numba
import numpy as np

from .. import mrs
from ..bodies.sources import FluidSources, fluid_sources

__all__ = ["background_velocity", "sources_velocity", "velocity"]


def _targets(points: np.ndarray) -> np.ndarray:
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3 or not np.all(np.isfinite(points)):
        raise ValueError(f"points: need finite (M, 3) coordinates, got shape {points.shape}")
    return np.ascontiguousarray(points)


def background_velocity(system: object, points: np.ndarray) -> np.ndarray:
    """u∞ = (γ̇ z, 0, 0) at ``points`` (zeros for a system without ``shear_rate``)."""
    u = np.zeros_like(points, dtype=np.float64)
    u[:, 0] = float(getattr(system, "shear_rate", 0.0)) * points[:, 2]
    return u


def sources_velocity(sources: FluidSources, points: np.ndarray, viscosity: float,
                     wall: bool = False, n_threads: int | None = None) -> np.ndarray:
    """u at ``points`` (M, 3) of the point loads ``sources`` in a fluid of ``viscosity`` (eq. 6,
    docs/physics.md (1), (3), and (5), (7) with ``wall``); targets below the wall get zero.
    ``n_threads``: kernel threads (default: numba's pool)."""
    targets = _targets(points)
    threads = numba.config.NUMBA_NUM_THREADS if n_threads is None else n_threads
    torques = sources.torques
    if torques is not None:
        torques = np.ascontiguousarray(torques, dtype=np.float64)
    u = mrs.velocity(targets, np.ascontiguousarray(sources.points, dtype=np.float64),
                     np.ascontiguousarray(sources.forces, dtype=np.float64),
                     epsilon=np.asarray(sources.epsilon, dtype=np.float64), mu=float(viscosity),
                     torques=torques, wall=bool(wall), n_threads=threads, check=False)
    if wall:
        u[targets[:, 2] < 0] = 0.0
    return u


def velocity(system: object, state: np.ndarray, points: np.ndarray, t: float = 0.0,
             background: bool = True, n_threads: int | None = None) -> np.ndarray:
    """The fluid velocity (M, 3) at ``points`` (M, 3) around ``system`` in ``state`` at time
    ``t``: eq. 6 over all its sources (module text), plus u∞ with ``background``.

    ``system`` is any body (rod, vesicle, chain, a user's body with ``loads`` and ``epsilon``)
    or a :class:`parastokes.scene.Scene`; its ``viscosity``, ``wall`` and ``shear_rate`` are the
    fluid's. At a body's own points this is the velocity its rates move them with.
    """
    if not hasattr(system, "viscosity"):
        raise ValueError(f"a {type(system).__name__} has no viscosity: the fluid's velocity needs "
                         "one (give the system a viscosity attribute)")
    targets = _targets(points)
    wall = bool(getattr(system, "wall", False))
    sources = fluid_sources(system, t, np.asarray(state, dtype=np.float64))
    u = sources_velocity(sources, targets, float(system.viscosity), wall, n_threads)
    if background:
        u_inf = background_velocity(system, targets)
        if wall:
            u_inf[targets[:, 2] < 0] = 0.0
        u += u_inf
    return u
