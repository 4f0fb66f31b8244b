"""Wall-time accounting of a Parareal run (the quantities of eq. 12)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, field

import numpy as np

from . import speedup as model

__all__ = ["Timings", "queued_durations"]


@dataclass
class Timings:
    """Wall times in seconds, as recorded by :func:`parastokes.parareal.run`.

    - ``coarse[k]``: every G call of serial sweep k (k = 0 is the initial sweep eq. 9; sweep k >= 1
      is the correction eq. 11 for n = k+1..N).
    - ``fine[k-1]``: every F call of parallel sweep k (eq. 10, slices n = k..N).
    - ``serial_sweeps[k]``, ``parallel_sweeps[k-1]``: the sweeps themselves.
    - ``total``: the whole run, Upsilon_pr of eq. 12 (summed over sessions when resumed).
    """

    coarse: list[list[float]] = field(default_factory=list)
    fine: list[list[float]] = field(default_factory=list)
    serial_sweeps: list[float] = field(default_factory=list)
    parallel_sweeps: list[float] = field(default_factory=list)
    total: float = 0.0

    @property
    def gamma_g(self) -> float:
        """gamma_G: the mean wall time of one G call over a slice."""
        return float(np.mean(np.concatenate(self.coarse)))

    @property
    def gamma_f(self) -> float:
        """gamma_F: the mean wall time of one F call over a slice."""
        return float(np.mean(np.concatenate(self.fine)))

    def overhead(self, n_slices: int) -> float:
        """Upsilon_oh of eq. 12: the measured total minus the ideal cost of the sweeps."""
        ideal = model.parareal_runtime(self.gamma_g, self.gamma_f, len(self.fine), n_slices)
        return self.total - ideal

    def to_dict(self) -> dict:
        """A JSON-ready copy (used by checkpoints and summary files)."""
        return asdict(self)


def queued_durations(
    submitted: Sequence[float], completed: Sequence[float], workers: int | None
) -> list[float]:
    """Run times of tasks on a first-in-first-out pool of ``workers``, from manager-side clocks.

    Task i is submitted at ``submitted[i]`` (increasing) and seen complete at ``completed[i]``. It
    starts when submitted, or, once all workers are busy, when the (i - workers + 1)-th of the tasks
    before it completes. ``workers=None`` means that every task starts at once.
    """
    durations = []
    for i, (start, end) in enumerate(zip(submitted, completed, strict=True)):
        if workers is not None and i >= workers:
            start = max(start, sorted(completed[:i])[i - workers])
        durations.append(end - start)
    return durations
