"""Algorithm 1 of the paper: Parareal with any fine and coarse propagators.

A propagator is any callable ``P(t_start, t_end, x) -> x`` over numpy arrays (section 3 writes it
``G(t_End, t_Start, X_Start)``). The engine knows nothing about physics: rods, vesicles and toy ODEs
are all driven the same way.

Every batch of parallel work goes through :func:`parastokes.parallel.run_labelled` /
``run_tasks`` (the coarse combinator's auxiliary solvers too), so a task that raises, or a worker
that dies, stops the run with a :class:`parastokes.parallel.TaskError` that names the slice and the
iteration; the checkpoint then holds the last completed iteration and a rerun resumes from it.
"""

from __future__ import annotations

import functools
import logging
import math
import os
import threading
import time
import warnings
from collections.abc import Callable
from concurrent.futures import Executor, Future
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..parallel import SerialExecutor, TaskError, run_labelled
from . import checkpoint as ckpt
from .metrics import Positions, relative_change
from .result import PararealResult
from .timings import Timings, queued_durations

__all__ = [
    "IterationReport",
    "PropagatorLike",
    "check_workers",
    "run",
    "serial_solution",
    "time_points",
]

logger = logging.getLogger(__name__)

PropagatorLike = Callable[[float, float, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class IterationReport:
    """What :func:`run` passes to ``on_iteration`` after iteration k.

    ``increment`` is η̃^k and ``error`` η^k (eq. 34; None without a reference), ``final_state`` the
    iterate X_N^k at T_N, ``elapsed`` the wall time of the whole run so far (resumed runs included).
    """

    iteration: int
    increment: float
    error: float | None
    final_state: np.ndarray
    elapsed: float


def time_points(t0: float, t1: float, n_slices: int) -> np.ndarray:
    """T_n = t0 + n (t1 - t0) / N_c for n = 0..N_c (section 3), with T_N = t1 exactly."""
    return np.linspace(t0, t1, n_slices + 1)


def serial_solution(
    propagator: PropagatorLike, x0: np.ndarray, t0: float, t1: float, n_slices: int
) -> np.ndarray:
    """The serial solution F(T_n, 0, x0) at every T_n, shape (n_slices + 1, *x0.shape).

    With the fine propagator this is the ``reference`` of :func:`run` (the x^F of eq. 34), computed
    slice by slice on the same time points so that Parareal reproduces it to the last bit.
    """
    times = time_points(t0, t1, n_slices)
    states = np.empty((n_slices + 1, *np.shape(x0)))
    states[0] = x0
    for n in range(1, n_slices + 1):
        states[n] = propagator(times[n - 1], times[n], states[n - 1])
    return states


def _validate(
    fine: PropagatorLike,
    coarse: PropagatorLike,
    x0: np.ndarray,
    t0: float,
    t1: float,
    n_slices: int,
    tol: float,
    max_iterations: int,
    reference: np.ndarray | None,
    wall_time_limit: float | None,
) -> None:
    """Reject bad parameters before any propagator is called."""
    if not (callable(fine) and callable(coarse)):
        raise ValueError("fine and coarse must be callables P(t_start, t_end, x) -> x")
    if isinstance(n_slices, bool) or not isinstance(n_slices, int | np.integer) or n_slices < 1:
        raise ValueError(f"n_slices must be an integer >= 1, got {n_slices!r}")
    if not (math.isfinite(tol) and tol >= 0.0):
        raise ValueError(f"tol must be finite and >= 0, got {tol!r}")
    if (
        isinstance(max_iterations, bool)
        or not isinstance(max_iterations, int | np.integer)
        or max_iterations < 1
    ):
        raise ValueError(f"max_iterations must be an integer >= 1, got {max_iterations!r}")
    if not (math.isfinite(t0) and math.isfinite(t1) and t1 > t0):
        raise ValueError(f"need finite t0 < t1, got t0={t0!r}, t1={t1!r}")
    if x0.size == 0 or not np.all(np.isfinite(x0)):
        raise ValueError("x0 must be a non-empty array of finite numbers")
    if reference is not None and reference.shape != (n_slices + 1, *x0.shape):
        raise ValueError(
            f"reference must have shape {(n_slices + 1, *x0.shape)} (the serial fine solution at "
            f"T_0..T_N), got {reference.shape}"
        )
    if wall_time_limit is not None and not wall_time_limit > 0.0:
        raise ValueError(f"wall_time_limit must be positive, got {wall_time_limit!r}")


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
    if workers is None or workers == 1 or n_auxiliary <= workers:
        return
    rounds = math.ceil(n_auxiliary / workers)
    if not allow_oversubscribe:
        raise ValueError(
            f"the coarse solver has N_G = {n_auxiliary} auxiliary solvers but the executor has "
            f"only N_c = {workers} workers: Algorithm 1 requires N_G <= N_c so that they all run "
            f"at once; use at least {n_auxiliary} workers or fewer Lagrange nodes / Richardson "
            "steps, or pass allow_oversubscribe=True to batch them (each coarse step of the "
            f"serial sweep then takes ceil({n_auxiliary}/{workers}) = {rounds} rounds)"
        )
    logger.warning(
        "N_G = %d auxiliary coarse solvers on N_c = %d workers (allow_oversubscribe=True): "
        "batched per worker, each coarse step of the serial sweep takes ceil(%d/%d) = %d rounds",
        n_auxiliary,
        workers,
        n_auxiliary,
        workers,
        rounds,
    )


def _auxiliary_count(coarse: Any) -> int:
    """N_G of a coarse combinator (``n_auxiliary``), looking through wrappers such as
    :class:`~parastokes.parareal.OnCoarseGrid` (``propagator``); 0 for a plain propagator."""
    while coarse is not None:
        count = getattr(coarse, "n_auxiliary", None)
        if count is not None:
            return count
        coarse = getattr(coarse, "propagator", None)
    return 0


def _with_executor(
    coarse: PropagatorLike, executor: Executor | None, allow_oversubscribe: bool
) -> PropagatorLike:
    """Send the coarse combinator's auxiliary solvers to ``executor`` unless it has its own.

    Checks N_G <= N_c first (:func:`check_workers`), before any work.
    """
    bind = getattr(coarse, "with_executor", None)
    if executor is None or bind is None or coarse.executor is not None:
        return coarse
    check_workers(_auxiliary_count(coarse), executor, allow_oversubscribe)
    return bind(executor)


def _warn_idle_workers(executor: Executor | None, n_slices: int) -> None:
    """Warn, before any work, when the executor has more workers than there are slices."""
    workers = getattr(executor, "workers", None)
    if workers is not None and workers > n_slices:
        warnings.warn(
            f"the executor has {workers} workers but the run has only {n_slices} slices: at most "
            f"{n_slices} fine solves run at once (Algorithm 1 uses one core per slice), so "
            f"{workers - n_slices} workers stay idle in every parallel sweep; use "
            f"n_slices={workers} or {n_slices} workers (MPI: mpiexec -n {n_slices + 1})",
            RuntimeWarning,
            stacklevel=3,
        )


def _timed(propagator: PropagatorLike, t_start: float, t_end: float, x: np.ndarray):
    start = time.perf_counter()
    value = propagator(t_start, t_end, x)
    return value, time.perf_counter() - start


def _coarse_step(
    coarse: PropagatorLike, times: np.ndarray, n: int, x: np.ndarray, k: int
) -> tuple[np.ndarray, float]:
    """G(T_n, T_{n-1}, x) and its wall time, in serial sweep k; a failure names slice and k.

    Raises TaskError labelled ``"coarse solve of slice n in iteration k"`` (k = 0: the initial
    sweep), prefixed by the auxiliary solver's label when one of those failed on a worker.
    """
    try:
        return _timed(coarse, times[n - 1], times[n], x)
    except TaskError as exc:
        label = f"{exc.label} in the coarse solve of slice {n} in iteration {k}"
        raise TaskError(label, exc.original) from exc.original
    except Exception as exc:
        raise TaskError(f"coarse solve of slice {n} in iteration {k}", exc) from exc


class _Clocked:
    """An executor proxy that records, on the manager, when each task is submitted and completed.

    The tasks reach ``executor`` as they are (``fine`` is never wrapped). Completion times come
    from done-callbacks; :meth:`durations` waits for all of them and reconstructs every task's
    run time on a first-in-first-out pool (:func:`~parastokes.parareal.timings.queued_durations`).
    """

    def __init__(self, executor: Executor) -> None:
        self.executor = executor
        self.submitted: list[float] = []
        self.completed: dict[int, float] = {}
        self._finished = threading.Condition()

    def submit(self, fn: Callable[..., Any], /, *args: Any) -> Future:
        index = len(self.submitted)
        self.submitted.append(time.perf_counter())
        future = self.executor.submit(fn, *args)
        future.add_done_callback(functools.partial(self._done, index))
        return future

    def _done(self, index: int, _future: Future) -> None:
        with self._finished:
            self.completed[index] = time.perf_counter()
            self._finished.notify_all()

    def durations(self) -> list[float]:
        """Run time of every task (all must have completed)."""
        n = len(self.submitted)
        with self._finished:
            self._finished.wait_for(lambda: len(self.completed) == n)
        completed = [self.completed[i] for i in range(n)]
        return queued_durations(self.submitted, completed, getattr(self.executor, "workers", None))


def _initial_sweep(
    coarse: PropagatorLike, x0: np.ndarray, times: np.ndarray, with_errors: bool
) -> ckpt.Progress:
    """Eq. 9: X_n^0 = G(T_n, T_{n-1}, X_{n-1}^0), keeping the G values for the first correction."""
    n_slices = len(times) - 1
    states = np.empty((n_slices + 1, *x0.shape))
    states[0] = x0
    timings = Timings(coarse=[[]])
    start = time.perf_counter()
    for n in range(1, n_slices + 1):
        states[n], elapsed = _coarse_step(coarse, times, n, states[n - 1], 0)
        timings.coarse[0].append(elapsed)
    timings.serial_sweeps.append(time.perf_counter() - start)
    return ckpt.Progress(
        0, states, states[1:].copy(), errors=[] if with_errors else None, timings=timings
    )


def _parallel_sweep(
    fine: PropagatorLike, times: np.ndarray, states: np.ndarray, k: int, executor: Executor
) -> tuple[list[np.ndarray], list[float]]:
    """Eq. 10: X_n^{k'} = F(T_n, T_{n-1}, X_{n-1}^{k-1}) for n = k..N, and the F call times.

    One labelled task per slice (``"fine solve of slice n in iteration k"``), submitted as
    ``executor.submit(fine, T_{n-1}, T_n, X_{n-1}^{k-1})``.
    """
    slices = range(k, len(times))
    clock = _Clocked(executor)
    values = run_labelled(
        clock,
        fine,
        [(times[n - 1], times[n], states[n - 1]) for n in slices],
        [f"fine solve of slice {n} in iteration {k}" for n in slices],
    )
    return values, clock.durations()


def _iterate(
    progress: ckpt.Progress,
    fine: PropagatorLike,
    coarse: PropagatorLike,
    times: np.ndarray,
    executor: Executor,
    project: Callable[[np.ndarray], np.ndarray] | None,
) -> None:
    """Iteration k = progress.iteration + 1 of Algorithm 1 (steps 9-18).

    ``progress`` is updated only once the iteration has completed, so an error or an interrupt
    part-way leaves it (and the checkpoint written from it) at iteration k - 1.
    """
    k = progress.iteration + 1
    start = time.perf_counter()
    fine_values, fine_times = _parallel_sweep(fine, times, progress.states, k, executor)
    parallel_time = time.perf_counter() - start

    states = progress.states.copy()  # X_n^k = X_n^{k-1} for n < k
    coarse_values = progress.coarse_values.copy()
    states[k] = fine_values[0]
    coarse_times = []
    start = time.perf_counter()
    for n in range(k + 1, len(times)):
        value, elapsed = _coarse_step(coarse, times, n, states[n - 1], k)
        coarse_times.append(elapsed)
        corrected = fine_values[n - k] + (value - coarse_values[n - 1])  # eq. 11
        states[n] = corrected if project is None else project(corrected)
        coarse_values[n - 1] = value
    serial_time = time.perf_counter() - start

    progress.timings.parallel_sweeps.append(parallel_time)
    progress.timings.fine.append(fine_times)
    progress.timings.serial_sweeps.append(serial_time)
    progress.timings.coarse.append(coarse_times)
    progress.states = states
    progress.coarse_values = coarse_values
    progress.iteration = k


def _stop_reason(progress: ckpt.Progress, tol: float, max_iterations: int) -> str | None:
    k = progress.iteration
    if k == 0:
        return None
    if progress.increments[-1] < tol:
        return "tolerance"
    if k == len(progress.states) - 1:
        return "all_slices"
    if k >= max_iterations:
        return "max_iterations"
    return None


def run(
    fine: PropagatorLike,
    coarse: PropagatorLike,
    x0: np.ndarray,
    t0: float,
    t1: float,
    n_slices: int,
    tol: float,
    max_iterations: int,
    executor: Executor | None = None,
    reference: np.ndarray | None = None,
    project: Callable[[np.ndarray], np.ndarray] | None = None,
    positions: Positions | None = None,
    checkpoint: str | os.PathLike | None = None,
    wall_time_limit: float | None = None,
    allow_oversubscribe: bool = False,
    on_iteration: Callable[[IterationReport], None] | None = None,
    identity: dict[str, Any] | None = None,
) -> PararealResult:
    """Parareal (Algorithm 1): initial serial sweep eq. 9, then iterations of eqs. 10-11.

    Iteration k runs the fine solver on slices n = k..N (eq. 10) on ``executor`` (submitted as
    ``executor.submit(fine, T_{n-1}, T_n, X_{n-1}^{k-1})``; in-process when None), keeps
    X_n^k = X_n^{k-1} for n < k, sets X_k^k = X_k^{k'}, and corrects n = k+1..N serially by eq. 11,
    reusing the stored G(T_n, T_{n-1}, X_{n-1}^{k-1}); ``project`` is applied to every corrected
    state. A coarse combinator with ``with_executor`` (see :func:`extrapolated`) that has no
    executor of its own gets ``executor`` for its auxiliary solvers; its N_G auxiliary solvers
    must not outnumber the executor's workers (Algorithm 1's N_G <= N_c) unless
    ``allow_oversubscribe`` (see :func:`check_workers`). More workers than slices gives a
    RuntimeWarning (the extra workers idle in the parallel sweeps).

    The run stops when the relative increment eta~^k (eq. 34 at T_N over the rows of
    ``positions(state)``, default the whole state) is below ``tol``, when k = N (then ``states``
    equals the serial fine solution), at ``max_iterations``, or, after an iteration, once
    ``wall_time_limit`` seconds have passed in this call. With ``reference`` (the serial fine
    solution at T_0..T_N, see :func:`serial_solution`) the true error eta^k (eq. 34) is recorded.

    With ``checkpoint`` (a file path) the state is written atomically after the initial sweep and
    every iteration; when the file exists the run resumes from it and gives bit-identical results.
    Bad parameters raise ValueError before any propagator is called. A fine or coarse solve that
    fails (raises, or its worker dies) raises :class:`parastokes.parallel.TaskError` labelled
    ``"fine solve of slice n in iteration k"`` or ``"coarse solve of slice n in iteration k"``
    (k = 0: the initial sweep); the checkpoint then holds iteration k - 1 and a rerun with the same
    checkpoint resumes from there (so does a rerun after ``KeyboardInterrupt``).

    ``on_iteration``, if given, is called after every iteration (once its checkpoint is written)
    with an :class:`IterationReport`: for live progress reports and per-iteration output.
    ``identity`` (JSON values by key) is added to the checkpoint's fingerprint: a checkpoint whose
    entries differ is refused, naming them (:class:`~.checkpoint.CheckpointMismatch`).
    """
    session_start = time.perf_counter()
    x0 = np.array(x0, dtype=float)
    reference = None if reference is None else np.asarray(reference, dtype=float)
    _validate(fine, coarse, x0, t0, t1, n_slices, tol, max_iterations, reference, wall_time_limit)
    times = time_points(t0, t1, n_slices)
    coarse = _with_executor(coarse, executor, allow_oversubscribe)
    _warn_idle_workers(executor, n_slices)
    pool = SerialExecutor() if executor is None else executor
    key = ckpt.fingerprint(x0, t0, t1, n_slices, reference, identity)

    progress = None if checkpoint is None else ckpt.load(checkpoint, key)
    saved = None if progress is None else progress.iteration
    try:
        if progress is None:
            earlier_total = 0.0
            progress = _initial_sweep(coarse, x0, times, reference is not None)
            progress.timings.total = time.perf_counter() - session_start
            if checkpoint is not None:
                ckpt.save(checkpoint, progress, key)
                saved = 0
        else:
            earlier_total = progress.timings.total
            logger.info("parareal: resuming from %s after iteration %d", checkpoint, saved)

        reason = _stop_reason(progress, tol, max_iterations)
        while reason is None:
            previous_final = progress.states[-1]
            _iterate(progress, fine, coarse, times, pool, project)
            final = progress.states[-1]
            progress.increments.append(relative_change(previous_final, final, positions))
            if reference is not None:
                progress.errors.append(relative_change(final, reference[-1], positions))
            elapsed = time.perf_counter() - session_start
            progress.timings.total = earlier_total + elapsed
            logger.info(
                "parareal k=%d eta~=%.3e eta=%s parallel sweep %.3fs serial sweep %.3fs",
                progress.iteration,
                progress.increments[-1],
                "n/a" if reference is None else f"{progress.errors[-1]:.3e}",
                progress.timings.parallel_sweeps[-1],
                progress.timings.serial_sweeps[-1],
            )
            if checkpoint is not None:
                ckpt.save(checkpoint, progress, key)
                saved = progress.iteration
            if on_iteration is not None:
                on_iteration(
                    IterationReport(
                        iteration=progress.iteration,
                        increment=progress.increments[-1],
                        error=progress.errors[-1] if reference is not None else None,
                        final_state=final,
                        elapsed=progress.timings.total,
                    )
                )
            reason = _stop_reason(progress, tol, max_iterations)
            if reason is None and wall_time_limit is not None and elapsed >= wall_time_limit:
                reason = "wall_time"
    except (TaskError, KeyboardInterrupt) as exc:
        if saved is not None:
            exc.add_note(
                f"parareal: the checkpoint {os.fspath(checkpoint)} holds iteration {saved}; "
                "rerun with the same checkpoint to resume from there"
            )
        raise

    progress.timings.total = earlier_total + (time.perf_counter() - session_start)
    return PararealResult(
        states=progress.states,
        times=times,
        increments=progress.increments,
        errors=progress.errors,
        iterations=progress.iteration,
        stop_reason=reason,
        timings=progress.timings,
    )
