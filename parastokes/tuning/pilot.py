"""The pilot window: the first few slices of the run, with the true fine reference.

:meth:`Pilot.prepare` computes the serial fine solution on P slices of the run's slice length (the
reference; it also proves that the fine solver is stable there and measures γ_F), and estimates the
fine solver's own time-discretization error over the first slice (one run at 2τ_f, Richardson's
estimate ``|F_τ - F_2τ| / (2^p - 1)``, eq. 34's measure; where 2τ_f is unstable, F at more than
half its stability limit, one at τ_f/2: ``2^p |F_τ - F_τ/2| / (2^p - 1)``). :meth:`Pilot.screen` is
one coarse call over the second slice from the reference: its defect against the reference, the
cheap accuracy measure that orders the search. :meth:`Pilot.measure` runs Algorithm 1 itself
(``parareal.run``) on the window for one coarse solver, giving η^k at T_P for k = 1..K and the
measured cost of its coarse calls. Fine solves whose input is the reference (slices n <= k in
iteration k) are taken from the reference instead of being recomputed, and the screen's coarse call
is reused. Costs (γ_F, γ_G) are CPU times of this process: on a shared machine they do not depend
on what else runs, wall times do.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import integrate
from ..core.contracts import System
from ..parareal import algorithm, metrics
from .space import TuningError

__all__ = ["Pilot", "PilotRun", "Screen", "own_error"]


def own_error(system: System, x0: np.ndarray, t0: float, t1: float,
              scheme: str | integrate.AnyScheme, dt: float,
              state: np.ndarray, rtol: float | None = None, atol: float | None = None) -> float:
    """Richardson's estimate of the error at ``t1`` of ``state``, the run of ``scheme`` at step
    ``dt`` from ``x0`` (eq. 34's measure): ``|F_τ - F_2τ| / (2^p - 1)`` from a run at 2τ, or,
    where 2τ is unstable (F at more than half its stability limit), ``2^p |F_τ - F_τ/2| /
    (2^p - 1)`` from a run at τ/2. Adaptive steps (``rtol``): ``|F_rtol - F_rtol/10|``, the
    run within a tenth of the tolerances taken as exact."""
    if rtol is not None:
        tighter = integrate.propagate(system, x0, t0, t1, scheme, dt, rtol=rtol / 10,
                                      atol=None if atol is None else atol / 10)
        return metrics.relative_change(state, tighter, system.positions)
    order = integrate.scheme_order(scheme)
    try:
        double = integrate.propagate(system, x0, t0, t1, scheme, 2.0 * dt)
        return metrics.relative_change(double, state, system.positions) / (2**order - 1)
    except integrate.BlowUpError:
        half = integrate.propagate(system, x0, t0, t1, scheme, 0.5 * dt)
        return metrics.relative_change(state, half, system.positions) * 2**order / (2**order - 1)


class _Reused:
    """The fine propagator, answering from the reference when its input is a reference state."""

    def __init__(self, fine: Any, times: np.ndarray, reference: np.ndarray) -> None:
        self.fine, self.times, self.reference = fine, times, reference

    def __call__(self, t_start: float, t_end: float, x: np.ndarray) -> np.ndarray:
        n = int(np.argmin(np.abs(self.times - t_start)))
        if n + 1 < len(self.times) and np.array_equal(x, self.reference[n]):
            return self.reference[n + 1].copy()
        return self.fine(t_start, t_end, x)


class _Timed:
    """A coarse propagator that records the CPU time of each call (no ``with_executor``, so
    ``parareal.run`` runs it as it is, in this process); ``known`` is a call already made
    (:class:`Screen`), answered without recomputing it."""

    def __init__(self, coarse: Any, known: Screen | None = None) -> None:
        self.coarse = coarse
        self.known = known
        self.seconds: list[float] = [] if known is None else [known.seconds]

    def __call__(self, t_start: float, t_end: float, x: np.ndarray) -> np.ndarray:
        known = self.known
        if known is not None and t_start == known.t0 and np.array_equal(x, known.x0):
            return known.state.copy()
        start = time.process_time()
        out = self.coarse(t_start, t_end, x)
        self.seconds.append(time.process_time() - start)
        return out


@dataclass
class PilotRun:
    """What one coarse solver did on the pilot window."""

    errors: list[float]  # η^k at T_P, k = 1..K
    coarse_seconds: float  # mean CPU time of one coarse call (all auxiliaries in this process)
    seconds: float  # wall time of the whole pilot run
    eta0: float  # |X^1 - X^0| at T_P: the coarse solution's own error, up to η¹
    calls: int  # coarse calls made (not the screen's, which was reused)


@dataclass
class Screen:
    """One coarse call over the second pilot slice from the reference state."""

    t0: float
    x0: np.ndarray
    state: np.ndarray  # G(x0)
    defect: float  # relative change of the positions against the reference at T_2 (eq. 34)
    seconds: float  # CPU time of the call


@dataclass
class Pilot:
    """The pilot window [t0, t0 + P ΔT] of ``system`` with its serial fine reference."""

    system: System
    fine: integrate.Propagator
    x0: np.ndarray
    t0: float
    slice_length: float
    n_slices: int
    reference: np.ndarray
    gamma_f: float
    fine_error: float
    seconds: float

    @property
    def times(self) -> np.ndarray:
        return algorithm.time_points(self.t0, self.t0 + self.n_slices * self.slice_length,
                                    self.n_slices)

    @classmethod
    def prepare(
        cls, fine: integrate.Propagator, x0: np.ndarray, t0: float, slice_length: float,
        n_slices: int,
    ) -> Pilot:
        """The reference on ``n_slices`` slices; raises TuningError if the fine solver blows up."""
        start, cpu = time.perf_counter(), time.process_time()
        system = fine.system
        times = algorithm.time_points(t0, t0 + n_slices * slice_length, n_slices)
        states = [system.project(np.array(x0, dtype=float))]
        worst = system.monitor(states[0])
        try:
            for n in range(n_slices):
                run = integrate.run(
                    system, states[-1], times[n], times[n + 1], fine.scheme, fine.dt,
                    rtol=fine.rtol, atol=fine.atol,
                )
                states.append(run.state)
                worst = max(worst, run.max_monitor)
        except integrate.BlowUpError as error:
            raise TuningError(
                f"the fine solver itself is unstable: {error}; reduce fine.dt (or choose a "
                "higher-order fine.scheme) before tuning"
            ) from None
        if not worst <= system.monitor_limit:
            raise TuningError(
                f"the fine solver leaves the stability monitor's limit ({worst:.3g} > "
                f"{system.monitor_limit:g}) on the first {n_slices} slices; reduce fine.dt"
            )
        gamma_f = (time.process_time() - cpu) / n_slices
        reference = np.array(states)
        fine_error = own_error(system, reference[0], times[0], times[1], fine.scheme, fine.dt,
                               reference[1], fine.rtol, fine.atol)
        return cls(system, fine, reference[0], t0, slice_length, n_slices, reference, gamma_f,
                   fine_error, time.perf_counter() - start)

    def screen(self, coarse: Any) -> Screen:
        """One call of ``coarse`` over the second slice from the reference state at T_1 (past
        the initial transient, which the first iteration corrects exactly; Algorithm 1 makes the
        same call in its first iteration), and its defect at T_2."""
        times, start_state = self.times, self.reference[1]
        start = time.process_time()
        state = coarse(float(times[1]), float(times[2]), start_state)
        seconds = time.process_time() - start
        if not np.all(np.isfinite(state)):
            raise integrate.BlowUpError(times[2], 0, math.nan, start_state, "non-finite state")
        defect = metrics.relative_change(state, self.reference[2], self.system.positions)
        return Screen(float(times[1]), start_state, state, float(defect), seconds)

    def measure(self, coarse: Any, iterations: int, known: Screen | None = None) -> PilotRun:
        """Algorithm 1 on the window: η^k at T_P for k = 1, ..., ``iterations`` (< P); ``known`` is
        the screen of the same solver (its call is reused)."""
        start = time.perf_counter()
        times = self.times
        fine = _Reused(self.fine, times, self.reference)
        timed = _Timed(coarse, known)
        res = algorithm.run(
            fine, timed, self.x0, t0=float(times[0]), t1=float(times[-1]),
            n_slices=self.n_slices, tol=0.0, max_iterations=iterations,
            reference=self.reference, positions=self.system.positions,
            project=self.system.project,
        )
        assert res.errors is not None  # (run with a reference)
        errors = [float(e) for e in res.errors]
        if not all(math.isfinite(e) for e in errors):
            raise integrate.BlowUpError(times[-1], 0, math.nan, self.x0, "non-finite iterate")
        return PilotRun(errors, float(np.mean(timed.seconds)), time.perf_counter() - start,
                        float(res.increments[0]), len(timed.seconds) - (known is not None))
