"""What every run shares (scipy's ``_ivp/base.py`` and ``common.py`` in spirit): the checked
calls into a system (``rates``, ``advance``, ``monitor``, ``project``), the result of a run, its
outcomes and the blow-up error."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..bodies import contract
from ..core.contracts import System

__all__ = ["ABOVE", "BEYOND", "BLOWUP_FACTOR", "DONE", "NON_FINITE", "BlowUpError", "RunResult",
           "advance", "monitor", "projected", "rates"]

#: Default ratio of monitor value to ``system.monitor_limit`` at which a run is declared blown up.
BLOWUP_FACTOR = 100.0

#: Outcomes of a loop of steps (``runs._python_steps``, ``system.run_steps``): all steps taken;
#: stopped after a step whose monitor exceeded ``stop_above`` (kept); a non-finite state; a
#: monitor beyond the blow-up limit (neither kept).
DONE, ABOVE, NON_FINITE, BEYOND = 0, 1, 2, 3


class BlowUpError(RuntimeError):
    """A run produced a non-finite state or a monitor far beyond its limit.

    Attributes: ``t`` (time reached by the failing step), ``step`` (its index, counted from 0 within
    the run), ``monitor`` (the monitor value there, ``nan`` for a non-finite state) and
    ``last_state`` (the last good state, at time ``t - dt``).
    """

    def __init__(self, t: float, step: int, monitor: float, last_state: np.ndarray, reason: str):
        super().__init__(
            f"blow-up at t={t:.10g} (step {step}): {reason}; monitor={monitor:.6g}"
        )
        self.t = t
        self.step = step
        self.monitor = monitor
        self.last_state = last_state
        self.reason = reason

    def __reduce__(self):
        # rebuild from the attributes, so the error crosses process boundaries intact
        return type(self), (self.t, self.step, self.monitor, self.last_state, self.reason)


@dataclass(frozen=True)
class RunResult:
    """Outcome of :func:`parastokes.integrate.run`: final state, largest monitor seen, steps
    taken and step used."""

    state: np.ndarray
    max_monitor: float
    n_steps: int
    dt: float
    completed: bool = True
    #: Steps rejected by the error control of adaptive steps (``n_steps`` counts the accepted).
    n_rejected: int = 0
    #: ``scheme="auto"``: its switches ``(t, scheme run from t, why)``, and the steps
    #: ``(scheme, accepted, rejected)`` of each scheme it ran (:mod:`.auto`).
    switches: tuple[tuple[float, str, str], ...] = ()
    by_scheme: tuple[tuple[str, int, int], ...] = ()


def projected(system: System, x: np.ndarray, t: float, step: int = 0) -> np.ndarray:
    """``system.project(x)``, a state the projection rejects (a ValueError, e.g. a rod frame
    made singular by a step far too large) being a :class:`BlowUpError` at ``t``."""
    try:
        return system.project(x)
    except ValueError as error:
        raise BlowUpError(t, step, math.nan, np.array(x), f"not a valid state ({error})") from None


def rates(system: System, t: float, x: np.ndarray) -> np.ndarray:
    """``system.rates(t, x)``, checked where it enters (real numbers, a row per state row)."""
    return contract.array(system, "rates(t, state)", system.rates(t, x), rows=len(x),
                          ndim=x.ndim, what="one row per state row")


def advance(system: System, x: np.ndarray, r: np.ndarray, dt: float) -> np.ndarray:
    """``system.advance(x, r, dt)``, checked where it enters (real numbers, the state's shape)."""
    return contract.array(system, "advance(state, rates, dt)", system.advance(x, r, dt),
                          shape=x.shape, what="the state's shape")


def monitor(system: System, x: np.ndarray) -> float:
    """``system.monitor(x)``, checked where it enters (a real number; infinite is the sign of a
    point on the wall, NaN of a non-finite state)."""
    return contract.number(system, "monitor(state)", system.monitor(x))
