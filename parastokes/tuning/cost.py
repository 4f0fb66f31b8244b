"""Predictions from pilot measurements: iterations to reach η*, γ_G/γ_F, speedup (eqs. 12-15).

- Iterations. The pilot gives η^k at T_P for k = 1..K. Errors of a stable coarse solver accumulate
  along the run roughly in proportion to the number of slices crossed (each slice adds its local
  defect), so η^k of the run is predicted as η^k_P N_c / P; beyond the measured iterations each
  iteration contracts by the last measured ratio ρ = η^K / η^(K-1) (geometric, which is
  conservative for Parareal's superlinear convergence); with K = 1 (a two-slice pilot) ρ is the
  first iteration's own ratio η¹ / η⁰. N_it is the first k with predicted η^k <= η*.
  docs/tuning.md compares this with real runs: right, or one iteration too many, whenever N_it is
  within the K measured iterations; optimistic by one or more iterations for slowly converging
  solvers when N_it lies beyond them (a short window converges in P iterations, so it overstates
  the contraction of a solver whose first iterations gain little). The report then says so
  (:func:`caution`).
- Screen. Before its pilot run a candidate is screened by one coarse call over the second slice
  from the reference state: its defect d against the reference (the first slice's defect is
  dominated by the initial transient, which the first iteration corrects exactly). Parareal's
  error after k iterations scales like the coarse solver's error to the power k + 1 (the classical
  bound, e.g. Gander & Hairer 2008), so the screened η^k is the baseline's measured η^k times
  (d / d_baseline)^(k+1). It only orders the search (docs/tuning.md measures how well); what is
  chosen was measured.
- Cost. γ_F is the pilot's fine slice time. γ_G is the time of one coarse call with its N_G
  auxiliary solvers on ``cores`` workers: the serial call time per auxiliary solver (its share of
  steps), times ceil(N_G / cores) waves of the slowest auxiliary solver.
- Speedup: eq. 14 (``parareal.speedup``) with Υ_oh = 0.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from .. import integrate
from ..core.contracts import rounds
from ..parareal.speedup import speedup as parareal_speedup
from .space import COARSE_RTOLS, Settings, adaptive_only

__all__ = ["caution", "compile_loops", "contraction", "estimated_ratio", "gamma_ratio",
           "predicted_errors", "predicted_iterations", "screened_errors", "speedup"]


def caution(iterations: int | None, measured: int, contraction: float | None) -> str | None:
    """A warning when the predicted N_it lies beyond the pilot's ``measured`` iterations K, i.e.
    rests on the contraction extrapolated from them (docs/tuning.md: against full-scale runs
    every N_it <= K held to within one iteration; beyond K slow solvers needed more)."""
    if iterations is None or iterations <= measured:
        return None
    rate = "" if contraction is None else f" (measured contraction {contraction:.2g})"
    return (f"N_it = {iterations} extrapolates the contraction{rate} beyond the pilot's "
            f"{measured} measured iteration{'s' if measured > 1 else ''}; for slowly converging "
            "solvers full-scale runs needed more (docs/tuning.md): allow more than "
            f"{iterations} iterations in a real run")


def _step_counts(settings: Settings, slice_length: float) -> list[int]:
    assert settings.dt is not None  # (the search costs candidates once their step is set)
    r = settings.r or 1.0
    return [integrate.n_steps(0.0, slice_length, settings.dt * r**q) for q in range(settings.m + 1)]


def gamma_ratio(
    settings: Settings, slice_length: float, coarse_seconds: float, gamma_f: float, cores: int
) -> float:
    """γ_G/γ_F on ``cores`` workers from the serial time of one coarse call (module docstring)."""
    counts = _step_counts(settings, slice_length)
    n_theta = settings.n_auxiliary // (settings.m + 1)
    slowest = coarse_seconds * max(counts) / (n_theta * sum(counts))
    return rounds(settings.n_auxiliary, cores) * slowest / gamma_f


def estimated_ratio(
    settings: Settings,
    slice_length: float,
    fine_scheme: str | integrate.AnyScheme,
    fine_steps: int,
    points: int,
    coarse_points: int,
    cores: int,
) -> float:
    """γ_G/γ_F from operation counts (stages x steps x points², like ``parastokes predict``): the
    cheap estimate used to order and prune candidates before measuring them."""
    stages = integrate.lookup(settings.scheme).stages
    fine = fine_steps * integrate.lookup(fine_scheme).stages * points**2
    slowest = max(_step_counts(settings, slice_length)) * stages * coarse_points**2
    return rounds(settings.n_auxiliary, cores) * slowest / fine


def predicted_errors(
    errors: Sequence[float], pilot_slices: int, n_slices: int, up_to: int,
    rho: float | None = None,
) -> list[float]:
    """η^k of the run for k = 1, ..., ``up_to`` from the pilot's η^k at T_P (module docstring);
    ``rho`` replaces the contraction read from ``errors`` (needed when there is one)."""
    scale = n_slices / pilot_slices
    out = [e * scale for e in errors]
    if rho is None:
        rho = contraction(errors)
    rho = 1.0 if rho is None else min(rho, 1.0)
    while len(out) < up_to:
        out.append(out[-1] * rho)
    return out[:up_to]


def predicted_iterations(
    errors: Sequence[float], pilot_slices: int, n_slices: int, target: float,
    rho: float | None = None,
) -> int | None:
    """The first k with predicted η^k <= η*; None if that takes N_c iterations or more (Parareal
    then gives no speedup) or the pilot shows no contraction."""
    if not errors or not all(e >= 0 for e in errors):
        return None
    predicted = predicted_errors(errors, pilot_slices, n_slices, n_slices, rho)
    for k, value in enumerate(predicted, 1):
        if value <= target:
            return k if k < n_slices else None
    return None


def contraction(errors: Sequence[float], eta0: float | None = None) -> float | None:
    """ρ = η^K / η^(K-1) of the pilot; with one iteration η¹ / η⁰ (``eta0``), else None."""
    if len(errors) == 1 and eta0:
        return errors[0] / eta0
    if len(errors) < 2 or errors[-2] <= 0:
        return None
    return errors[-1] / errors[-2]


def screened_errors(defect: float, base_defect: float, base_errors: Sequence[float]) -> list:
    """η^k predicted from a one-slice defect, scaled from the baseline's (module docstring)."""
    ratio = defect / base_defect
    return [e * ratio ** (k + 1) for k, e in enumerate(base_errors, 1)]


def speedup(ratio: float, iterations: int, n_slices: int) -> float:
    """Eq. 14 with Υ_oh = 0."""
    return parareal_speedup(ratio, 1.0, iterations, n_slices)


def compile_loops(system: Any, x: np.ndarray, t0: float, fine: Any, schemes: Iterable[str]
                  ) -> None:
    """One step of F (``fine``: scheme, dt and its rtol/atol) and of each of ``schemes`` from
    ``(t0, x)``: loads, or on a cold numba cache compiles, their stepping loops before a clock
    starts, so that compiling is not charged to a measurement (a fresh checkout's vesicle: 21 %
    of a tune instead of 14); a scheme that takes adaptive steps only (``"auto"``, the explicit
    pairs) with the first rtol of :data:`~.space.COARSE_RTOLS`. A blow-up here is left to the
    timed runs to report."""
    for scheme in dict.fromkeys((fine.scheme, *schemes)):
        own = scheme == fine.scheme
        rtol = fine.rtol if own else (COARSE_RTOLS[0] if adaptive_only(scheme) else None)
        try:
            integrate.run(system, x, t0, t0 + fine.dt, scheme, fine.dt, rtol=rtol,
                          atol=fine.atol if own else None)
        except integrate.BlowUpError:
            pass
