"""The adaptive driver: a run from ``t0`` to ``t1`` whose steps the controller of
:mod:`.controller` sizes from a scheme's error estimate, every accepted state checked as the
fixed steps' are (finite, monitor within the blow-up limit)."""

from __future__ import annotations

import logging
import math
from collections.abc import Callable

import numpy as np

from .. import stiff
from ..core.contracts import StepFailure, System
from ..stiff import Rosenbrock
from .base import BlowUpError, RunResult, monitor, projected
from .controller import AdaptiveResult, StepSizeError, adaptive_steps, estimate_order
from .explicit import PairStepper
from .implicit import checked_stepper, solve_blowup
from .loop import CompiledPair, compiled_pair
from .schemes import AnyScheme

__all__ = ["Watch", "adaptive_run", "segment", "stepper_for"]

#: A stepper with an error estimate: an explicit pair's (in Python or compiled) or a
#: Rosenbrock scheme's.
Stepper = PairStepper | CompiledPair | stiff.Stepper

log = logging.getLogger(__name__)


class Watch:
    """The checks of every accepted state of a run (finite, monitor within ``blowup_factor``
    times the limit: else a rejected step) and the worst monitor seen."""

    def __init__(self, system: System, x: np.ndarray, blowup_factor: float) -> None:
        self.system = system
        self.limit = blowup_factor * system.monitor_limit
        self.worst = monitor(system, x)

    def __call__(self, t: float, x_new: np.ndarray, index: int) -> bool:
        if not np.isfinite(x_new).all():
            return False
        m = monitor(self.system, x_new)
        if not m <= self.limit:
            return False
        self.worst = max(self.worst, m)
        return True


def stepper_for(system: System, scheme: AnyScheme, compiled: bool = True) -> Stepper:
    """The stepper with an error estimate of ``scheme`` on a run's checked calls: for an
    explicit pair with ``compiled``, the compiled loop of the system's exact type where it has
    one (:func:`.loop.compiled_pair`: the same steps), else its steps in Python."""
    if isinstance(scheme, Rosenbrock):
        return checked_stepper(system, scheme)
    pair = compiled_pair(system, scheme) if compiled else None
    return PairStepper(system, scheme) if pair is None else pair


def segment(stepper: Stepper, x: np.ndarray, t0: float, t1: float, h: float,
            tol: tuple[float, float], watch: Watch,
            until: Callable[[float, np.ndarray, float, float], bool] | None = None,
            every: int = 1, previous: float | None = None) -> tuple[np.ndarray, AdaptiveResult]:
    """:func:`.controller.adaptive_steps` of ``stepper`` from ``(t0, x)`` toward ``t1`` (see
    there; PI control for an explicit pair), its failures as :class:`BlowUpError`. A stepper
    that ended the last segment at ``(t0, x)`` (the same array) goes on with its first stage
    known (first same as last) and, with ``previous``, its PI control."""
    q, pi = estimate_order(stepper.scheme), not stepper.scheme.implicit
    try:
        if isinstance(stepper, CompiledPair):
            x, counts, watch.worst = stepper.steps_from(x, t0, t1, h, q, tol, watch.limit,
                                                        watch.worst, until, pi, every, previous)
            return x, counts
        return adaptive_steps(stepper, q, x, t0, t1, h, *tol, watch, until, pi=pi, every=every,
                              previous=previous)
    except stiff.StiffSolveError as error:
        raise solve_blowup(error, stepper.steps, x) from error
    except StepSizeError as error:
        reason = f"{error} (adaptive steps); loosen rtol/atol or check the body's forces"
        raise BlowUpError(error.t, stepper.steps, math.nan, x, reason) from error
    except StepFailure as error:  # (a failed mobility solve): no result, a blow-up
        raise BlowUpError(t0, stepper.steps, math.nan, x, str(error)) from None


def adaptive_run(system: System, x: np.ndarray, t0: float, t1: float, dt: float,
                 tol: tuple[float, float], blowup_factor: float, *, scheme: AnyScheme,
                 compiled: bool = True) -> RunResult:
    """:func:`parastokes.integrate.run` with adaptive steps (see there): every accepted state is
    checked as the fixed steps' are (:class:`Watch`); an explicit pair in the system's compiled
    loop where it has one and ``compiled``."""
    x = projected(system, x, t0)
    watch = Watch(system, x, blowup_factor)
    end, counts = segment(stepper_for(system, scheme, compiled), x, t0, t1, dt, tol, watch)
    log.debug("adaptive %s on [%g, %g]: %d steps accepted, %d rejected", scheme.name, t0, t1,
              counts.accepted, counts.rejected)
    return RunResult(projected(system, end, t1), watch.worst, counts.accepted, counts.last_step,
                     n_rejected=counts.rejected)
