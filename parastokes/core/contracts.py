"""The contracts between the parts of parastokes, as types, and the one rule they share.

Protocols (structural: any class with these members qualifies, nothing to inherit):

- :class:`System`: a body (or several) in a fluid, stepped by :mod:`parastokes.integrate`
  (docs/contracts.md; ``parastokes.testing.check_system`` checks it at run time);
- :class:`Propagator`: ``P(t_start, t_end, x) -> x``, the fine and coarse solvers of Parareal;
- :class:`CoarseSolver`: a propagator made of ``n_auxiliary`` auxiliary solvers that can run
  concurrently on an executor (``with_executor``), as the extrapolated G of eq. 30;
- :class:`SizedExecutor`: a ``concurrent.futures.Executor`` that says how many tasks run at once;
- :class:`TracingCoarse`: a coarse solver whose coarse step is a *trace* (a record kept between
  iterations) and whose correction replaces eq. 11's G(new) − G(old), as HODMD-Parareal's does.

The rule of Algorithm 1 that ties them, N_G <= N_c (all auxiliary coarse solvers of a coarse step
run at once, one per worker), lives here only: :func:`oversubscription` words it,
:func:`check_workers` enforces it on an executor, and the config checks call the former.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from concurrent.futures import Executor
from typing import Any, Protocol, runtime_checkable

import numpy as np

__all__ = [
    "CoarseSolver",
    "Propagator",
    "PropagatorLike",
    "SizedExecutor",
    "StepFailure",
    "System",
    "TracingCoarse",
    "auxiliary_count",
    "check_workers",
    "oversubscription",
    "rounds",
    "with_executor",
]

logger = logging.getLogger(__name__)

#: Any callable propagator, ``P(t_start, t_end, x) -> x``.
PropagatorLike = Callable[[float, float, np.ndarray], np.ndarray]


class StepFailure(RuntimeError):
    """A system's ``rates`` could not give a trustworthy result at a state (e.g. a rigid body's
    mobility solve that failed, :class:`parastokes.mobility.SolveError`): the integrator reports
    the step as a blow-up (:class:`parastokes.integrate.BlowUpError`, the last good state kept),
    with this message as its reason."""


@runtime_checkable
class System(Protocol):
    """What :mod:`parastokes.integrate` and :mod:`parastokes.parareal` use of a system
    (docs/contracts.md). Optional members: ``bracket(r1, r2)`` (non-abelian rates, RKMK4),
    ``run_steps`` (a compiled loop of steps), ``coarsened(factor)`` (a coarser grid)."""

    def initial_state(self) -> np.ndarray: ...

    def rates(self, t: float, state: np.ndarray) -> np.ndarray: ...

    def advance(self, state: np.ndarray, rates: np.ndarray, dt: float) -> np.ndarray: ...

    def project(self, state: np.ndarray) -> np.ndarray: ...

    def positions(self, state: np.ndarray) -> np.ndarray: ...

    @property
    def params(self) -> dict[str, float]: ...

    def with_params(self, **theta: float) -> System: ...

    def monitor(self, state: np.ndarray) -> float: ...

    @property
    def monitor_limit(self) -> float: ...


@runtime_checkable
class Propagator(Protocol):
    """``P(t_start, t_end, x) -> x`` (a picklable value when it runs on workers)."""

    def __call__(self, t_start: float, t_end: float, x: np.ndarray) -> np.ndarray: ...


@runtime_checkable
class CoarseSolver(Propagator, Protocol):
    """A propagator of ``n_auxiliary`` auxiliary solvers (N_G of eq. 31) that runs them on
    ``executor`` (None: one after the other); ``with_executor(ex)`` is a copy bound to ``ex``."""

    n_auxiliary: int
    executor: Executor | None

    def with_executor(self, executor: Executor | None) -> CoarseSolver: ...


@runtime_checkable
class SizedExecutor(Protocol):
    """An executor with ``workers``: how many of its tasks run at once (N_c of Algorithm 1)."""

    workers: int

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Any: ...


@runtime_checkable
class TracingCoarse(Protocol):
    """A coarse solver whose correction is its own, not eq. 11's G(X^k) − G(X^{k-1})
    (docs/contracts.md, "Tracing coarse solvers"; HODMD-Parareal, :mod:`parastokes.coarse.hodmd`).

    - ``trace(t_start, t_end, x, k)``: the coarse step G_n^k of iteration k (k = 0: the initial
      sweep) from ``x`` at ``t_start``, as a *trace*: a float array of one shape for all n and k
      (the family's memory between iterations). The engine keeps it as it keeps G_n^k under eq. 11
      (checkpoint, solve memo, pipelined tasks), so it must be picklable and deterministic;
    - ``end_state(t_start, t_end, trace)``: X_n^0 of the initial sweep from the trace of slice n;
    - ``correction(t_start, t_end, new, old, k)``: the term that replaces G(new) − G(old) in
      X_n^k = project(F(X_{n-1}^{k-1}) + correction) from the traces from X_{n-1}^k (``new``)
      and X_{n-1}^{k-1} (``old``), on the manager.

    Optional: ``initial_guess(times, x0)``: X^0 at every T_n at once (an initial guess that is
    not a sweep of coarse steps), or None for the sweep; the traces of iteration 0 are then
    computed from it, slice by slice (at once under the pipelined schedule).

    Both schedules and every executor run it; a coarse solver without these members is corrected
    by eq. 11, bit for bit as before.
    """

    def trace(self, t_start: float, t_end: float, x: np.ndarray, k: int) -> np.ndarray: ...

    def end_state(self, t_start: float, t_end: float, trace: np.ndarray) -> np.ndarray: ...

    def correction(self, t_start: float, t_end: float, new: np.ndarray, old: np.ndarray,
                   k: int) -> np.ndarray: ...


def rounds(n_auxiliary: int, workers: int) -> int:
    """The rounds in which ``workers`` workers run a coarse step's N_G = ``n_auxiliary``
    auxiliary solves: ceil(N_G / W) (one when N_G <= W, as Algorithm 1 assumes)."""
    return math.ceil(n_auxiliary / workers)


def oversubscription(
    n_auxiliary: int, workers: int | None, schedule: str = "standard"
) -> str | None:
    """Why ``n_auxiliary`` auxiliary coarse solvers cannot all run at once on ``workers``
    workers (Algorithm 1's input condition N_G <= N_c), or None when they can. One worker (the
    serial reference) and an unknown count (``None``: every task at once) are never oversubscribed,
    nor is the pipelined ``schedule``, whose auxiliary solves wait for workers like any task.
    """
    if schedule == "pipelined" or workers is None or workers == 1 or n_auxiliary <= workers:
        return None
    return (
        f"the coarse solver has N_G = {n_auxiliary} auxiliary solvers but there are only "
        f"N_c = {workers} workers, so they cannot all run at once (Algorithm 1 requires "
        "N_G <= N_c)"
    )


def check_workers(n_auxiliary: int, executor: Executor | None, allow_oversubscribe: bool) -> None:
    """Check Algorithm 1's input condition N_G <= N_c on ``executor``.

    The N_G = N_theta1 N_theta2 N_theta3 (m + 1) = ``n_auxiliary`` auxiliary solvers of a coarse
    step run concurrently on the N_c = ``executor.workers`` workers (Algorithm 1, steps 4 and 15).
    With more solvers than workers this raises ValueError naming both numbers, unless
    ``allow_oversubscribe``: then a warning is logged, the solvers are batched, one batch per
    worker, and each coarse step of a serial sweep takes ceil(N_G / N_c) rounds.
    An executor with one worker (the serial reference) runs everything serially anyway, and one
    without a ``workers`` attribute is taken to run every task at once: neither is checked.
    """
    workers = getattr(executor, "workers", None)
    problem = oversubscription(n_auxiliary, workers)
    if problem is None:
        return
    assert workers is not None  # oversubscription is None for an unknown count
    n_rounds = rounds(n_auxiliary, workers)
    if not allow_oversubscribe:
        raise ValueError(
            f"{problem}; use at least {n_auxiliary} workers or fewer Lagrange nodes / Richardson "
            "steps, or pass allow_oversubscribe=True to batch them (each coarse step of the "
            f"serial sweep then takes ceil({n_auxiliary}/{workers}) = {n_rounds} rounds)"
        )
    logger.warning(
        "N_G = %d auxiliary coarse solvers on N_c = %d workers (allow_oversubscribe=True): "
        "batched per worker, each coarse step of the serial sweep takes ceil(%d/%d) = %d rounds",
        n_auxiliary,
        workers,
        n_auxiliary,
        workers,
        n_rounds,
    )


def auxiliary_count(coarse: Any) -> int:
    """N_G of a coarse solver (``n_auxiliary``), looking through wrappers such as
    :class:`~parastokes.parareal.OnCoarseGrid` (``propagator``); 0 for a plain propagator."""
    while coarse is not None:
        count = getattr(coarse, "n_auxiliary", None)
        if count is not None:
            return count
        coarse = getattr(coarse, "propagator", None)
    return 0


def with_executor(
    coarse: PropagatorLike, executor: Executor | None, allow_oversubscribe: bool
) -> PropagatorLike:
    """Send the coarse solver's auxiliary solvers to ``executor`` unless it has its own.

    Checks N_G <= N_c first (:func:`check_workers`), before any work.
    """
    bind = getattr(coarse, "with_executor", None)
    if executor is None or bind is None or getattr(coarse, "executor", None) is not None:
        return coarse
    check_workers(auxiliary_count(coarse), executor, allow_oversubscribe)
    return bind(executor)
