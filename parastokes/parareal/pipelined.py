"""Pipelined (event-based) Parareal: every task starts as soon as its inputs exist.

Algorithm 1 alternates a parallel sweep (eq. 10) and a serial coarse sweep (eq. 11) with a barrier
between them. Here the same tasks run as a dependency graph (Minion 2010; Elwasif et al. 2011;
Berry et al. 2012; Ruprecht 2017; docs/parareal.md):

- the fine solve F_n^k = F(T_{n-1}, T_n, X_{n-1}^{k-1}) for n = k..N (eq. 10) starts once
  X_{n-1}^{k-1} exists;
- the coarse step G_n^k = G(T_{n-1}, T_n, X_{n-1}^k) for n = k+1..N (k = 0: the initial sweep,
  eq. 9) starts once X_{n-1}^k exists; a coarse solver with ``split`` (an extrapolated one, eq. 30)
  runs each of its N_G auxiliary solves as a task of its own and is combined on the manager;
- X_k^k = F_k^k, and X_n^k = project(F_n^k + (G_n^k - G_n^{k-1})) (eq. 11; a tracing coarse
  solver's own correction of its traces G_n^k, G_n^{k-1} instead) is formed on the
  manager as soon as its three inputs exist, by :func:`~parastokes.parareal.algorithm.correct`,
  the function Algorithm 1 uses: the iterates are Algorithm 1's, bit for bit.

Tasks wait in a priority queue and are handed to the executor while fewer than
``executor.workers`` run (all at once without that attribute): list scheduling with priority to
the coarse chain, the critical path (:func:`priority`; the cost model in
:mod:`~parastokes.parareal.schedule_model` uses the same). Iterations are closed in order: after
iteration k has completed, its checkpoint, report and stopping rule are exactly Algorithm 1's
(:class:`~parastokes.parareal.algorithm.Bookkeeping`); work already started for later iterations is
then cancelled (tasks not started) or discarded (tasks running). A task that fails stops new work
for its iteration and later ones; its TaskError is raised once every earlier iteration has
completed without meeting the stopping rule, so the same runs fail, with the same checkpoint, as
under Algorithm 1.
"""

from __future__ import annotations

import heapq
import itertools
import math
import queue
import time
from collections import deque
from collections.abc import Callable
from concurrent.futures import BrokenExecutor, Executor, Future
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..parallel import TaskError, WorkerDiedError
from . import checkpoint as ckpt
from .algorithm import (
    Bookkeeping,
    Problem,
    PropagatorLike,
    add_steps,
    coarse_error,
    correct,
    correction_of,
    fine_label,
    initial_guess,
    initial_state,
    is_tracing,
    step_of,
    stop_reason,
)
from .learned import SecantHistory
from .timings import Timings
from .transfer import take_step_counts

__all__ = ["AUXILIARY", "COARSE", "FINE", "priority", "run_pipelined"]

FINE, COARSE, AUXILIARY = "fine", "coarse", "auxiliary"


def priority(kind: str, n: int, k: int, index: int = 0) -> tuple[int, int, int, int]:
    """List-scheduling priority of a task, smaller first: coarse work (coarse steps and their
    auxiliary solves: the critical path) before fine solves, then lower iterations k, then lower
    slices n, then the auxiliary solver's index."""
    return (1 if kind == FINE else 0, k, n, index)


@dataclass
class _Job:
    kind: str
    n: int
    k: int
    fn: Callable[..., Any]
    args: tuple
    label: str
    index: int = 0


@dataclass
class _Group:
    """The auxiliary solves of one split coarse step, and how to combine them."""

    combine: Callable[[list[np.ndarray]], np.ndarray]
    values: list
    remaining: int
    args: tuple  # (T_{n-1}, T_n, X_{n-1}^k) of the coarse step
    begin: float = math.inf
    longest: float = 0.0  # the longest auxiliary solve


class _Workers:
    """List scheduling on an executor: ready jobs by priority, at most ``workers`` in flight.

    Each job in flight holds a worker slot (0, 1, ...), the worker it is drawn on in the Gantt
    chart; start and end are read on the manager when it is submitted and when it completes.
    """

    def __init__(self, executor: Executor) -> None:
        self.executor = executor
        self.limit = getattr(executor, "workers", None)
        self.ready: list[tuple[tuple, int, _Job]] = []
        self.order = itertools.count()
        self.flight: dict[Future, tuple[_Job, int, float]] = {}
        self.free: list[int] = []
        self.slots = 0
        self.done: queue.SimpleQueue = queue.SimpleQueue()

    def add(self, job: _Job) -> None:
        key = priority(job.kind, job.n, job.k, job.index)
        heapq.heappush(self.ready, (key, next(self.order), job))

    def start(self, blocked: float) -> None:
        """Submit ready jobs while a worker is free; drop those of iterations >= ``blocked``."""
        while self.ready and (self.limit is None or len(self.flight) < self.limit):
            _, _, job = heapq.heappop(self.ready)
            if job.k >= blocked:
                continue
            if self.free:
                slot = heapq.heappop(self.free)
            else:
                slot, self.slots = self.slots, self.slots + 1
            begin = time.perf_counter()
            try:
                future = self.executor.submit(job.fn, *job.args)
            except Exception as exc:  # e.g. a pool that a dead worker has broken
                future = Future()
                future.set_exception(exc)
            self.flight[future] = (job, slot, begin)
            future.add_done_callback(self._finished)

    def _finished(self, future: Future) -> None:
        self.done.put((future, time.perf_counter()))

    def next(self) -> tuple[_Job, Future, float, float, int]:
        """Wait for the next job to complete: (job, future, start, end, slot)."""
        future, end = self.done.get()
        job, slot, begin = self.flight.pop(future)
        heapq.heappush(self.free, slot)
        return job, future, begin, end, slot

    def cancel(self) -> None:
        """Drop the jobs not submitted and cancel those not started; running ones are left to
        finish (their results are never read)."""
        self.ready.clear()
        for future in self.flight:
            future.cancel()


def _is_broken(exc: BaseException) -> bool:
    return isinstance(exc, BrokenExecutor)


def _is_bystander(exc: BaseException) -> bool:
    """A task that failed only because another task broke the pool."""
    return isinstance(exc, BrokenExecutor) and not isinstance(exc, WorkerDiedError)


@dataclass
class _Pipeline:
    fine: PropagatorLike
    coarse: PropagatorLike
    times: np.ndarray
    project: Callable[[np.ndarray], np.ndarray] | None
    book: Bookkeeping
    workers: _Workers
    x: dict = field(default_factory=dict)  # (n, k) -> X_n^k for n >= k
    fine_values: dict = field(default_factory=dict)  # (n, k) -> F_n^k
    coarse_values: dict = field(default_factory=dict)  # (n, k) -> G_n^k
    groups: dict = field(default_factory=dict)  # (n, k) -> _Group
    runs: dict = field(default_factory=dict)  # (kind, n, k) -> (start, end)
    coarse_times: dict = field(default_factory=dict)  # (n, k) -> the time of G_n^k (gamma_G)
    coarse_steps: dict = field(default_factory=dict)  # (n, k) -> G_n^k's adaptive step counts
    fine_times: dict = field(default_factory=dict)  # (n, k) -> the time of F_n^k (gamma_F)
    tasks: list = field(default_factory=list)  # this session's Timings.tasks entries
    finished: set = field(default_factory=set)  # iterations whose X_N^k exists
    failures: dict = field(default_factory=dict)  # iteration -> TaskError
    progress: ckpt.Progress | None = None
    completed: int = -1
    earlier_tasks: list = field(default_factory=list)
    # kept solves found but not yet applied: (kind, n, k, value, seconds, steps). Applying them
    # from a queue, not from add_fine/add_coarse, keeps the stack flat when a resumed run replays
    # hundreds of kept steps (each applied value enables the next slice's tasks).
    replay: deque = field(default_factory=deque)
    guessed: bool = False  # X^0 came from the coarse solver's initial_guess
    # the learned correction's data (None: eq. 11); X_n^k then waits for X_n^{k-1}, whose
    # correction kept slice n's pair of iteration k - 2
    secant: SecantHistory | None = None

    @property
    def n_slices(self) -> int:
        return len(self.times) - 1

    @property
    def last(self) -> int:
        """The last iteration that may be needed."""
        return min(self.book.stopping.max_iterations or self.n_slices, self.n_slices)

    @property
    def blocked(self) -> float:
        """The lowest iteration with a failed task (no new work from there on)."""
        return min(self.failures, default=math.inf)

    # ---- tasks ---------------------------------------------------------------------------
    def kept(
        self, kind: str, n: int, k: int, args: tuple[float, float, np.ndarray]
    ) -> tuple[np.ndarray, float, dict[str, int] | None] | None:
        """The solve from the memo of a stopped session (:mod:`.solve_memo`), or None."""
        memo = self.book.memo
        return None if memo is None else memo.get(kind, n, k, *args)

    def keep(
        self,
        kind: str,
        n: int,
        k: int,
        args: tuple[float, float, np.ndarray],
        value: np.ndarray,
        seconds: float,
        steps: dict[str, int] | None = None,
    ) -> None:
        """Keep a completed solve (a coarse step with its adaptive step counts) in the memo
        (when the run has a checkpoint)."""
        if self.book.memo is not None:
            self.book.memo.put(kind, n, k, *args, value, seconds, steps)

    def add_fine(self, n: int, k: int) -> None:
        if k <= self.last and k < self.blocked:
            args = (self.times[n - 1], self.times[n], self.x[n - 1, k - 1])
            kept = self.kept(FINE, n, k, args)
            if kept is not None:
                self.replay.append((FINE, n, k, *kept))
                return
            self.workers.add(_Job(FINE, n, k, self.fine, args, fine_label(n, k)))

    def add_coarse(self, n: int, k: int) -> None:
        if k > self.last or k >= self.blocked:
            return
        t_start, t_end, x = self.times[n - 1], self.times[n], self.x[n - 1, k]
        kept = self.kept(COARSE, n, k, (t_start, t_end, x))
        if kept is not None:
            self.replay.append((COARSE, n, k, *kept))
            return
        split = None if is_tracing(self.coarse) else getattr(self.coarse, "split", None)
        try:
            parts = None if split is None else split(t_start, t_end, x)
        except Exception as exc:
            self.fail(k, coarse_error(exc, n, k))
            return
        if parts is None:
            step = step_of(self.coarse, k)
            self.workers.add(_Job(COARSE, n, k, step, (t_start, t_end, x), "coarse step"))
            return
        tasks, combine = parts
        self.groups[n, k] = _Group(combine, [None] * len(tasks), len(tasks), (t_start, t_end, x))
        for i, task in enumerate(tasks):
            self.workers.add(_Job(AUXILIARY, n, k, task.fn, tuple(task.args), task.label, i))

    # ---- values --------------------------------------------------------------------------
    def set_state(self, n: int, k: int, value: np.ndarray) -> None:
        self.x[n, k] = value
        if n == self.n_slices:
            self.finished.add(k)
            return
        self.add_coarse(n + 1, k)
        self.add_fine(n + 1, k + 1)

    def try_correct(self, n: int, k: int) -> None:
        keys = ((n, k) in self.fine_values, (n, k) in self.coarse_values)
        learned = self.secant is None or self.secant.has(n, k - 2)
        if (all(keys) and (n, k - 1) in self.coarse_values and (n, k) not in self.x
                and learned):
            value = correct(
                self.fine_values[n, k],
                self.coarse_values[n, k],
                self.coarse_values[n, k - 1],
                self.project,
                (n, k, float(self.times[n])),
                correction_of(self.coarse, self.times[n - 1], self.times[n], k),
                None if self.secant is None else (
                    self.secant, self.x[n - 1, k], self.x[n - 1, k - 1]),
            )
            self.set_state(n, k, value)
            if self.secant is not None and n > k + 1:
                self.try_correct(n, k + 1)  # (it may have waited for this one's pair)

    def coarse_done(
        self, n: int, k: int, value: np.ndarray, begin: float, end: float, duration: float,
        steps: dict[str, int] | None = None,
    ) -> None:
        self.runs[COARSE, n, k] = (begin, end)
        self.coarse_steps[n, k] = steps
        self.coarse_times[n, k] = duration
        self.coarse_values[n, k] = value
        if k == 0 and self.guessed:
            if all((m, 0) in self.coarse_values for m in range(1, self.n_slices + 1)):
                self.finished.add(0)
        elif k == 0:
            self.set_state(n, 0, initial_state(self.coarse, self.times[n - 1], self.times[n],
                                               value))
        else:
            self.try_correct(n, k)
        if n > k + 1:
            self.try_correct(n, k + 1)

    def fine_done(
        self, n: int, k: int, value: np.ndarray, begin: float, end: float, duration: float
    ) -> None:
        self.runs[FINE, n, k] = (begin, end)
        self.fine_times[n, k] = duration
        self.fine_values[n, k] = value
        if n == k:
            self.set_state(n, k, value)
        else:
            self.try_correct(n, k)

    def apply_kept(self) -> None:
        """Apply the kept solves found so far, and those they enable, one after the other."""
        while self.replay:
            kind, n, k, value, seconds, steps = self.replay.popleft()
            now = time.perf_counter()
            if kind == FINE:
                self.fine_done(n, k, value, now, now, seconds)
            else:
                self.coarse_done(n, k, value, now, now, seconds, steps)

    def job_done(self, job: _Job, future: Future, begin: float, end: float, slot: int) -> None:
        self.tasks.append([job.kind, job.n, job.k, begin, end, slot])
        exc = future.exception()
        n, k = job.n, job.k
        if exc is not None:
            self.task_failed(job, exc)
        elif job.kind == FINE:
            self.keep(FINE, n, k, job.args, future.result(), end - begin)
            self.fine_done(n, k, future.result(), begin, end, end - begin)
        elif job.kind == COARSE:
            self.keep(COARSE, n, k, job.args, future.result(), end - begin)
            self.coarse_done(n, k, future.result(), begin, end, end - begin)
        else:
            group = self.groups[n, k]
            group.values[job.index] = future.result()
            group.remaining -= 1
            group.begin = min(group.begin, begin)
            group.longest = max(group.longest, end - begin)
            if group.remaining == 0:
                del self.groups[n, k]
                start = time.perf_counter()
                try:
                    value = group.combine(group.values)
                except Exception as error:
                    self.fail(k, coarse_error(error, n, k))
                    return
                done = time.perf_counter()
                # the counts combine() took off this step's auxiliary results, on the manager
                steps = take_step_counts(self.coarse)
                # gamma_G as in Algorithm 1: as if the auxiliary solves had run at once
                duration = group.longest + done - start
                self.keep(COARSE, n, k, group.args, value, duration, steps)
                self.coarse_done(n, k, value, group.begin, done, duration, steps)

    # ---- failures ------------------------------------------------------------------------
    def error_of(self, job: _Job, exc: BaseException) -> TaskError:
        if job.kind == FINE:
            return TaskError(job.label, exc)
        if job.kind == AUXILIARY:
            return coarse_error(TaskError(job.label, exc), job.n, job.k)
        return coarse_error(exc, job.n, job.k)

    def task_failed(self, job: _Job, exc: BaseException) -> None:
        if not _is_broken(exc):
            self.fail(job.k, self.error_of(job, exc))
            return
        # A worker died: the pool fails every task in flight. Collect them all and name the
        # task that ran on the dead worker (as parallel.run_tasks does).
        errors = [(job.k, exc, job)]
        while self.workers.flight:
            other, future, *_ = self.workers.next()
            failure = None if future.cancelled() else future.exception()
            if failure is not None:
                errors.append((other.k, failure, other))
        causes = [e for e in errors if not _is_bystander(e[1])] or errors
        _, cause, culprit = min(causes, key=lambda e: e[0])
        error = self.error_of(culprit, cause)
        raise error from cause

    def fail(self, k: int, error: TaskError) -> None:
        """A task of iteration k failed: no new work from iteration k on (see the module)."""
        self.failures.setdefault(k, error)

    # ---- iterations ----------------------------------------------------------------------
    def close_iterations(self) -> str | None:
        """Close the completed iterations in order; return a stop reason, or raise the failure
        of the next iteration once nothing before it can stop the run."""
        while self.completed + 1 in self.finished:
            k = self.completed + 1
            reason = self.close(k)
            self.completed = k
            if reason is not None:
                return reason
        if self.failures and min(self.failures) == self.completed + 1:
            error = self.failures[self.completed + 1]
            raise error from error.original
        return None

    def durations(self, kind: str, slices: range, k: int) -> tuple[list[float], float]:
        """Run times of one kind of task of iteration k, and their span (first start to last
        end; 0 when there are none)."""
        runs = [self.runs[kind, n, k] for n in slices]
        span = max((e for _, e in runs), default=0.0) - min((b for b, _ in runs), default=0.0)
        times = self.coarse_times if kind == COARSE else self.fine_times
        return [times[n, k] for n in slices], span

    def sweep_steps(self, k: int) -> list[dict[str, int]]:
        """The adaptive step counts of iteration k's coarse steps summed as Algorithm 1 sums its
        serial sweep k (``add_steps``): ``[counts]``, or [] when none were counted."""
        counts = None
        for n in range(k + 1, self.n_slices + 1):
            counts = add_steps(counts, self.coarse_steps.get((n, k)))
        return [] if counts is None else [counts]

    def close(self, k: int) -> str | None:
        n_slices = self.n_slices
        coarse, coarse_span = self.durations(COARSE, range(k + 1, n_slices + 1), k)
        origin = self.book.origin
        tasks = self.earlier_tasks + [
            [kind, n, j, begin - origin, end - origin, slot]
            for kind, n, j, begin, end, slot in self.tasks
        ]
        if k == 0:
            x0 = self.x[0, 0]
            states = np.empty((n_slices + 1, *x0.shape))
            states[0] = x0
            for n in range(1, n_slices + 1):
                states[n] = self.x[n, 0]
            timings = Timings(coarse=[coarse], serial_sweeps=[coarse_span], tasks=tasks,
                              coarse_steps=self.sweep_steps(0))
            errors: list[float] | None = [] if self.book.reference is not None else None
            if is_tracing(self.coarse):
                traces = np.array([self.coarse_values[n, 0] for n in range(1, n_slices + 1)])
            else:
                traces = states[1:].copy()
            self.progress = ckpt.Progress(0, states, traces, errors=errors, timings=timings)
            self.book.initial_sweep_done(self.progress)
            return None
        progress = self.progress
        assert progress is not None  # set when iteration 0 closed, or by start (resumed)
        previous_final = progress.states[-1]
        states = progress.states.copy()  # X_n^k = X_n^{k-1} for n < k
        coarse_values = progress.coarse_values.copy()
        for n in range(k, n_slices + 1):
            states[n] = self.x[n, k]
        for n in range(k + 1, n_slices + 1):
            coarse_values[n - 1] = self.coarse_values[n, k]
        fine, fine_span = self.durations(FINE, range(k, n_slices + 1), k)
        timings = progress.timings
        timings.fine.append(fine)
        timings.coarse.append(coarse)
        timings.coarse_steps.extend(self.sweep_steps(k))
        timings.parallel_sweeps.append(fine_span)
        timings.serial_sweeps.append(coarse_span)
        timings.tasks = tasks
        progress.states = states
        progress.coarse_values = coarse_values
        progress.iteration = k
        return self.book.iteration_done(progress, previous_final)

    # ---- the run -------------------------------------------------------------------------
    def start(self, progress: ckpt.Progress | None, x0: np.ndarray) -> None:
        if progress is None:
            guess = initial_guess(self.coarse, self.times, x0)
            if guess is None:
                self.set_state(0, 0, x0)
                return
            # X^0 given at once: every coarse step of iteration 0 and every fine solve of
            # iteration 1 can start now; iteration 0 closes when all its traces exist
            self.guessed = True
            for n in range(self.n_slices + 1):
                self.x[n, 0] = guess[n]
            for n in range(1, self.n_slices + 1):
                self.add_coarse(n, 0)
                self.add_fine(n, 1)
            return
        k0 = progress.iteration
        self.progress, self.completed = progress, k0
        self.earlier_tasks = list(progress.timings.tasks)
        for n in range(k0 + 1, self.n_slices + 1):
            self.coarse_values[n, k0] = progress.coarse_values[n - 1]
        for n in range(k0, self.n_slices):
            self.x[n, k0] = progress.states[n]
            self.add_fine(n + 1, k0 + 1)

    def run(self) -> str:
        while True:
            self.apply_kept()
            reason = self.close_iterations()
            if reason is not None:
                return reason
            self.workers.start(self.blocked)
            if not self.workers.flight:
                raise RuntimeError("pipelined Parareal: no task left to run (please report)")
            self.job_done(*self.workers.next())


def run_pipelined(
    progress: ckpt.Progress | None, problem: Problem, book: Bookkeeping
) -> tuple[ckpt.Progress, str]:
    """Parareal's iterates by the pipelined schedule, from ``progress`` (a resumed run) or from
    the start; the counterpart of Algorithm 1's loop in :func:`parastokes.parareal.run`."""
    if progress is not None:
        reason = stop_reason(progress, book.stopping)
        if reason is not None:
            return progress, reason
    workers = _Workers(problem.executor)
    p = problem
    pipeline = _Pipeline(p.fine, p.coarse, p.times, p.project, book, workers, secant=p.secant)
    try:
        pipeline.start(progress, p.x0)
        reason = pipeline.run()
    finally:
        workers.cancel()
    assert pipeline.progress is not None  # a reason comes from a closed iteration
    return pipeline.progress, reason
