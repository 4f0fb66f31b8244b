"""The outcome of a Parareal run: the iterate, its history, timings and speedups."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TypedDict

import numpy as np

from . import speedup as model
from .timings import Timings

__all__ = ["STOP_REASONS", "PararealResult", "Speedups"]

#: Why a run stopped: eta~^k < tol; k reached N (the result is the serial fine solution);
#: k reached max_iterations; the wall-time limit was reached after an iteration.
STOP_REASONS = ("tolerance", "all_slices", "max_iterations", "wall_time")


class Speedups(TypedDict):
    """What :meth:`PararealResult.speedup` returns."""

    measured: float
    theoretical: float
    bound: float
    gamma_G: float
    gamma_F: float
    gamma_ratio: float
    coarse_setup: float
    overhead: float
    serial_time: float
    serial_time_estimated: bool
    schedule: str


@dataclass
class PararealResult:
    """Result of :func:`parastokes.parareal.run`.

    ``states[n]`` is X_n^K at T_n (n = 0..N) after the last iteration K = ``iterations``;
    ``increments[k-1]`` is eta~^k and ``errors[k-1]`` is eta^k (eq. 34, at the final time T_N;
    ``errors`` is None without a reference).
    """

    states: np.ndarray
    times: np.ndarray
    increments: list[float]
    errors: list[float] | None
    iterations: int
    stop_reason: str
    timings: Timings

    @property
    def n_slices(self) -> int:
        """N_c: the number of time slices."""
        return len(self.times) - 1

    @property
    def converged(self) -> bool:
        """True when the run stopped on the tolerance or because k reached N."""
        return self.stop_reason in ("tolerance", "all_slices")

    def speedup(self, serial_time: float | None = None) -> Speedups:
        """Speedups of eqs. 14-15 from the recorded timings.

        - ``measured``: Upsilon_F / Upsilon_pr, with Upsilon_pr the measured total and Upsilon_F the
          measured serial fine time ``serial_time`` when given, else N_c gamma_F (eq. 13);
        - ``theoretical``: eq. 14 with Upsilon_oh = 0 and the measured gamma_G, gamma_F;
        - ``bound``: eq. 15;

        for a run of the pipelined schedule their counterparts for that schedule
        (:func:`~parastokes.parareal.speedup.schedule_speedups`).
        Also returned: gamma_G, gamma_F, their ratio, G's one-off setup (``coarse_setup``, the
        excess of its first call, left out of gamma_G), the overhead Upsilon_oh of eq. 12, whether
        the serial time was estimated and the schedule.
        """
        t = self.timings
        n, k = self.n_slices, self.iterations
        estimated = serial_time is None
        serial = n * t.gamma_f if serial_time is None else float(serial_time)
        theoretical, bound = model.schedule_speedups(t.schedule, t.gamma_g, t.gamma_f, k, n)
        return {
            "measured": serial / t.total,
            "theoretical": theoretical,
            "bound": bound,
            "gamma_G": t.gamma_g,
            "gamma_F": t.gamma_f,
            "gamma_ratio": t.gamma_g / t.gamma_f,
            "coarse_setup": t.coarse_setup,
            "overhead": t.overhead(n),
            "serial_time": serial,
            "serial_time_estimated": estimated,
            "schedule": t.schedule,
        }
