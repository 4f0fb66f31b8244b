"""The stability search: whether steps of a size keep a body's monitor within its limit, and
the largest such step (the paper's coarse steps "close to the largest time step permitted",
section 5.1.1)."""

from __future__ import annotations

import logging
import math
from collections.abc import Callable

import numpy as np

from ..core.contracts import System
from .base import BLOWUP_FACTOR, BlowUpError
from .runs import stepping
from .schemes import AnyScheme, fixed_step_scheme

__all__ = ["is_stable", "largest_stable_step"]

log = logging.getLogger(__name__)


def is_stable(
    system: System,
    scheme: str | AnyScheme,
    dt: float,
    t_span: float,
    *,
    x0: np.ndarray | None = None,
    t0: float = 0.0,
    limit: float | None = None,
) -> bool:
    """Whether ``ceil(t_span/dt)`` steps of exactly ``dt`` keep the monitor within ``limit``
    (default: the system's ``monitor_limit``)."""
    limit = system.monitor_limit if limit is None else limit
    worst = _worst_monitor(system, scheme, dt, t_span, x0, t0, limit)
    return worst is not None and worst <= limit


def _worst_monitor(system: System, scheme: str | AnyScheme, dt: float, t_span: float,
                   x0: np.ndarray | None, t0: float, stop_above: float) -> float | None:
    """The largest monitor over ``ceil(t_span/dt)`` steps of ``dt``; None if it blew up or went
    above ``stop_above`` (the run stops there)."""
    x = system.initial_state() if x0 is None else np.asarray(x0, dtype=float)
    n = max(1, math.ceil(t_span / dt - 1e-9))
    try:
        res = stepping(system, fixed_step_scheme(scheme), x, t0, dt, n, BLOWUP_FACTOR,
                        stop_above=stop_above)
    except BlowUpError:
        return None
    return res.max_monitor if res.completed else None


def largest_stable_step(
    system: System,
    scheme: str | AnyScheme,
    t_span: float,
    dt_lo: float,
    dt_hi: float,
    *,
    x0: np.ndarray | None = None,
    t0: float = 0.0,
    rtol: float = 0.05,
    relative: bool = False,
    stop: Callable[[], None] | None = None,
) -> float:
    """Largest step in ``[dt_lo, dt_hi]`` keeping the monitor within ``system.monitor_limit``
    (``relative``: within the limit of its value at ``dt_lo``, i.e. of the body's own change,
    for bodies whose monitor changes physically: a vesicle of perturbed viscosity deforms more).

    Bisects geometrically on runs of length ``t_span`` (steps of exactly dt, see
    :func:`is_stable`) until the bracket is narrower than ``rtol``: the result passes and a step at
    most ``result * (1 + rtol)`` failed. The paper picks its coarse steps "close to the largest time
    step permitted" (section 5.1.1, Fig. 3) with the limits of docs/physics.md (rod length 1%,
    vesicle area 0.01%). ``dt_lo`` must pass (ValueError otherwise); if ``dt_hi`` passes it is
    returned with a warning. ``stop`` is called before every trial run (a caller's budget: it
    raises to abandon the search).
    """
    if not 0 < dt_lo < dt_hi:
        raise ValueError(f"dt_lo, dt_hi: need 0 < dt_lo < dt_hi, got {dt_lo}, {dt_hi}")
    if not t_span > 0:
        raise ValueError(f"t_span: must be positive, got {t_span}")
    if not rtol > 0:
        raise ValueError(f"rtol: must be positive, got {rtol}")

    check = stop or (lambda: None)
    threshold = None
    if relative:  # the run at dt_lo sets the threshold, so it passes by construction
        check()
        physical = _worst_monitor(system, scheme, dt_lo, t_span, x0, t0, math.inf)
        if physical is None:
            raise ValueError(f"dt_lo: {dt_lo:g} is not stable over t_span={t_span:g}")
        threshold = system.monitor_limit + physical

    def ok(dt: float) -> bool:
        check()
        return is_stable(system, scheme, dt, t_span, x0=x0, t0=t0, limit=threshold)

    if not relative and not ok(dt_lo):
        raise ValueError(f"dt_lo: {dt_lo:g} is not stable over t_span={t_span:g}")
    if ok(dt_hi):
        log.warning("largest_stable_step: dt_hi=%g is stable; the limit lies above it", dt_hi)
        return dt_hi
    lo, hi = dt_lo, dt_hi
    while hi > lo * (1 + rtol):
        mid = math.sqrt(lo * hi)
        if ok(mid):
            lo = mid
        else:
            hi = mid
    return lo
