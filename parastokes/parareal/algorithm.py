"""Algorithm 1 of the paper: Parareal with any fine and coarse propagators.

A propagator is any callable ``P(t_start, t_end, x) -> x`` over numpy arrays (section 3 writes it
``G(t_End, t_Start, X_Start)``). The engine knows nothing about physics: rods, vesicles and toy ODEs
are all driven the same way.
"""

from __future__ import annotations

import logging
import math
import os
import time
from collections.abc import Callable
from concurrent.futures import Executor, as_completed

import numpy as np

from . import checkpoint as ckpt
from .metrics import Positions, relative_change
from .result import PararealResult
from .timings import Timings, queued_durations

__all__ = ["PropagatorLike", "run", "serial_solution", "time_points"]

logger = logging.getLogger(__name__)

PropagatorLike = Callable[[float, float, np.ndarray], np.ndarray]


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


def _with_executor(coarse: PropagatorLike, executor: Executor | None) -> PropagatorLike:
    """Send the coarse combinator's auxiliary solvers to ``executor`` unless it has its own."""
    bind = getattr(coarse, "with_executor", None)
    if executor is None or bind is None or coarse.executor is not None:
        return coarse
    return bind(executor)


def _timed(propagator: PropagatorLike, t_start: float, t_end: float, x: np.ndarray):
    start = time.perf_counter()
    value = propagator(t_start, t_end, x)
    return value, time.perf_counter() - start


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
        states[n], elapsed = _timed(coarse, times[n - 1], times[n], states[n - 1])
        timings.coarse[0].append(elapsed)
    timings.serial_sweeps.append(time.perf_counter() - start)
    return ckpt.Progress(
        0, states, states[1:].copy(), errors=[] if with_errors else None, timings=timings
    )


def _parallel_sweep(
    fine: PropagatorLike, times: np.ndarray, states: np.ndarray, k: int, executor: Executor | None
) -> tuple[list[np.ndarray], list[float]]:
    """Eq. 10: X_n^{k'} = F(T_n, T_{n-1}, X_{n-1}^{k-1}) for n = k..N, and the F call times."""
    slices = range(k, len(times))
    if executor is None:
        pairs = [_timed(fine, times[n - 1], times[n], states[n - 1]) for n in slices]
        return [value for value, _ in pairs], [elapsed for _, elapsed in pairs]
    futures, submitted = [], []
    for n in slices:
        submitted.append(time.perf_counter())
        futures.append(executor.submit(fine, times[n - 1], times[n], states[n - 1]))
    seen = {}
    for future in as_completed(futures):
        seen[future] = time.perf_counter()
    completed = [seen[future] for future in futures]
    durations = queued_durations(submitted, completed, getattr(executor, "workers", None))
    return [future.result() for future in futures], durations


def _iterate(
    progress: ckpt.Progress,
    fine: PropagatorLike,
    coarse: PropagatorLike,
    times: np.ndarray,
    executor: Executor | None,
    project: Callable[[np.ndarray], np.ndarray] | None,
) -> None:
    """Iteration k = progress.iteration + 1 of Algorithm 1 (steps 9-18), in place."""
    k = progress.iteration + 1
    previous = progress.states
    start = time.perf_counter()
    fine_values, fine_times = _parallel_sweep(fine, times, previous, k, executor)
    progress.timings.parallel_sweeps.append(time.perf_counter() - start)
    progress.timings.fine.append(fine_times)

    states = previous.copy()  # X_n^k = X_n^{k-1} for n < k
    states[k] = fine_values[0]
    coarse_times = []
    start = time.perf_counter()
    for n in range(k + 1, len(times)):
        value, elapsed = _timed(coarse, times[n - 1], times[n], states[n - 1])
        coarse_times.append(elapsed)
        corrected = fine_values[n - k] + (value - progress.coarse_values[n - 1])  # eq. 11
        states[n] = corrected if project is None else project(corrected)
        progress.coarse_values[n - 1] = value
    progress.timings.serial_sweeps.append(time.perf_counter() - start)
    progress.timings.coarse.append(coarse_times)
    progress.states = states
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
) -> PararealResult:
    """Parareal (Algorithm 1): initial serial sweep eq. 9, then iterations of eqs. 10-11.

    Iteration k runs the fine solver on slices n = k..N (eq. 10) on ``executor`` (submitted as
    ``executor.submit(fine, T_{n-1}, T_n, X_{n-1}^{k-1})``; in-process when None), keeps
    X_n^k = X_n^{k-1} for n < k, sets X_k^k = X_k^{k'}, and corrects n = k+1..N serially by eq. 11,
    reusing the stored G(T_n, T_{n-1}, X_{n-1}^{k-1}); ``project`` is applied to every corrected
    state. A coarse combinator with ``with_executor`` (see :func:`extrapolated`) that has no
    executor of its own gets ``executor`` for its auxiliary solvers.

    The run stops when the relative increment eta~^k (eq. 34 at T_N over the rows of
    ``positions(state)``, default the whole state) is below ``tol``, when k = N (then ``states``
    equals the serial fine solution), at ``max_iterations``, or, after an iteration, once
    ``wall_time_limit`` seconds have passed in this call. With ``reference`` (the serial fine
    solution at T_0..T_N, see :func:`serial_solution`) the true error eta^k (eq. 34) is recorded.

    With ``checkpoint`` (a file path) the state is written atomically after the initial sweep and
    every iteration; when the file exists the run resumes from it and gives bit-identical results.
    Bad parameters raise ValueError before any propagator is called.
    """
    session_start = time.perf_counter()
    x0 = np.array(x0, dtype=float)
    reference = None if reference is None else np.asarray(reference, dtype=float)
    _validate(fine, coarse, x0, t0, t1, n_slices, tol, max_iterations, reference, wall_time_limit)
    times = time_points(t0, t1, n_slices)
    coarse = _with_executor(coarse, executor)
    key = ckpt.fingerprint(x0, t0, t1, n_slices, reference)

    progress = None if checkpoint is None else ckpt.load(checkpoint, key)
    if progress is None:
        earlier_total = 0.0
        progress = _initial_sweep(coarse, x0, times, reference is not None)
        progress.timings.total = time.perf_counter() - session_start
        if checkpoint is not None:
            ckpt.save(checkpoint, progress, key)
    else:
        earlier_total = progress.timings.total
        logger.info("parareal: resuming from %s after iteration %d", checkpoint, progress.iteration)

    reason = _stop_reason(progress, tol, max_iterations)
    while reason is None:
        previous_final = progress.states[-1]
        _iterate(progress, fine, coarse, times, executor, project)
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
        reason = _stop_reason(progress, tol, max_iterations)
        if reason is None and wall_time_limit is not None and elapsed >= wall_time_limit:
            reason = "wall_time"

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
