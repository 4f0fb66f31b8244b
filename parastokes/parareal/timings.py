"""Wall-time accounting of a Parareal run (the quantities of eq. 12)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, field

import numpy as np

from . import speedup as model

__all__ = [
    "MANAGER",
    "TASK_FIELDS",
    "Timings",
    "queued_durations",
    "queued_intervals",
    "queued_start",
]

#: The fields of one entry of ``Timings.tasks``.
TASK_FIELDS = ("kind", "slice", "iteration", "start", "end", "worker")

#: The ``worker`` of a task run on the manager (the standard schedule's coarse steps).
MANAGER = -1


@dataclass
class Timings:
    """Wall times in seconds, as recorded by :func:`parastokes.parareal.run`.

    - ``coarse[k]``: every G call of serial sweep k (k = 0 is the initial sweep eq. 9; sweep k >= 1
      is the correction eq. 11 for n = k+1..N).
    - ``fine[k-1]``: every F call of parallel sweep k (eq. 10, slices n = k..N).
    - ``serial_sweeps[k]``, ``parallel_sweeps[k-1]``: the sweeps themselves.
    - ``total``: the whole run, Upsilon_pr of eq. 12 (summed over sessions when resumed).
    - ``tasks``: one ``[kind, slice, iteration, start, end, worker]`` per task (``TASK_FIELDS``),
      kind ``"fine"``, ``"coarse"`` or ``"auxiliary"`` (one auxiliary solve of an extrapolated
      coarse step, pipelined schedule only), times in seconds since the run started, worker the
      slot 0, 1, ... that ran it or ``MANAGER`` (-1); the data of the Gantt chart.
    - ``schedule``: ``"standard"`` (Algorithm 1) or ``"pipelined"``.
    - ``coarse_steps[k]``: the steps ``{accepted, rejected, switches}`` of the adaptive
      auxiliary solves of serial sweep k (a coarse solver with ``rtol``; empty otherwise), summed
      over its coarse steps G_n^k, n = k+1..N, in both schedules; a step taken from a stopped
      session's memo brings the counts kept with it, and completed sweeps' counts come from the
      checkpoint.

    In the pipelined schedule ``parallel_sweeps[k-1]`` and ``serial_sweeps[k]`` are the spans
    (first start to last end) of iteration k's fine and coarse tasks, which overlap.
    """

    coarse: list[list[float]] = field(default_factory=list)
    fine: list[list[float]] = field(default_factory=list)
    serial_sweeps: list[float] = field(default_factory=list)
    parallel_sweeps: list[float] = field(default_factory=list)
    total: float = 0.0
    tasks: list[list] = field(default_factory=list)
    schedule: str = "standard"
    coarse_steps: list[dict[str, int]] = field(default_factory=list)

    @property
    def gamma_g(self) -> float:
        """gamma_G: the mean wall time of one G call over a slice, without the run's first call
        when there are others: that call carries G's one-off setup (:attr:`coarse_setup`)."""
        calls = np.concatenate(self.coarse)
        return float(np.mean(calls[1:] if calls.size > 1 else calls))

    @property
    def coarse_setup(self) -> float:
        """G's one-off setup (a factorization or a table kept for the later calls): the excess of
        the run's first G call over gamma_G, 0 when it was not slower or is the only call. It
        counts in the measured total and in the overhead of eq. 12, not in gamma_G."""
        calls = np.concatenate(self.coarse)
        return max(0.0, float(calls[0]) - self.gamma_g) if calls.size > 1 else 0.0

    @property
    def gamma_f(self) -> float:
        """gamma_F: the mean wall time of one F call over a slice."""
        return float(np.mean(np.concatenate(self.fine)))

    def overhead(self, n_slices: int) -> float:
        """Upsilon_oh of eq. 12: the measured total minus the ideal cost of the sweeps."""
        ideal = model.parareal_runtime(self.gamma_g, self.gamma_f, len(self.fine), n_slices)
        return self.total - ideal

    def add_task(
        self, kind: str, n: int, k: int, start: float, end: float, worker: int, origin: float
    ) -> None:
        """Record a task that ran from ``start`` to ``end`` (clock readings; ``origin`` is the
        reading at the start of the run)."""
        self.tasks.append([kind, n, k, start - origin, end - origin, worker])

    def to_dict(self) -> dict:
        """A JSON-ready copy (used by checkpoints and summary files)."""
        return asdict(self)


def queued_start(
    index: int, submitted: float, earlier: Sequence[float], workers: int | None
) -> float:
    """When task ``index`` of a first-in-first-out pool of ``workers`` started: when it was
    submitted, or, once all workers are busy, when the (index - workers + 1)-th of the tasks before
    it completed (``earlier``: their completion times, as far as known)."""
    if workers is None or index < workers or len(earlier) <= index - workers:
        return submitted
    return max(submitted, sorted(earlier)[index - workers])


def queued_intervals(
    submitted: Sequence[float], completed: Sequence[float], workers: int | None
) -> list[tuple[float, float, int]]:
    """(start, end, worker slot) of tasks on a first-in-first-out pool of ``workers``, from
    manager-side clocks.

    Task i is submitted at ``submitted[i]`` (increasing) and seen complete at ``completed[i]``. It
    starts when submitted, or, once all workers are busy, when the (i - workers + 1)-th of the tasks
    before it completes. ``workers=None`` means that every task starts at once. The slot is the one
    that became free first (for drawing: the pool does not say which worker ran what).
    """
    intervals = []
    free_at: list[float] = []  # when each slot became free
    for i, (start, end) in enumerate(zip(submitted, completed, strict=True)):
        start = queued_start(i, start, completed[:i], workers)
        idle = [s for s, t in enumerate(free_at) if t <= start]
        if idle or (workers is not None and len(free_at) >= workers):
            slot = min(idle or range(len(free_at)), key=lambda s: free_at[s])
        else:
            slot = len(free_at)
            free_at.append(start)
        free_at[slot] = end
        intervals.append((start, end, slot))
    return intervals


def queued_durations(
    submitted: Sequence[float], completed: Sequence[float], workers: int | None
) -> list[float]:
    """Run times of the tasks of :func:`queued_intervals`."""
    return [end - start for start, end, _ in queued_intervals(submitted, completed, workers)]
