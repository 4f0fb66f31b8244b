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

from ..core.contracts import PropagatorLike, TracingCoarse, check_workers
from ..core.contracts import with_executor as _with_executor
from ..core.values import is_real
from ..integrate import BlowUpError
from ..parallel import SerialExecutor, TaskError, run_labelled
from . import checkpoint as ckpt
from . import options
from .learned import CORRECTIONS, SecantHistory
from .metrics import Positions, relative_change
from .options import Checkpoint, Reporting, Stopping
from .result import PararealResult
from .solve_memo import SolveMemo, memo_directory
from .timings import MANAGER, Timings, queued_intervals, queued_start
from .transfer import take_step_counts

__all__ = [
    "IterationReport",
    "PropagatorLike",
    "check_workers",
    "run",
    "serial_solution",
    "time_points",
]

logger = logging.getLogger(__name__)


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
    """The serial solution F(T_n, 0, x0) at every T_n, shape ``(n_slices + 1, *x0.shape)``.

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
    reference: np.ndarray | None,
) -> None:
    """Reject bad parameters before any propagator is called (the stopping rule's are checked
    by :class:`~.options.Stopping`)."""
    if not (callable(fine) and callable(coarse)):
        raise ValueError("fine and coarse must be callables P(t_start, t_end, x) -> x")
    if isinstance(n_slices, bool) or not isinstance(n_slices, int | np.integer) or n_slices < 1:
        raise ValueError(f"n_slices must be an integer >= 1, got {n_slices!r}")
    if not (is_real(t0) and is_real(t1) and math.isfinite(t0) and math.isfinite(t1) and t1 > t0):
        raise ValueError(f"need finite t0 < t1, got t0={t0!r}, t1={t1!r}")
    if x0.size == 0 or not np.all(np.isfinite(x0)):
        raise ValueError("x0 must be a non-empty array of finite numbers")
    if reference is not None and reference.shape != (n_slices + 1, *x0.shape):
        raise ValueError(
            f"reference must have shape {(n_slices + 1, *x0.shape)} (the serial fine solution at "
            f"T_0..T_N), got {reference.shape}"
        )


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


def _coarse_step(
    coarse: PropagatorLike, times: np.ndarray, n: int, x: np.ndarray, k: int
) -> tuple[np.ndarray, float, float]:
    """G(T_n, T_{n-1}, x) in serial sweep k, with the clock before and after; a failure names
    slice and k.

    Raises TaskError labelled ``"coarse solve of slice n in iteration k"`` (k = 0: the initial
    sweep), prefixed by the auxiliary solver's label when one of those failed on a worker.
    """
    start = time.perf_counter()
    try:
        value = coarse(times[n - 1], times[n], x)
    except TaskError as exc:
        raise coarse_error(exc, n, k) from exc.original
    except Exception as exc:
        raise coarse_error(exc, n, k) from exc
    return value, start, time.perf_counter()


def _kept_coarse_step(
    coarse: PropagatorLike,
    times: np.ndarray,
    n: int,
    x: np.ndarray,
    k: int,
    memo: SolveMemo | None,
    record: Timings,
    origin: float,
) -> tuple[np.ndarray, float, dict[str, int] | None]:
    """:func:`_coarse_step` of G_n^k (``step_of(coarse, k)``) through the memo of the iteration
    in progress: the value, its wall time and its adaptive step counts (``take_step_counts``;
    None on fixed steps); a step computed now is kept in the memo with its counts and recorded as
    a task of ``record``, a kept one brings the counts of the session that computed it."""
    kept = None if memo is None else memo.get("coarse", n, k, times[n - 1], times[n], x)
    if kept is not None:
        return kept
    value, start, end = _coarse_step(step_of(coarse, k), times, n, x, k)
    steps = take_step_counts(coarse)
    record.add_task("coarse", n, k, start, end, MANAGER, origin)
    if memo is not None:
        memo.put("coarse", n, k, times[n - 1], times[n], x, value, end - start, steps)
    return value, end - start, steps


def add_steps(total: dict[str, int] | None, steps: dict[str, int] | None
              ) -> dict[str, int] | None:
    """The step counts ``{accepted, rejected, switches}`` of a sweep so far (``total``, None
    before any counted step) with those of one more coarse step (None: not counted)."""
    if steps is None:
        return total
    if total is None:
        return dict(steps)
    return {key: total.get(key, 0) + value for key, value in steps.items()}


def coarse_error(exc: BaseException, n: int, k: int) -> TaskError:
    """The TaskError of a failed coarse step G_n^k (``exc`` may be an auxiliary solve's)."""
    label = f"coarse solve of slice {n} in iteration {k}"
    if isinstance(exc, TaskError):
        return TaskError(f"{exc.label} in the {label}", exc.original)
    return TaskError(label, exc)


def fine_label(n: int, k: int) -> str:
    """The label of the fine solve F_n^k in errors."""
    return f"fine solve of slice {n} in iteration {k}"


def correction_label(n: int, k: int) -> str:
    """The label of the correction (eq. 11) forming X_n^k in errors."""
    return f"correction (eq. 11) of slice {n} in iteration {k}"


def correct(
    fine_value: np.ndarray,
    coarse_value: np.ndarray,
    previous_coarse: np.ndarray,
    project: Callable[[np.ndarray], np.ndarray] | None,
    where: tuple[int, int, float] | None = None,
    difference: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
    secant: tuple[SecantHistory, np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """Eq. 11: X_n^k = F(X_{n-1}^{k-1}) + (G(X_{n-1}^k) - G(X_{n-1}^{k-1})), then ``project``.

    ``difference(new, old)`` replaces G(new) - G(old) for a tracing coarse solver
    (:class:`~parastokes.core.contracts.TracingCoarse`, :func:`correction_of`). ``secant`` =
    (history, X_{n-1}^k, X_{n-1}^{k-1}) adds the secant term of the learned correction
    (:mod:`.learned`; ``where`` = (n, k, T_n) required). Both schedules correct through this one
    function, so their iterates agree bit for bit. With ``where``, a corrected state that
    ``project`` rejects (a ValueError: e.g. a rod's frame made singular by a correction far larger
    than the state) is a numerical blow-up: a :class:`TaskError` labelled by
    :func:`correction_label` around a :class:`~parastokes.integrate.BlowUpError` whose last good
    state is F(X_{n-1}^{k-1}).
    """
    if difference is None:
        change = coarse_value - previous_coarse
    else:
        change = difference(coarse_value, previous_coarse)
    if secant is not None:
        assert where is not None  # (the secant term is slice n's of iteration k)
        history, new_input, old_input = secant
        change = change + history.correction(
            where[0], where[1], new_input, old_input, fine_value, previous_coarse
        )
    corrected = fine_value + change
    if project is None:
        return corrected
    try:
        return project(corrected)
    except ValueError as error:
        if where is None:
            raise
        n, k, t = where
        size = float(np.max(np.abs(change)))
        blow = BlowUpError(
            t, 0, math.nan, np.array(fine_value),
            f"the corrected state is not a valid state ({error}); the correction "
            f"G(X^k) - G(X^(k-1)) reaches {size:.3g}",
        )
        raise TaskError(correction_label(n, k), blow) from error


def is_tracing(coarse: PropagatorLike) -> bool:
    """Whether ``coarse`` keeps traces and corrects by its own rule (:class:`TracingCoarse`)."""
    return isinstance(coarse, TracingCoarse)


def step_of(coarse: PropagatorLike, k: int) -> PropagatorLike:
    """The coarse step G_n^k as a propagator ``(t_start, t_end, x) -> value``: ``coarse`` itself,
    or, for a tracing coarse solver, its ``trace`` of iteration k (picklable with ``coarse``)."""
    if is_tracing(coarse):
        return functools.partial(coarse.trace, k=k)  # type: ignore[attr-defined]
    return coarse


def correction_of(
    coarse: PropagatorLike, t_start: float, t_end: float, k: int
) -> Callable[[np.ndarray, np.ndarray], np.ndarray] | None:
    """The ``difference`` of :func:`correct` on slice (t_start, t_end) in iteration k: None
    (eq. 11) unless ``coarse`` is tracing."""
    if is_tracing(coarse):
        return functools.partial(coarse.correction, t_start, t_end, k=k)  # type: ignore[attr-defined]
    return None


def initial_guess(coarse: PropagatorLike, times: np.ndarray, x0: np.ndarray) -> np.ndarray | None:
    """X^0 at every T_n from a tracing coarse solver's ``initial_guess`` (the traces of iteration
    0 then start from it), or None: the sweep of eq. 9."""
    guess = getattr(coarse, "initial_guess", None) if is_tracing(coarse) else None
    return None if guess is None else guess(times, x0)


def initial_state(coarse: PropagatorLike, t_start: float, t_end: float,
                  value: np.ndarray) -> np.ndarray:
    """X_n^0 from the coarse step G_n^0 of the initial sweep (eq. 9): the value itself, or the
    end state of a tracing coarse solver's trace."""
    if is_tracing(coarse):
        return coarse.end_state(t_start, t_end, value)  # type: ignore[attr-defined]
    return value


class _Clocked:
    """An executor proxy that records, on the manager, when each task is submitted and completed.

    The tasks reach ``executor`` as they are (``fine`` is never wrapped). Completion times come
    from done-callbacks; :meth:`intervals` waits for all of them and reconstructs every task's
    start, end and worker slot on a first-in-first-out pool
    (:func:`~parastokes.parareal.timings.queued_intervals`). ``on_result(index, value, seconds)``,
    when given, is called as each task succeeds, with its wall time as far as the completions seen
    by then tell it.
    """

    def __init__(
        self,
        executor: Executor,
        on_result: Callable[[int, Any, float], None] | None = None,
    ) -> None:
        self.executor = executor
        self.on_result = on_result
        self.submitted: list[float] = []
        self.completed: dict[int, float] = {}
        self.settled = 0  # tasks whose done-callback has finished
        self._finished = threading.Condition()

    def __getattr__(self, name: str) -> Any:
        # anything else is the executor's (e.g. the batching context that run_tasks looks for)
        return getattr(self.executor, name)

    def submit(self, fn: Callable[..., Any], /, *args: Any) -> Future:
        index = len(self.submitted)
        self.submitted.append(time.perf_counter())
        future = self.executor.submit(fn, *args)
        future.add_done_callback(functools.partial(self._done, index))
        return future

    def _done(self, index: int, future: Future) -> None:
        with self._finished:
            self.completed[index] = end = time.perf_counter()
            # (a task that has completed started after enough of the earlier ones had ended)
            earlier = [t for i, t in self.completed.items() if i < index]
            workers = getattr(self.executor, "workers", None)
            seconds = end - queued_start(index, self.submitted[index], earlier, workers)
        if self.on_result is not None and not future.cancelled() and future.exception() is None:
            try:
                self.on_result(index, future.result(), seconds)
            except Exception:  # keeping a result is a convenience: the run goes on without it
                logger.warning("parareal: could not keep the result of task %d", index,
                               exc_info=True)
        with self._finished:  # (only now: the sweep ends after every result has been kept)
            self.settled += 1
            self._finished.notify_all()

    def intervals(self) -> list[tuple[float, float, int]]:
        """(start, end, worker slot) of every task (all must have completed)."""
        n = len(self.submitted)
        with self._finished:
            self._finished.wait_for(lambda: self.settled == n)
        completed = [self.completed[i] for i in range(n)]
        return queued_intervals(
            self.submitted, completed, getattr(self.executor, "workers", None)
        )


def _initial_sweep(
    coarse: PropagatorLike,
    x0: np.ndarray,
    times: np.ndarray,
    with_errors: bool,
    origin: float,
    memo: SolveMemo | None = None,
) -> ckpt.Progress:
    """Eq. 9: X_n^0 = G(T_n, T_{n-1}, X_{n-1}^0), keeping the G values for the first correction
    (steps kept in ``memo`` by a stopped session are taken from there); a tracing coarse solver's
    ``initial_guess`` gives X^0 at once, and its traces of iteration 0 start from it."""
    n_slices = len(times) - 1
    states = np.empty((n_slices + 1, *x0.shape))
    states[0] = x0
    timings = Timings(coarse=[[]])
    sweep_start = time.perf_counter()
    traces = []
    guess = initial_guess(coarse, times, x0)
    if guess is not None:  # X^0 given at once: the coarse steps of iteration 0 start from it
        states[:] = guess
    counts = None
    for n in range(1, n_slices + 1):
        value, seconds, steps = _kept_coarse_step(
            coarse, times, n, states[n - 1], 0, memo, timings, origin
        )
        if guess is None:
            states[n] = initial_state(coarse, times[n - 1], times[n], value)
        traces.append(value)
        timings.coarse[0].append(seconds)
        counts = add_steps(counts, steps)
    timings.serial_sweeps.append(time.perf_counter() - sweep_start)
    if counts is not None:
        timings.coarse_steps.append(counts)
    coarse_values = np.array(traces) if is_tracing(coarse) else states[1:].copy()
    return ckpt.Progress(
        0, states, coarse_values, errors=[] if with_errors else None, timings=timings
    )


def _parallel_sweep(
    fine: PropagatorLike,
    times: np.ndarray,
    states: np.ndarray,
    k: int,
    executor: Executor,
    memo: SolveMemo | None = None,
) -> tuple[list[np.ndarray], list[float], list[tuple[int, float, float, int]]]:
    """Eq. 10: X_n^{k'} = F(T_n, T_{n-1}, X_{n-1}^{k-1}) for n = k..N.

    One labelled task per slice (``"fine solve of slice n in iteration k"``), submitted as
    ``executor.submit(fine, T_{n-1}, T_n, X_{n-1}^{k-1})``, except the solves that ``memo`` holds
    from a stopped session; each solve is kept in ``memo`` as it completes. Returns the values and
    wall times of slices k..N and (n, start, end, worker) of the tasks that ran now.
    """
    args = {n: (times[n - 1], times[n], states[n - 1]) for n in range(k, len(times))}
    kept = {} if memo is None else {n: memo.get("fine", n, k, *a) for n, a in args.items()}
    todo = [n for n in args if kept.get(n) is None]

    def keep(index: int, value: np.ndarray, seconds: float) -> None:
        assert memo is not None  # keep is given with a memo only
        memo.put("fine", todo[index], k, *args[todo[index]], value, seconds)

    clock = _Clocked(executor, None if memo is None else keep)
    values = run_labelled(
        clock, fine, [args[n] for n in todo], [fine_label(n, k) for n in todo]
    )
    runs = [(n, *interval) for n, interval in zip(todo, clock.intervals(), strict=True)]
    found = {n: (v, end - begin) for v, (n, begin, end, _) in zip(values, runs, strict=True)}
    found.update({n: entry[:2] for n, entry in kept.items() if entry is not None})
    return [found[n][0] for n in args], [found[n][1] for n in args], runs


def _iterate(
    progress: ckpt.Progress,
    fine: PropagatorLike,
    coarse: PropagatorLike,
    times: np.ndarray,
    executor: Executor,
    project: Callable[[np.ndarray], np.ndarray] | None,
    origin: float,
    memo: SolveMemo | None = None,
    secant: SecantHistory | None = None,
) -> None:
    """Iteration k = progress.iteration + 1 of Algorithm 1 (steps 9-18); with ``secant``, the
    learned correction (:mod:`.learned`).

    ``progress`` is updated only once the iteration has completed, so an error or an interrupt
    part-way leaves it (and the checkpoint written from it) at iteration k - 1; the solves that
    completed before are in ``memo``, and a rerun takes them from there.
    """
    k = progress.iteration + 1
    start = time.perf_counter()
    fine_values, fine_times, fine_runs = _parallel_sweep(
        fine, times, progress.states, k, executor, memo
    )
    parallel_time = time.perf_counter() - start
    record = Timings()
    for n, begin, end, slot in fine_runs:
        record.add_task("fine", n, k, begin, end, slot, origin)

    states = progress.states.copy()  # X_n^k = X_n^{k-1} for n < k
    coarse_values = progress.coarse_values.copy()
    states[k] = fine_values[0]
    coarse_times = []
    counts = None
    start = time.perf_counter()
    for n in range(k + 1, len(times)):
        value, seconds, steps = _kept_coarse_step(
            coarse, times, n, states[n - 1], k, memo, record, origin
        )
        coarse_times.append(seconds)
        counts = add_steps(counts, steps)
        states[n] = correct(
            fine_values[n - k], value, coarse_values[n - 1], project, (n, k, float(times[n])),
            correction_of(coarse, times[n - 1], times[n], k),
            None if secant is None else (secant, states[n - 1], progress.states[n - 1]),
        )
        coarse_values[n - 1] = value
    serial_time = time.perf_counter() - start
    if counts is not None:
        progress.timings.coarse_steps.append(counts)

    progress.timings.parallel_sweeps.append(parallel_time)
    progress.timings.fine.append(fine_times)
    progress.timings.serial_sweeps.append(serial_time)
    progress.timings.coarse.append(coarse_times)
    progress.timings.tasks.extend(record.tasks)
    progress.states = states
    progress.coarse_values = coarse_values
    progress.iteration = k


def stop_reason(progress: ckpt.Progress, stopping: Stopping) -> str | None:
    """Why the run stops after ``progress.iteration`` (see :data:`~.result.STOP_REASONS`), or
    None; the wall-time limit is checked by :class:`Bookkeeping`."""
    k = progress.iteration
    if k == 0:
        return None
    if progress.increments[-1] < stopping.tol:
        return "tolerance"
    if k == len(progress.states) - 1:
        return "all_slices"
    if stopping.max_iterations is not None and k >= stopping.max_iterations:
        return "max_iterations"
    return None


class Bookkeeping:
    """What both schedules do once an iteration has completed: eta~^k and eta^k (eq. 34), the
    run's total time, the log line, the checkpoint, the report and the stopping rule; the one
    holder of ``run``'s resolved options (:mod:`.options`) for both schedules.

    ``origin`` is the clock reading at the start of the run (earlier sessions of a resumed run
    included), so ``clock() - origin`` is the run's elapsed time.
    """

    def __init__(
        self,
        stopping: Stopping,
        checkpoint: Checkpoint | None,
        reporting: Reporting,
        reference: np.ndarray | None,
        positions: Positions | None,
        key: dict[str, Any],
        session_start: float,
    ) -> None:
        self.stopping = stopping
        self.checkpoint = None if checkpoint is None else checkpoint.path
        self.reporting = reporting
        self.reference = reference
        self.positions = positions
        self.key = key
        self.session_start = session_start
        self.earlier_total = 0.0
        self.saved: int | None = None
        #: the solves of the iterations in progress (None without checkpoint)
        self.memo = None if checkpoint is None else SolveMemo(
            memo_directory(checkpoint.path), key
        )
        #: the learned correction's data, saved with every checkpoint (None: eq. 11)
        self.secant: SecantHistory | None = None

    def save(self, progress: ckpt.Progress) -> None:
        """Write the checkpoint of ``progress`` (with the learned correction's data)."""
        assert self.checkpoint is not None and self.memo is not None  # (made together)
        if self.secant is not None:
            progress.extra = self.secant.to_arrays()
        ckpt.save(self.checkpoint, progress, self.key)
        self.saved = progress.iteration
        self.memo.forget(progress.iteration)

    @property
    def origin(self) -> float:
        """The clock reading at the start of the run."""
        return self.session_start - self.earlier_total

    def resume(self, progress: ckpt.Progress) -> None:
        """Continue a run loaded from the checkpoint."""
        self.earlier_total = progress.timings.total
        self.saved = progress.iteration

    def initial_sweep_done(self, progress: ckpt.Progress) -> None:
        """Eq. 9 has completed: log its adaptive coarse steps, write the first checkpoint."""
        progress.timings.total = time.perf_counter() - self.session_start
        if progress.timings.coarse_steps:
            logger.info("parareal k=0 adaptive coarse steps %s", progress.timings.coarse_steps[0])
        if self.checkpoint is not None:
            self.save(progress)

    def iteration_done(self, progress: ckpt.Progress, previous_final: np.ndarray) -> str | None:
        """Iteration ``progress.iteration`` has completed (X^{k-1}_N was ``previous_final``):
        record, save, report; return why the run stops now, or None."""
        final = progress.states[-1]
        progress.increments.append(relative_change(previous_final, final, self.positions))
        error = None
        if self.reference is not None:
            assert progress.errors is not None  # a run with a reference records eta^k
            error = relative_change(final, self.reference[-1], self.positions)
            progress.errors.append(error)
        elapsed = time.perf_counter() - self.session_start
        progress.timings.total = self.earlier_total + elapsed
        logger.info(
            "parareal k=%d eta~=%.3e eta=%s parallel sweep %.3fs serial sweep %.3fs",
            progress.iteration,
            progress.increments[-1],
            "n/a" if error is None else f"{error:.3e}",
            progress.timings.parallel_sweeps[-1],
            progress.timings.serial_sweeps[-1],
        )
        if len(progress.timings.coarse_steps) > progress.iteration:
            logger.info("parareal k=%d adaptive coarse steps %s", progress.iteration,
                        progress.timings.coarse_steps[progress.iteration])
        if self.checkpoint is not None:
            self.save(progress)
        if self.reporting.on_iteration is not None:
            self.reporting.on_iteration(
                IterationReport(
                    iteration=progress.iteration,
                    increment=progress.increments[-1],
                    error=error,
                    final_state=final,
                    elapsed=progress.timings.total,
                )
            )
        reason = stop_reason(progress, self.stopping)
        limit = self.stopping.wall_time_limit
        if reason is None and limit is not None and elapsed >= limit:
            reason = "wall_time"
        return reason


@dataclass(frozen=True)
class Problem:
    """What a schedule iterates: F, G (bound to its executor as ``run`` decides), x0, the time
    points T_0..T_N, the executor of the tasks and the projection of corrected states."""

    fine: PropagatorLike
    coarse: PropagatorLike
    x0: np.ndarray
    times: np.ndarray
    executor: Executor
    project: Callable[[np.ndarray], np.ndarray] | None
    #: the learned correction's data (``correction="secant"``), or None: eq. 11
    secant: SecantHistory | None = None


def _run_standard(
    progress: ckpt.Progress | None, problem: Problem, book: Bookkeeping
) -> tuple[ckpt.Progress, str]:
    """Algorithm 1: the initial sweep (unless resumed), then iterations until a stop reason."""
    p = problem
    if progress is None:
        progress = _initial_sweep(
            p.coarse, p.x0, p.times, book.reference is not None, book.origin, book.memo
        )
        book.initial_sweep_done(progress)
    reason = stop_reason(progress, book.stopping)
    while reason is None:
        previous_final = progress.states[-1]
        _iterate(
            progress, p.fine, p.coarse, p.times, p.executor, p.project, book.origin, book.memo,
            p.secant,
        )
        reason = book.iteration_done(progress, previous_final)
    return progress, reason


def _check_correction(correction: str, coarse: PropagatorLike) -> None:
    """Refuse an unknown correction, and the secant correction with a tracing coarse solver
    (whose correction is not G(new) - G(old))."""
    if correction not in CORRECTIONS:
        raise ValueError(f"correction must be one of {CORRECTIONS}, got {correction!r}")
    if correction == "secant" and is_tracing(coarse):
        raise ValueError("correction 'secant' needs a coarse solver whose correction is "
                         "G(new) - G(old), not a tracing one: use correction 'classical'")


#: The schedules of :func:`run`.
SCHEDULES = ("standard", "pipelined")


def run(
    fine: PropagatorLike,
    coarse: PropagatorLike,
    x0: np.ndarray,
    t0: float,
    t1: float,
    n_slices: int,
    tol: float | None = None,
    max_iterations: int | None = None,
    executor: Executor | None = None,
    reference: np.ndarray | None = None,
    project: Callable[[np.ndarray], np.ndarray] | None = None,
    positions: Positions | None = None,
    checkpoint: str | os.PathLike | Checkpoint | None = None,
    wall_time_limit: float | None = None,
    allow_oversubscribe: bool = False,
    on_iteration: Callable[[IterationReport], None] | None = None,
    schedule: str = "standard",
    identity: dict[str, Any] | None = None,
    *,
    stopping: Stopping | None = None,
    reporting: Reporting | None = None,
    correction: str = "classical",
) -> PararealResult:
    """Parareal (Algorithm 1): the initial serial sweep eq. 9, then iterations of eqs. 10-11.

    Parameters
    ----------
    fine, coarse
        Propagators ``P(t_start, t_end, x) -> x`` over numpy arrays: F and G.
    x0
        The initial state X_0 at ``t0``.
    t0, t1, n_slices
        The interval, cut into N = ``n_slices`` slices at T_n = t0 + n (t1 - t0) / N.
    stopping
        A :class:`~.options.Stopping` (``tol``, ``max_iterations``, ``wall_time_limit``), or
        these as the flat keywords ``tol=`` (required in that form), ``max_iterations=`` and
        ``wall_time_limit=``.
    checkpoint
        A :class:`~.options.Checkpoint` (``path``, ``identity``, ``resume``), or a file path, with
        the flat keyword ``identity=``. None: no checkpoint.
    reporting
        A :class:`~.options.Reporting` (``on_iteration``), or the flat keyword ``on_iteration=``.
    executor
        Where the fine solves of each parallel sweep run (any ``concurrent.futures.Executor``;
        ``executor.workers``, when present, says how many run at once). None: in-process.
    reference
        The serial fine solution at T_0..T_N (:func:`serial_solution`); the true error eta^k of
        eq. 34 is then recorded.
    project
        Applied to every corrected state (e.g. re-orthonormalizing a rod's frames).
    positions
        The rows over which eq. 34 measures eta~^k and eta^k (default: the whole state).
    allow_oversubscribe
        Let a coarse solver's N_G auxiliary solvers outnumber the executor's workers
        (:func:`check_workers`).
    schedule
        ``"standard"`` (Algorithm 1) or ``"pipelined"`` (:mod:`~.pipelined`): the same iterates,
        bit for bit.
    correction
        ``"classical"`` (eq. 11) or ``"secant"``: eq. 11 plus a secant estimate of (F - G)' from
        the slice's previous iterates (:mod:`~.learned`; its data are saved with the checkpoint;
        not with a tracing coarse solver).

    Returns
    -------
    PararealResult
        The iterate X^K at T_0..T_N, eta~^k and eta^k for k = 1..K, K, why it stopped, timings.

    Raises
    ------
    TypeError
        When an option is given both as a group and as one of its flat keywords (naming both),
        or no tolerance is given.
    ValueError
        On bad parameters, before any propagator is called.
    parastokes.parallel.TaskError
        When a fine or coarse solve fails (raises, or its worker dies), labelled
        ``"fine solve of slice n in iteration k"`` or ``"coarse solve of slice n in iteration k"``
        (k = 0: the initial sweep). The checkpoint then holds iteration k - 1, and a rerun with it
        resumes from there (so does a rerun after ``KeyboardInterrupt``).

    Notes
    -----
    Iteration k runs F on slices n = k..N (eq. 10) as ``executor.submit(fine, T_{n-1}, T_n,
    X_{n-1}^{k-1})``, keeps X_n^k = X_n^{k-1} for n < k, sets X_k^k = X_k^{k'} and corrects
    n = k+1..N serially by eq. 11, reusing the stored G(T_n, T_{n-1}, X_{n-1}^{k-1}).

    Under the standard schedule a coarse solver with ``with_executor`` (:func:`extrapolated`) and
    no executor of its own gets ``executor`` for its auxiliary solvers, whose number N_G must not
    exceed the executor's workers (Algorithm 1's N_G <= N_c) unless ``allow_oversubscribe``. Under
    ``"pipelined"`` every fine solve, coarse step and auxiliary solve is a task on ``executor``
    (so ``coarse`` must pickle like ``fine``) and the rule does not apply. More workers than
    slices gives a RuntimeWarning.

    The stopping rule is checked after every iteration (:class:`~.options.Stopping`). The
    checkpoint is written atomically after the initial sweep and every iteration; an existing one
    of the same problem (and ``identity``) is resumed with bit-identical results, one of another
    is refused (:class:`~.checkpoint.CheckpointMismatch`). Every fine solve and coarse step of
    the iterations in progress is also kept as it completes (:mod:`.solve_memo`), so a resumed
    run repeats none of them. ``on_iteration`` is called after each
    checkpoint write with an :class:`IterationReport`. See docs/parareal.md.
    """
    session_start = time.perf_counter()
    stopping, saving, reporting = options.resolve(
        tol=tol, max_iterations=max_iterations, wall_time_limit=wall_time_limit,
        checkpoint=checkpoint, identity=identity, on_iteration=on_iteration,
        stopping=stopping, reporting=reporting,
    )
    x0 = np.array(x0, dtype=float)
    reference = None if reference is None else np.asarray(reference, dtype=float)
    _validate(fine, coarse, x0, t0, t1, n_slices, reference)
    if schedule not in SCHEDULES:
        raise ValueError(f"schedule must be one of {SCHEDULES}, got {schedule!r}")
    _check_correction(correction, coarse)
    times = time_points(t0, t1, n_slices)
    if schedule == "standard":  # (pipelined: the auxiliary solves are tasks of its own)
        coarse = _with_executor(coarse, executor, allow_oversubscribe)
    _warn_idle_workers(executor, n_slices)
    pool = SerialExecutor() if executor is None else executor
    key = ckpt.fingerprint(
        x0, t0, t1, n_slices, reference, None if saving is None else saving.identity
    )
    if correction != "classical":  # (a checkpoint of another correction is refused)
        key["correction"] = correction
    book = Bookkeeping(stopping, saving, reporting, reference, positions, key, session_start)

    resume = saving is not None and saving.resume
    progress = ckpt.load(saving.path, key) if saving is not None and saving.resume else None
    if progress is not None:
        book.resume(progress)
        logger.info("parareal: resuming from %s after iteration %d", book.checkpoint, book.saved)
    if book.memo is not None and not resume:
        book.memo.clear()  # solves kept by an earlier run at this path
    elif book.memo is not None and book.memo.count():
        logger.info(
            "parareal: %d solves of the stopped iteration kept in %s are reused where they match",
            book.memo.count(), book.memo.directory,
        )
    if schedule == "standard":
        strategy = _run_standard
    else:
        from .pipelined import run_pipelined  # (pipelined.py builds on this module)

        strategy = run_pipelined
    try:
        if correction == "secant":  # (resumed: the training data saved with the checkpoint)
            book.secant = SecantHistory.from_arrays({} if progress is None else progress.extra)
        problem = Problem(fine, coarse, x0, times, pool, project, book.secant)
        progress, reason = strategy(progress, problem, book)
    except (TaskError, KeyboardInterrupt) as exc:
        memo, saved_to = book.memo, book.checkpoint
        kept = 0 if memo is None else memo.count()
        held = [] if book.saved is None or saved_to is None else [
            f"the checkpoint {os.fspath(saved_to)} holds iteration {book.saved}"]
        if kept and memo is not None:
            held.append(f"{memo.directory} keeps {kept} solves of the iteration after it")
        if held:
            exc.add_note(
                f"parareal: {' and '.join(held)}; rerun with the same checkpoint to resume from "
                "there"
            )
        raise

    if book.memo is not None and reason != "wall_time":
        # a finished run forgets the solves of later iterations the pipelined schedule had
        # completed; a wall-time stop keeps them for the call that continues it
        book.memo.clear()
    progress.timings.total = book.earlier_total + (time.perf_counter() - session_start)
    progress.timings.schedule = schedule
    return PararealResult(
        states=progress.states,
        times=times,
        increments=progress.increments,
        errors=progress.errors,
        iterations=progress.iteration,
        stop_reason=reason,
        timings=progress.timings,
    )
