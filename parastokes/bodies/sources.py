"""What a system puts into the fluid: its point loads, where they sit and their blob widths.

:class:`FluidSources` is the one low-level description of a system's regularized Stokeslets and
rotlets (eq. 6; docs/physics.md (1)-(8)), so that the fluid's velocity can be evaluated anywhere
(:mod:`parastokes.flow`), not only at the bodies' own points:

- a system with ``fluid_sources(t, state)`` gives them itself (a scene composes its bodies'; a
  body whose loads sit elsewhere than its state rows, e.g. on a rigid body's surface, must);
- otherwise the points are the state's positions (columns 0-2), the loads ``system.loads(t,
  state)`` (forces, torques or None) and every source has the system's ``epsilon``.

The forces and torques are what the bodies exert on the fluid (docs/contracts.md, "System").
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from . import contract

__all__ = ["FluidSources", "fluid_sources"]


class FluidSources(NamedTuple):
    """A system's point loads on the fluid at one instant."""

    points: np.ndarray  # (N, 3) where the loads sit
    forces: np.ndarray  # (N, 3) what the bodies exert on the fluid
    torques: np.ndarray | None  # (N, 3) or None
    epsilon: np.ndarray  # (N,) blob width per source


def fluid_sources(system: Any, t: float, state: np.ndarray) -> FluidSources:
    """The point loads of ``system`` in ``state`` at time ``t`` (see the module's text).

    ValueError naming what to add for a system that offers neither ``fluid_sources`` nor
    ``loads`` and ``epsilon`` (e.g. a user's body whose ``rates`` call the fluid directly); a
    :class:`~parastokes.bodies.contract.BodyError` naming ``Type.loads`` for loads that are not
    real (N, 3) arrays.
    """
    if hasattr(system, "fluid_sources"):
        sources = system.fluid_sources(t, state)
        return FluidSources(*sources)
    missing = [name for name in ("loads", "epsilon") if not hasattr(system, name)]
    if missing:
        raise ValueError(
            f"a {type(system).__name__} does not say what it exerts on the fluid: give it "
            f"{' and '.join(missing)} (loads(t, state) -> (forces, torques or None), epsilon: its "
            "blob width) or fluid_sources(t, state) (docs/contracts.md, 'System')"
        )
    state = np.asarray(state, dtype=np.float64)
    points = np.ascontiguousarray(state[:, :3])
    forces, torques = system.loads(t, state)
    rows = (len(points), 3)  # checked where they enter (the fluid's sums do not check)
    forces = np.ascontiguousarray(contract.array(system, "loads(t, state)[0]", forces,
                                                 shape=rows, what="forces, one row per point"))
    if torques is not None:
        torques = np.ascontiguousarray(contract.array(
            system, "loads(t, state)[1]", torques, shape=rows, what="torques, one row per point"))
    epsilon = np.full(len(points), float(system.epsilon))
    return FluidSources(points, forces, torques, epsilon)
