"""Which systems have a compiled loop of steps: a table keyed by the exact types involved.

``register(RodSystem, factory, fluid=MRS)`` says that a system whose type *is* ``RodSystem``, with
a ``fluid`` whose type *is* :class:`parastokes.fluid.MRS`, is stepped by
``factory(system)``, a ``run_steps(scheme, x, t0, dt, n, limit, stop_above)`` with the result of
:func:`parastokes.integrate._python_steps`. The lookup is by ``type(system)``, never through
inheritance or attributes: a subclass that changes the physics, or a wrapper that forwards
attributes (as :class:`parastokes.parallel.spatial.TargetBlocks` did), cannot pick up a loop that
computes another system's rates, and a system whose fluid is computed otherwise (by blocks of
targets on an executor, :class:`parastokes.fluid.BlockedMRS`) is stepped through its own ``rates``.
A subclass that keeps the physics registers itself explicitly.

A body type whose compiled parts can also be composed into a scene's loop registers how to build
its compiled data, ``register_data(RodSystem, rod_data)`` (``rod_data(system, threads)``, see
:mod:`parastokes.integrate.loop`): :func:`compiled_data` finds it, again by exact type only, and
:mod:`parastokes.scene.compiled` steps a scene in compiled code exactly when every one of its
bodies has it. :func:`parastokes.integrate.loop.register_parts` registers both at once.

A body type that can also be solved batched on the GPU registers where its device parts are,
``register_device(RodSystem, "parastokes.kinds.rod.device:PARTS")`` (a
:class:`parastokes.bodies.device.DeviceParts`, imported by :mod:`parastokes.gpu` when a GPU solve
needs it): :func:`device_target` finds it, by exact type only.

This module imports nothing, so :mod:`parastokes.integrate` can ask it without an import cycle.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

__all__ = ["compiled_data", "compiled_loop", "device_target", "register", "register_data",
           "register_device", "registered"]

RunSteps = Callable[..., tuple[Any, float, int, int, float]]

_LOOPS: dict[tuple[type, type], Callable[[Any], RunSteps | None]] = {}
_DATA: dict[type, Callable[[Any, int], tuple]] = {}
_DEVICE: dict[type, str] = {}


def _key(system: object) -> tuple[type, type]:
    return type(system), type(getattr(system, "fluid", None))


def register(
    cls: type, factory: Callable[[Any], RunSteps | None], fluid: type | None = None
) -> None:
    """Step systems of exactly the type ``cls`` whose ``fluid`` is exactly of the type ``fluid``
    (None: systems without a ``fluid``) with ``factory(system)`` (None: this system has none,
    e.g. a scene with a body without compiled parts)."""
    _LOOPS[cls, type(None) if fluid is None else fluid] = factory


def registered() -> list[tuple[type, type]]:
    """The (system type, fluid type) pairs that have a compiled loop."""
    return list(_LOOPS)


def compiled_loop(system: object) -> RunSteps | None:
    """The compiled ``run_steps`` of ``system`` if its exact types have one, else None."""
    factory = _LOOPS.get(_key(system))
    return None if factory is None else factory(system)


def register_data(cls: type, make_data: Callable[[Any, int], tuple]) -> None:
    """Systems of exactly the type ``cls`` have compiled parts on the data
    ``make_data(system, threads)`` (a ``NamedTuple``; :mod:`parastokes.integrate.loop`), including
    the parts a scene composes (``loads_into``, ``body_rates_into``)."""
    _DATA[cls] = make_data


def compiled_data(system: object) -> Callable[[Any, int], tuple] | None:
    """The ``make_data`` registered for the exact type of ``system``, else None."""
    return _DATA.get(type(system))


def register_device(cls: type, target: str) -> None:
    """Systems of exactly the type ``cls`` have device parts at ``target``, ``"module:NAME"`` of a
    :class:`parastokes.bodies.device.DeviceParts`, or of a function of the system that returns
    one (a scene's depend on its bodies); imported on a GPU solve's first use."""
    if not isinstance(target, str) or ":" not in target:
        raise ValueError(f"target: give it as \"package.module:NAME\", got {target!r}")
    _DEVICE[cls] = target


def device_target(system: object) -> str | None:
    """Where the device parts of the exact type of ``system`` are, else None."""
    return _DEVICE.get(type(system))
