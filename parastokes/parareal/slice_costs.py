"""gamma_F and gamma_G of one slice, each solve timed on its own (the inputs of eqs. 12-14).

On N_c cores Algorithm 1 runs the N_G auxiliary solves of a coarse step at once (steps 4 and 15),
so gamma_G = max(auxiliary) + the combination's own time (:func:`coarse_step_time`); the
pipelined schedule runs each auxiliary solve as a task of its own. :func:`measure_slice_costs`
times one fine slice, every auxiliary solve and the combination (splitting the coarse call,
weighted sum of eq. 30, projection, grid transfer of eqs. 32-33) back to back, several times.
A fixed-step solve costs the same per step along a slice (same state size, same operations per
step), so a long slice can be timed over a few hundred steps and scaled by the step count; the
fine solver is timed over n and 2n steps, and ``linearity`` (t(2n) / 2 t(n), 1 when the per-call
cost is negligible) checks it in every repeat. A tracing coarse solver (HODMD-Parareal) is timed
as one task: its trace of iteration 1 over the whole slice (G1 over the window, G2 over the slice),
with one extrapolation (its HODMDs) as the overhead.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..core.contracts import TracingCoarse

__all__ = ["SliceCosts", "auxiliary_solvers", "coarse_step_time", "measure_slice_costs"]


def auxiliary_solvers(coarse: Any) -> tuple[list[Any], Any]:
    """The auxiliary propagators of a coarse solver (the solver itself when it is plain) in the
    order of its tasks, and its grid transfer (None without one)."""
    transfer = getattr(coarse, "transfer", None)
    inner = coarse.propagator if transfer is not None else coarse
    auxiliary = getattr(inner, "auxiliary", None)
    return ([p for row in auxiliary for p in row] if auxiliary else [inner]), transfer


def coarse_step_time(auxiliary: Sequence[float], overhead: float, workers: int | None) -> float:
    """gamma_G of one coarse step whose auxiliary solves take ``auxiliary`` seconds each, on
    ``workers`` workers (None: as many as needed), plus the combination's ``overhead``.

    N_G <= W: all at once, max(auxiliary) + overhead. N_G > W: the solves in W consecutive batches
    (``numpy.array_split``, as :class:`~parastokes.parareal.Extrapolated` batches them), one per
    worker: the longest batch + overhead; one worker: their sum + overhead.
    """
    if len(auxiliary) == 0:
        raise ValueError("auxiliary: need at least one auxiliary solve time")
    if workers is not None and workers < 1:
        raise ValueError(f"workers must be >= 1 (or None), got {workers!r}")
    times = np.asarray(auxiliary, dtype=float)
    if workers is None or len(times) <= workers:
        return float(times.max()) + overhead
    return max(float(batch.sum()) for batch in np.array_split(times, workers)) + overhead


@dataclass(frozen=True)
class SliceCosts:
    """Seconds per slice measured by :func:`measure_slice_costs`, one entry per repeat.

    ``fine[r]`` one fine slice; ``auxiliary[r][i]`` auxiliary solve i over a slice; ``overhead[r]``
    the combination's own time per coarse call (per call, not scaled); ``linearity[r]`` t(2n) /
    2 t(n) of the fine solver; ``fine_steps`` (timed n, per slice) and ``auxiliary_steps[i]``
    (timed, per slice) the step counts behind the scaling.
    """

    fine: list[float]
    auxiliary: list[list[float]]
    overhead: list[float]
    linearity: list[float]
    fine_steps: tuple[int, int]
    auxiliary_steps: list[tuple[int, int]]

    @property
    def n_auxiliary(self) -> int:
        return len(self.auxiliary[0])

    def gamma_ratio(self, workers: int | None = None) -> float:
        """Median over repeats of gamma_G / gamma_F, gamma_G by :func:`coarse_step_time`."""
        return statistics.median(
            coarse_step_time(aux, over, workers) / fine
            for aux, over, fine in zip(self.auxiliary, self.overhead, self.fine, strict=True)
        )

    def task_ratio(self) -> float:
        """Median over repeats of (max(auxiliary) + overhead) / gamma_F: the cost of one auxiliary
        task, the slowest one with the combination added (an upper bound for every task)."""
        return self.gamma_ratio(None)

    def as_dict(self) -> dict[str, Any]:
        return {
            "fine_slice_s": self.fine,
            "auxiliary_slice_s": self.auxiliary,
            "overhead_s": self.overhead,
            "linearity": self.linearity,
            "fine_steps": list(self.fine_steps),
            "auxiliary_steps": [list(s) for s in self.auxiliary_steps],
            "n_auxiliary": self.n_auxiliary,
            "gamma_F_s": statistics.median(self.fine),
            "gamma_ratio": self.task_ratio(),
        }


def _steps(solver: Any, t_start: float, t_end: float) -> int:
    return solver.n_steps(t_start, t_end) if hasattr(solver, "n_steps") else 1


def _span(solver: Any, steps: int | None, slice_length: float) -> float:
    """``steps`` steps of ``solver`` (the whole slice when None, when it has no fixed step, or
    when the slice is shorter)."""
    if steps is None or not hasattr(solver, "dt"):
        return slice_length
    return min(slice_length, steps * solver.dt)


def measure_slice_costs(
    fine: Any,
    coarse: Any,
    t_start: float,
    t_end: float,
    x0: np.ndarray,
    *,
    repeats: int = 3,
    fine_steps: int | None = 200,
    coarse_steps: int | None = 50,
    clock: Callable[[], float] = time.perf_counter,
) -> SliceCosts:
    """Time one slice [t_start, t_end] of ``fine`` and of every auxiliary solve of ``coarse``.

    Per repeat, back to back: the fine solver over n = ``fine_steps`` steps, every auxiliary solve
    over ``coarse_steps`` steps of the largest auxiliary step (from the restricted state on a
    coarse grid), the combination (``coarse.split`` and its combine function; restriction and
    prolongation for a plain solver on a coarse grid), and the fine solver over 2n steps. Each time
    is scaled to the slice by its step count; None times whole slices. Every solver is called once
    over one step before the first repeat (not timed). Raises ValueError for ``repeats`` < 1.
    """
    if repeats < 1:
        raise ValueError(f"repeats must be >= 1, got {repeats!r}")
    length = t_end - t_start

    def timed(fn: Callable[..., Any], *args: Any) -> tuple[Any, float]:
        start = clock()
        value = fn(*args)
        return value, clock() - start

    if isinstance(coarse, TracingCoarse):
        coarse_once, aux_steps = _tracing_timer(coarse, t_start, t_end, x0, timed)
    else:
        coarse_once, aux_steps = _auxiliary_timer(coarse, t_start, t_end, x0, coarse_steps,
                                                  timed)
    fine(t_start, t_start + _span(fine, 1, length), x0)  # warm-up: compile, caches
    fine_span = _span(fine, fine_steps, length)
    double_span = min(length, 2 * fine_span)
    n_fine = (_steps(fine, t_start, t_start + fine_span), _steps(fine, t_start, t_end))
    n_double = _steps(fine, t_start, t_start + double_span)
    fines, auxes, overheads, linear = [], [], [], []
    for _ in range(repeats):
        short = timed(fine, t_start, t_start + fine_span, x0)[1]
        aux, over = coarse_once()
        double = timed(fine, t_start, t_start + double_span, x0)[1]
        fines.append((short + double) / (n_fine[0] + n_double) * n_fine[1])
        auxes.append([t * total / done for t, (done, total) in zip(aux, aux_steps, strict=True)])
        overheads.append(over)
        linear.append(double / short * n_fine[0] / n_double)
    return SliceCosts(fines, auxes, overheads, linear, n_fine, aux_steps)


Timer = Callable[..., tuple[Any, float]]


def _auxiliary_timer(coarse: Any, t_start: float, t_end: float, x0: np.ndarray,
                     coarse_steps: int | None, timed: Timer) -> tuple[Callable, list]:
    """Times every auxiliary solve of ``coarse`` over ``coarse_steps`` steps and its combination
    (see :func:`measure_slice_costs`): the timer and the step counts (timed, per slice)."""
    length = t_end - t_start
    solvers, transfer = auxiliary_solvers(coarse)
    xc = x0 if transfer is None else transfer.restrict(x0)
    for solver in solvers:
        solver(t_start, t_start + _span(solver, 1, length), xc)  # warm-up: compile, caches
    widest = max(solvers, key=lambda p: getattr(p, "dt", 0.0))
    coarse_end = t_start + _span(widest, coarse_steps, length)
    aux_steps = [(_steps(p, t_start, coarse_end), _steps(p, t_start, t_end)) for p in solvers]
    split = getattr(coarse, "split", None)

    def once() -> tuple[list[float], float]:
        # split on the whole slice: the coefficients a run uses (steps rounded to whole counts
        # on a short span can coincide where the slice's do not); its tasks then run on the
        # short span, each scaled to the slice
        parts, t_split = timed(split, t_start, t_end, x0) if split else (None, 0.0)
        if parts is None:
            x_aux, over = (xc, 0.0) if transfer is None else timed(transfer.restrict, x0)
            values, aux = zip(*(timed(p, t_start, coarse_end, x_aux) for p in solvers), strict=True)
            if transfer is not None:
                over += timed(transfer.prolong, values[0])[1]
        else:
            tasks, combine = parts
            values, aux = zip(*(timed(task.fn, task.args[0], coarse_end, *task.args[2:])
                                for task in tasks), strict=True)
            over = t_split + timed(combine, list(values))[1]
        return list(aux), over

    return once, aux_steps


def _tracing_timer(coarse: Any, t_start: float, t_end: float, x0: np.ndarray,
                   timed: Timer) -> tuple[Callable, list]:
    """Times a tracing coarse solver as one task: its trace of iteration 1 over the slice, and its
    ``end_state`` (one HODMD per column group, as a correction runs) as the overhead."""
    coarse.trace(t_start, t_end, x0, 1)  # warm-up: compile, caches

    def once() -> tuple[list[float], float]:
        trace, traced = timed(coarse.trace, t_start, t_end, x0, 1)
        return [traced], timed(coarse.end_state, t_start, t_end, trace)[1]

    return once, [(1, 1)]
