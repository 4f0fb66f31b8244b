"""Runs: fixed steps (in Python or in a system's compiled loop) or adaptive ones (:mod:`.adaptive`)
from ``t0`` to ``t1``, their result, and the propagators built on them."""

from __future__ import annotations

import functools
import logging
import math
from dataclasses import dataclass

import numpy as np

from ..bodies import contract
from ..core.contracts import StepFailure, System
from ..registry.loops import compiled_loop
from ..stiff import Rosenbrock
from .adaptive import adaptive_run
from .auto import auto_run
from .base import (
    ABOVE,
    BEYOND,
    BLOWUP_FACTOR,
    DONE,
    NON_FINITE,
    BlowUpError,
    RunResult,
    monitor,
    projected,
)
from .explicit import explicit_step
from .implicit import implicit_stepper
from .schemes import AUTO, SCHEMES, AnyScheme, Auto, fixed_step_scheme, lookup, scheme_order

__all__ = ["Propagator", "n_steps", "propagate", "run", "run_result", "step", "tolerances"]

log = logging.getLogger(__name__)

#: The smallest ``rtol`` accepted: 100 machine epsilons.
RTOL_MIN = 100 * float(np.finfo(float).eps)


def step(system: System, scheme: str | AnyScheme, t: float, x: np.ndarray, dt: float
         ) -> np.ndarray:
    """One step of ``scheme`` from ``(t, x)`` to ``t + dt`` (no projection; what ``rates`` and
    ``advance`` return is checked, :mod:`parastokes.bodies.contract`, not its finiteness)."""
    s = lookup(scheme)
    if isinstance(s, Auto):
        raise ValueError("scheme: 'auto' chooses its own steps; use run or propagate with rtol")
    if isinstance(s, Rosenbrock):
        return implicit_stepper(system, s)(t, x, dt)
    return explicit_step(system, s, t, x, dt)


def n_steps(t_start: float, t_end: float, dt: float) -> int:
    """Equal steps used on ``[t_start, t_end]``: ``max(1, round(span/dt))``, and 0 if span = 0."""
    if not dt > 0:
        raise ValueError(f"dt: must be positive, got {dt}")
    span = t_end - t_start
    if span < 0:
        raise ValueError(f"t_end: must not precede t_start, got [{t_start}, {t_end}]")
    if span == 0:
        return 0
    return max(1, round(span / dt))


def _python_steps(
    system: System,
    scheme: AnyScheme,
    x: np.ndarray,
    t0: float,
    dt: float,
    n: int,
    limit: float,
    stop_above: float,
) -> tuple[np.ndarray, float, int, int, float]:
    """``n`` steps through ``system.rates``/``system.advance``, checked after each step.

    Returns ``(last state kept, worst monitor, steps kept, outcome, monitor that ended the run)``;
    ``system.run_steps`` (optional, compiled) has the same signature and result.
    """
    worst = monitor(system, x)
    take = (implicit_stepper(system, scheme) if isinstance(scheme, Rosenbrock)
            else functools.partial(step, system, scheme))
    for i in range(n):
        try:
            x_new = take(t0 + i * dt, x, dt)
        except StepFailure as error:  # (a failed mobility solve): no result, a blow-up
            raise BlowUpError(t0 + (i + 1) * dt, i, math.nan, x, str(error)) from None
        if not np.isfinite(x_new).all():
            return x, worst, i, NON_FINITE, math.nan
        m = monitor(system, x_new)
        if not m <= limit:
            return x, worst, i, BEYOND, m
        worst = max(worst, m)
        x = x_new
        if m > stop_above:
            return x, worst, i + 1, ABOVE, m
    return x, worst, n, DONE, worst


def stepping(
    system: System,
    scheme: AnyScheme,
    x: np.ndarray,
    t0: float,
    dt: float,
    n: int,
    blowup_factor: float,
    stop_above: float | None = None,
    compiled: bool = True,
) -> RunResult:
    """Take ``n`` steps of size ``dt``; stop early (``completed=False``) if monitor > stop_above.

    The steps run in the compiled loop registered for the exact type of ``system`` when there is
    one and ``compiled`` (:mod:`parastokes.registry.loops`: rods, vesicles), else in
    :func:`_python_steps`; both return the same.
    """
    limit = blowup_factor * system.monitor_limit
    shape = x.shape
    x = projected(system, x, t0)
    loop = compiled_loop(system) if compiled and not scheme.implicit else None
    if loop is None:
        x = contract.array(system, "project(state)", x, shape=shape, what="the state's shape")
        loop = functools.partial(_python_steps, system)
    steps = loop(scheme, x, t0, dt, n, limit, math.inf if stop_above is None else stop_above)
    return run_result(system, t0, dt, steps, blowup_factor)


def run_result(
    system: System,
    t0: float,
    dt: float,
    steps: tuple[np.ndarray, float, int, int, float],
    blowup_factor: float = BLOWUP_FACTOR,
) -> RunResult:
    """The :class:`RunResult` of a loop of steps from ``t0`` (``steps``: what ``run_steps``
    returns), or the :class:`BlowUpError` it ended with. Also used by the GPU backend
    (:mod:`parastokes.gpu`), whose batched loops return the same tuples."""
    x, worst, taken, outcome, m = steps
    t = t0 + (taken + 1) * dt
    if outcome == NON_FINITE:
        reason = "non-finite state" + contract.culprit(system, t - dt, x)
        raise BlowUpError(t, taken, math.nan, x, reason)
    if outcome == BEYOND:
        reason = f"monitor beyond {blowup_factor:g} x its limit {system.monitor_limit:g}"
        if m == math.inf:  # the monitors' sign of a point on or below the wall z = 0
            reason += " (infinite: a point reached the wall z = 0)"
        raise BlowUpError(t, taken, m, x, reason)
    end = projected(system, x, t0 + taken * dt, max(taken - 1, 0))
    return RunResult(end, worst, taken, dt, completed=outcome == DONE)


def run(
    system: System,
    x: np.ndarray,
    t0: float,
    t1: float,
    scheme: str | AnyScheme,
    dt: float,
    *,
    blowup_factor: float = BLOWUP_FACTOR,
    compiled: bool = True,
    rtol: float | None = None,
    atol: float | None = None,
) -> RunResult:
    """Integrate from ``t0`` to ``t1`` with equal steps closest to ``dt``; report the worst monitor.

    With ``rtol`` (``atol`` defaults to ``rtol``; ``atol`` alone is a ValueError): adaptive
    steps of a scheme with an error estimate instead (:mod:`.controller`, ``dt`` the first step
    tried, the last one cut to end at ``t1``);
    ``n_steps`` of the result counts the accepted steps, ``n_rejected`` the rejected ones.

    The step actually used is ``(t1 - t0) / n_steps(t0, t1, dt)``; a change is logged (DEBUG).
    The initial and the final state are projected (``system.project``). Raises
    :class:`BlowUpError` on blow-up. ``compiled=False`` takes the steps through the system's
    ``rates`` and ``advance`` in Python even when it has a compiled loop (``run_steps``, and for
    the adaptive steps of an explicit pair :func:`.loop.compiled_pair`), e.g. to check one
    against the other: both give the same result (adaptive steps: the same steps, states equal
    to round-off).
    """
    s = lookup(scheme)
    n = n_steps(t0, t1, dt)
    tol = None if rtol is None and atol is None and s is not AUTO else tolerances(s, rtol, atol)
    if tol is not None and n:
        start = np.asarray(x, dtype=float)
        if isinstance(s, Auto):
            return auto_run(system, start, t0, t1, dt, tol, blowup_factor, compiled=compiled)
        return adaptive_run(system, start, t0, t1, dt, tol, blowup_factor, scheme=s,
                            compiled=compiled)
    if n == 0:
        return RunResult(system.project(np.array(x, dtype=float)), system.monitor(x), 0, dt)
    h = (t1 - t0) / n
    if abs(h - dt) > 1e-12 * dt:
        log.debug("step adjusted from %.6g to %.6g: %d steps divide [%g, %g]", dt, h, n, t0, t1)
    return stepping(system, fixed_step_scheme(s), np.asarray(x, dtype=float), t0, h, n,
                    blowup_factor, compiled=compiled)


def tolerances(scheme: str | AnyScheme | Auto, rtol: float | None, atol: float | None
               ) -> tuple[float, float]:
    """``(rtol, atol)`` checked for the adaptive steps of ``scheme``: ``rtol`` given (``atol``
    alone is refused, not ignored), both finite and positive (``atol`` None: ``rtol``),
    ``rtol`` at least :data:`RTOL_MIN` (below it the steps would chase round-off), and a
    scheme with an error estimate (ValueError naming the key)."""
    s = lookup(scheme)
    if rtol is None and s is AUTO:
        raise ValueError("rtol: required by the scheme 'auto', which takes adaptive steps only")
    if rtol is None:
        raise ValueError(f"atol: given ({atol!r}) without rtol; adaptive steps need rtol "
                         "(atol defaults to rtol), or leave both out for fixed steps")
    atol = rtol if atol is None else atol
    for name, value in (("rtol", rtol), ("atol", atol)):
        if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
            raise ValueError(f"{name}: must be a finite number > 0, got {value!r}")
    if rtol < RTOL_MIN:
        raise ValueError(f"rtol: {rtol:g} is below {RTOL_MIN:.2g} (100 machine epsilons): no "
                         "step can meet it in double precision; use a larger rtol")
    if not s.adaptive:
        adaptive = sorted(k for k, v in SCHEMES.items() if v.adaptive)
        raise ValueError(f"rtol: the scheme {s.name!r} has no error estimate for adaptive "
                         f"steps; use one of {adaptive}, or a fixed step without rtol/atol")
    return float(rtol), float(atol)


def propagate(
    system: System,
    x: np.ndarray,
    t0: float,
    t1: float,
    scheme: str | AnyScheme,
    dt: float,
    *,
    blowup_factor: float = BLOWUP_FACTOR,
    rtol: float | None = None,
    atol: float | None = None,
) -> np.ndarray:
    """The state at ``t1`` of the run of :func:`run` (fixed public name, design.md)."""
    return run(system, x, t0, t1, scheme, dt, blowup_factor=blowup_factor, rtol=rtol,
               atol=atol).state


@dataclass(frozen=True)
class Propagator:
    """A picklable solver ``P(t_start, t_end, x) -> x`` (fine F or auxiliary G): fixed steps
    closest to ``dt``, or with ``rtol`` (and ``atol``) adaptive steps from a first step ``dt``."""

    system: System
    scheme: str | AnyScheme
    dt: float
    blowup_factor: float = BLOWUP_FACTOR
    rtol: float | None = None
    atol: float | None = None

    def __post_init__(self) -> None:
        lookup(self.scheme)
        if not self.dt > 0:
            raise ValueError(f"dt: must be positive, got {self.dt}")
        if self.rtol is not None or self.atol is not None or self.scheme == AUTO.name:
            tolerances(self.scheme, self.rtol, self.atol)

    @property
    def order(self) -> int:
        return scheme_order(self.scheme)

    def n_steps(self, t_start: float, t_end: float) -> int:
        """Number of equal steps actually taken on ``[t_start, t_end]``."""
        return n_steps(t_start, t_end, self.dt)

    def __call__(self, t_start: float, t_end: float, x: np.ndarray) -> np.ndarray:
        return propagate(self.system, x, t_start, t_end, self.scheme, self.dt,
                         blowup_factor=self.blowup_factor, rtol=self.rtol, atol=self.atol)

    def run(self, t_start: float, t_end: float, x: np.ndarray) -> RunResult:
        """The :class:`RunResult` of the propagation (steps taken, and rejected with ``rtol``)."""
        return run(self.system, x, t_start, t_end, self.scheme, self.dt,
                   blowup_factor=self.blowup_factor, rtol=self.rtol, atol=self.atol)

    def counted(self, t_start: float, t_end: float, x: np.ndarray
                ) -> tuple[np.ndarray, tuple[int, int, int]]:
        """The state at ``t_end`` and the steps ``(accepted, rejected, switches)`` taken
        (``switches``: those of ``"auto"``): a task whose counts travel back with its state
        from a worker process (Parareal's adaptive auxiliary solves)."""
        result = self.run(t_start, t_end, x)
        return result.state, (result.n_steps, result.n_rejected, len(result.switches))


