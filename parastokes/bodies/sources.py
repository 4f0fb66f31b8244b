"""Where a system's bodies load the fluid: the sources of the flow field around them.

:func:`fluid_sources` asks ``system.fluid_sources(t, state)`` when the system has it (rigid and
prescribed-motion bodies, whose surface forces come from a mobility solve, and scenes) and
otherwise builds the sources from ``positions``, ``loads`` and ``epsilon`` (explicit bodies).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

__all__ = ["FluidSources", "fluid_sources"]


class FluidSources(NamedTuple):
    points: np.ndarray          # (N, 3) where the loads sit
    forces: np.ndarray          # (N, 3) what the bodies exert on the fluid
    torques: np.ndarray | None  # (N, 3) or None
    epsilon: np.ndarray         # (N,) blob width per source


def fluid_sources(system: Any, t: float, state: np.ndarray) -> FluidSources:
    """The loads ``system`` exerts on the fluid at ``(t, state)`` (see the module)."""
    own = getattr(system, "fluid_sources", None)
    if own is not None:
        return own(t, state)
    points = np.asarray(system.positions(state), dtype=float)
    forces, torques = system.loads(t, state)
    epsilon = np.broadcast_to(np.asarray(system.epsilon, dtype=float), (len(points),)).copy()
    return FluidSources(points, np.asarray(forces, dtype=float),
                        None if torques is None else np.asarray(torques, dtype=float), epsilon)
