"""Which systems have a compiled loop of steps: a table keyed by the exact type of the system.

``register(RodSystem, factory)`` says that a system whose type *is* ``RodSystem`` is stepped by
``factory(system)``, a ``run_steps(scheme, x, t0, dt, n, limit, stop_above)`` with the result of
:func:`parastokes.integrate._python_steps`. The lookup is by ``type(system)``, never through
inheritance or attributes: a subclass that changes the physics, or a wrapper that forwards
attributes (as :class:`parastokes.spatial.TargetBlocks` did), cannot pick up a loop that computes
another system's rates. A subclass that keeps the physics registers itself explicitly.

This module imports nothing, so :mod:`parastokes.integrate` can ask it without an import cycle.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

__all__ = ["compiled_loop", "register", "registered"]

RunSteps = Callable[..., tuple[Any, float, int, int, float]]

_LOOPS: dict[type, Callable[[Any], RunSteps]] = {}


def register(cls: type, factory: Callable[[Any], RunSteps]) -> None:
    """Step systems of exactly the type ``cls`` with ``factory(system)``."""
    _LOOPS[cls] = factory


def registered() -> list[type]:
    """The types that have a compiled loop."""
    return list(_LOOPS)


def compiled_loop(system: Any) -> RunSteps | None:
    """The compiled ``run_steps`` of ``system`` if its exact type has one, else None."""
    factory = _LOOPS.get(type(system))
    return None if factory is None else factory(system)
