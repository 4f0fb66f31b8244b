"""THE step-size controller of every adaptive scheme (explicit pairs and Rosenbrock schemes):
the weighted RMS error norm, acceptance at ``err <= 1``, the elementary controller with its
safety factor and clipped growth and shrinkage (Hairer, Nørsett & Wanner, *Solving ODEs I*,
II.4; scipy's ``_ivp/common.py`` and ``rk.py``).

A stepper is anything with ``step_with_estimate(t, x, h) -> (x_new, x_low)``: the step's
solution and its embedded one of lower order (:class:`parastokes.stiff.Stepper`, the explicit
pairs' stepper of :mod:`.adaptive`). The controller's exponent is ``1/(q+1)`` with ``q`` the
order of the estimate, ``min(order, embedded order)``: the local error of the embedded solution
goes as ``h^(q+1)``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numba import njit

__all__ = ["GROW", "SAFETY", "SHRINK", "AdaptiveResult", "StepSizeError", "adaptive_steps",
           "constants", "error_norm", "estimate_order", "factor", "lands", "smallest_step",
           "step_factor"]

#: Step-size controller: safety factor, smallest and largest change of a step.
SAFETY, SHRINK, GROW = 0.9, 0.2, 5.0
#: A rejected step shrinks by at least this (a step just above the tolerance is not retried at
#: 0.99 of its size).
REJECT_MAX = 0.5
#: PI control after an accepted step that follows another (Gustafsson, ACM TOMS 17, 1991;
#: Hairer & Wanner, *Solving ODEs II*, IV.2): ``err^(-PI_ALPHA/(q+1)) prev^(PI_BETA/(q+1))``,
#: ``prev`` the last accepted error, at least PREVIOUS_MIN (DOPRI5's floor). It damps the
#: oscillation of the elementary controller where stability, not accuracy, limits an explicit
#: step (on the rod of 301 points: rk23 from 66 rejected steps of 181 to none, docs/stiff.md).
#: The explicit pairs only: for ros2 on a stiff Prothero-Robinson problem it took 5 times the
#: steps of the elementary controller (docs/stiff.md).
PI_ALPHA, PI_BETA, PREVIOUS_MIN = 0.7, 0.4, 1e-4


class StepSizeError(RuntimeError):
    """The adaptive steps shrank below 1e-12 of the interval at time ``t``."""

    def __init__(self, t: float, step: float) -> None:
        super().__init__(f"step size {step:.3g} too small at t={t:.10g}")
        self.t, self.step = t, step

    def __reduce__(self) -> tuple:
        return type(self), (self.t, self.step)


class EstimatingStepper(Protocol):
    def step_with_estimate(self, t: float, x: np.ndarray, h: float
                           ) -> tuple[np.ndarray, np.ndarray]: ...


def estimate_order(scheme: object) -> int:
    """``q = min(order, embedded order)`` of a scheme with an error estimate (``order_low``
    where the scheme says it, else one less than its order: every embedded solution here is of
    one order less)."""
    order = int(scheme.order)  # type: ignore[attr-defined]
    low = getattr(scheme, "order_low", None)
    return min(order, order - 1 if low is None else int(low))


@njit(cache=True, error_model="numpy")
def error_norm(x: np.ndarray, x_new: np.ndarray, x_low: np.ndarray, rtol: float,
               atol: float) -> float:
    """The RMS over the state's entries of ``(x_new - x_low) / (atol + rtol max(|x|, |x_new|))``
    (the norm of Hairer, Nørsett & Wanner, *Solving ODEs I*, II.4; scipy's solve_ivp).
    Compiled (numba), so that the Python steps and the compiled adaptive loop of :mod:`.loop`
    get the same bits: where stability limits the steps, a difference of round-off in ``err``
    grows some 5-fold a step (measured on a rod)."""
    scale = atol + rtol * np.maximum(np.abs(x), np.abs(x_new))
    return float(np.sqrt(np.mean(((x_new - x_low) / scale) ** 2)))


def constants() -> np.ndarray:
    """``(SAFETY, SHRINK, GROW, REJECT_MAX, PI_ALPHA, PI_BETA, PREVIOUS_MIN)`` as they are now:
    what :func:`step_factor` takes, read at each call (by :func:`factor` and by the compiled
    adaptive loop of :mod:`.loop`, so the constants live here only)."""
    return np.array([SAFETY, SHRINK, GROW, REJECT_MAX, PI_ALPHA, PI_BETA, PREVIOUS_MIN])


@njit(cache=True, error_model="numpy")
def step_factor(err: float, q: int, accepted: bool, previous: float, control: np.ndarray
                ) -> float:
    """:func:`factor` with ``previous <= 0`` for none and the constants ``control``
    (:func:`constants`): the one implementation of the arithmetic, compiled (numba) and called by
    :func:`factor` and by the compiled adaptive loop of :mod:`.loop` alike."""
    safety, shrink, grow, reject_max, alpha, beta = (control[0], control[1], control[2],
                                                     control[3], control[4], control[5])
    if not np.isfinite(err):
        return shrink
    if err == 0.0:
        wanted = grow
    elif accepted and previous > 0.0:
        wanted = safety * err ** (-alpha / (q + 1)) * previous ** (beta / (q + 1))
    else:
        wanted = safety * err ** (-1.0 / (q + 1))
    return min(grow, max(shrink, wanted)) if accepted else max(shrink, min(reject_max, wanted))


def factor(err: float, q: int, accepted: bool, previous: float | None = None) -> float:
    """The next step over this one: ``SAFETY err^(-1/(q+1))``, or with ``previous`` (the error
    of the accepted step before an accepted one) the PI factor ``SAFETY err^(-PI_ALPHA/(q+1))
    previous^(PI_BETA/(q+1))``; within ``[SHRINK, GROW]`` after an accepted step and ``[SHRINK,
    REJECT_MAX]`` after a rejected one (a step can be rejected for its state,
    :func:`adaptive_steps`, at any ``err``; ``err`` infinite: ``SHRINK``)."""
    return float(step_factor(float(err), q, accepted, 0.0 if previous is None else previous,
                             constants()))


@njit(cache=True)
def lands(t: float, h: float, t1: float) -> bool:
    """Whether a step ``h`` from ``t`` reaches ``t1`` (to a relative 1e-14): it is then cut to
    end there."""
    return t + h >= t1 * (1 - 1e-14) if t1 else t + h >= t1


def smallest_step(t0: float, t1: float) -> float:
    """Steps below this (1e-12 of the interval ``[t0, t1]``, or of ``|t1|``) are a
    :class:`StepSizeError`."""
    return 1e-12 * max(abs(t1 - t0), abs(t1))


@dataclass(frozen=True)
class AdaptiveResult:
    """Steps accepted and rejected by :func:`adaptive_steps`, and the last step size tried."""

    accepted: int
    rejected: int
    last_step: float
    #: Where the steps ended: ``t1``, or earlier where ``until`` stopped them.
    end: float = math.nan
    #: The last accepted error of PI control (None without), to go on from ``end``.
    previous: float | None = None


def adaptive_steps(stepper: EstimatingStepper, q: int, x: np.ndarray, t0: float, t1: float,
                   h0: float, rtol: float, atol: float,
                   accept: Callable[[float, np.ndarray, int], bool],
                   until: Callable[[float, np.ndarray, float, float], bool] | None = None,
                   pi: bool = False, every: int = 1, previous: float | None = None
                   ) -> tuple[np.ndarray, AdaptiveResult]:
    """Steps from ``(t0, x)`` to ``t1`` whose estimated local error stays within ``rtol`` and
    ``atol`` (:func:`error_norm` <= 1), the first of size ``h0``, the next ones by
    :func:`factor` with the estimate's order ``q`` (with ``pi``, PI control from the second
    accepted step on, or from the first with ``previous``, the last accepted error of steps
    that ended at ``(t0, x)``: :attr:`AdaptiveResult.previous`), the last one cut to end at
    ``t1``.

    ``accept(t, x_new, step)`` sees every step whose error is small enough; it returns False for
    a state the run cannot keep (its monitor beyond the limit: the step is rejected) and may
    raise to end the run. ``until(t, x, step, h)``, after every ``every``-th accepted step
    (``step`` taken, ``h`` the next one) before ``t1``, may stop the steps there. Returns the
    state where the steps ended and the counts.
    """
    t, h = t0, min(h0, t1 - t0)
    smallest = smallest_step(t0, t1)
    accepted = rejected = 0
    previous = previous if pi else None  # the error of the last accepted step (PI control)
    while t < t1:
        last = lands(t, h, t1)
        step = t1 - t if last else h
        x_new, x_low = stepper.step_with_estimate(t, x, step)
        err = error_norm(x, x_new, x_low, rtol, atol)
        if not np.isfinite(err):
            err = np.inf
        ok = err <= 1.0 and accept(t + step, x_new, accepted)
        h = step * factor(err, q, ok, previous)
        if ok:
            t = t1 if last else t + step
            x = x_new
            accepted += 1
            previous = max(err, PREVIOUS_MIN) if pi else None
        else:
            rejected += 1
        if h < smallest:
            raise StepSizeError(t, h)
        if ok and t < t1 and until is not None and accepted % every == 0 and until(t, x, step, h):
            break
    return x, AdaptiveResult(accepted, rejected, h, t, previous)
