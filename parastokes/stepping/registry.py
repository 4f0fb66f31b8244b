"""Which systems have a compiled loop of steps: a table keyed by the exact types involved.

``register(RodSystem, factory, fluid=MRS)`` says that a system whose type *is* ``RodSystem``, with
a ``fluid`` whose type *is* :class:`parastokes.fluid.MRS`, is stepped by
``factory(system)``, a ``run_steps(scheme, x, t0, dt, n, limit, stop_above)`` with the result of
:func:`parastokes.integrate._python_steps`. The lookup is by ``type(system)``, never through
inheritance or attributes: a subclass that changes the physics, or a wrapper that forwards
attributes (as :class:`parastokes.spatial.TargetBlocks` did), cannot pick up a loop that computes
another system's rates, and a system whose fluid is computed otherwise (by blocks of targets on
an executor, :class:`parastokes.fluid.BlockedMRS`) is stepped through its own ``rates``. A subclass
that keeps the physics registers itself explicitly.

This module imports nothing, so :mod:`parastokes.integrate` can ask it without an import cycle.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

__all__ = ["compiled_loop", "register", "registered"]

RunSteps = Callable[..., tuple[Any, float, int, int, float]]

_LOOPS: dict[tuple[type, type], Callable[[Any], RunSteps]] = {}


def _key(system: Any) -> tuple[type, type]:
    return type(system), type(getattr(system, "fluid", None))


def register(cls: type, factory: Callable[[Any], RunSteps], fluid: type | None = None) -> None:
    """Step systems of exactly the type ``cls`` whose ``fluid`` is exactly of the type ``fluid``
    (None: systems without a ``fluid``) with ``factory(system)``."""
    _LOOPS[cls, type(None) if fluid is None else fluid] = factory


def registered() -> list[tuple[type, type]]:
    """The (system type, fluid type) pairs that have a compiled loop."""
    return list(_LOOPS)


def compiled_loop(system: Any) -> RunSteps | None:
    """The compiled ``run_steps`` of ``system`` if its exact types have one, else None."""
    factory = _LOOPS.get(_key(system))
    return None if factory is None else factory(system)
