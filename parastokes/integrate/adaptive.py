"""The adaptive driver: a run from ``t0`` to ``t1`` whose steps the controller of
:mod:`.controller` sizes from a scheme's error estimate, every accepted state checked as the
fixed steps' are (finite, monitor within the blow-up limit)."""

from __future__ import annotations

import logging
import math

import numpy as np

from .. import stiff
from ..core.contracts import StepFailure, System
from ..stiff import Rosenbrock
from .base import BlowUpError, RunResult, monitor, projected
from .controller import StepSizeError, adaptive_steps, estimate_order
from .explicit import PairStepper
from .implicit import checked_stepper, solve_blowup
from .schemes import AnyScheme

__all__ = ["adaptive_run"]

log = logging.getLogger(__name__)


def adaptive_run(system: System, scheme: AnyScheme, x: np.ndarray, t0: float, t1: float,
                 dt: float, tol: tuple[float, float], blowup_factor: float) -> RunResult:
    """:func:`parastokes.integrate.run` with adaptive steps (see there): every accepted state is
    checked as the fixed steps' are (finite, monitor within ``blowup_factor`` times the limit;
    a state beyond it is a rejected step)."""
    limit = blowup_factor * system.monitor_limit
    x = projected(system, x, t0)
    worst = [monitor(system, x)]
    stepper = (checked_stepper(system, scheme) if isinstance(scheme, Rosenbrock)
               else PairStepper(system, scheme))

    def accept(t: float, x_new: np.ndarray, index: int) -> bool:
        if not np.isfinite(x_new).all():
            return False
        m = monitor(system, x_new)
        if not m <= limit:
            return False
        worst[0] = max(worst[0], m)
        return True

    try:
        end, counts = adaptive_steps(stepper, estimate_order(scheme), x, t0, t1, dt, *tol,
                                     accept)
    except stiff.StiffSolveError as error:
        raise solve_blowup(error, stepper.steps, x) from error
    except StepSizeError as error:
        reason = f"{error} (adaptive steps); loosen rtol/atol or check the body's forces"
        raise BlowUpError(error.t, stepper.steps, math.nan, x, reason) from error
    except StepFailure as error:  # (a failed mobility solve): no result, a blow-up
        raise BlowUpError(t0, stepper.steps, math.nan, x, str(error)) from None
    log.debug("adaptive %s on [%g, %g]: %d steps accepted, %d rejected", scheme.name, t0, t1,
              counts.accepted, counts.rejected)
    return RunResult(projected(system, end, t1), worst[0], counts.accepted, counts.last_step,
                     n_rejected=counts.rejected)
