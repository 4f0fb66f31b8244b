"""Stability of the combined coarse slice map (the edge effects of docs/validation.md).

Three cheap measurements, in the order the tuner uses them:

- :func:`step_limit`: the largest step at which one auxiliary solver keeps the system's monitor
  within its limit of the value it has at the fine step over one slice
  (``integrate.largest_stable_step``), at the candidate's most restrictive node;
- :func:`step_margin`: the derived safety margin below it. Near the limit the stiffest mode is
  multiplied by about 1 - 2δ per step at (1 - δ) times the limit (forward Euler and RK2 on the
  negative real axis), so over the n steps of a slice by (1 - 2δ)^n. The combination multiplies
  what its members leave by up to Σ|w_j v_q|; requiring Σ|w_j v_q| (1 - 2δ)^n <= η*/10 gives
  δ = (1 - (η* / (10 Σ|w_j v_q|))^(1/n)) / 2. Long slices need a small margin (the paper's slices),
  short slices and large weights a large one (the 5-10 % of docs/validation.md);
- :func:`spectral_radius`: ρ(DG) of the whole coarse map over one slice, the growth per slice of a
  position perturbation under repeated slices (:mod:`.slice_map`: ARPACK on finite differences).
  A combination can amplify although every member is stable (docs/validation.md, section 3);
  :func:`allowed_radius` is the growth allowed over the run. Not the norm ‖DG‖: on the rods it is
  about 50 for stable maps (a one-slice transient), docs/tuning.md step 7.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from .. import integrate
from ..core.contracts import System
from . import slice_map

__all__ = ["GROWTH", "allowed_radius", "radius_tolerance", "spectral_radius", "step_limit",
           "step_margin"]

#: The extra growth of coarse perturbations over the whole run that a stable candidate may add to
#: that of the physics (ρ(DG) of the plain solver at half its step limit): two orders of magnitude.
GROWTH = 100.0


def step_limit(
    system: System, scheme: str, x0: np.ndarray, t0: float, span: float, dt_lo: float,
    dt_hi: float, stop: Callable[[], None] | None = None,
) -> float:
    """Largest step (1 % bisection) keeping ``system.monitor`` within its limit of its value at
    ``dt_lo`` over ``span`` (the monitor's physical change at a perturbed parameter, e.g. the
    area of a vesicle of larger viscosity, is not an instability). ``stop`` is called before
    every trial run (the search's budget: it raises to abandon the bisection).

    Raises ValueError (caught by the caller) when even ``dt_lo`` blows up.
    """
    return integrate.largest_stable_step(
        system, scheme, span, dt_lo, dt_hi, x0=x0, t0=t0, rtol=0.01, relative=True, stop=stop
    )


def step_margin(n_steps: int, weight_sum: float, target: float) -> float:
    """δ with Σ|w v| (1 - 2δ)^n = η*/10 (module docstring), at most 0.5."""
    ratio = min(1.0, target / (10.0 * max(weight_sum, 1.0)))
    return min(0.5, 0.5 * (1.0 - ratio ** (1.0 / max(n_steps, 1))))


def safe_step(limit: float, slice_length: float, weight_sum: float, target: float) -> tuple:
    """(base step dividing the slice, margin δ) with step <= limit (1 - δ)."""
    n = math.ceil(slice_length / limit)
    for _ in range(5):  # δ depends on the step count; a fixed point in a few rounds
        delta = step_margin(n, weight_sum, target)
        n_new = math.ceil(slice_length / (limit * (1.0 - delta)) - 1e-9)
        if n_new == n:
            break
        n = n_new
    return slice_length / n, delta


def radius_tolerance(n_slices: int) -> float:
    """ARPACK's tolerance for the verdict over ``n_slices``: a tenth of the allowed growth per
    slice GROWTH^(1/N_c) - 1, at most ``slice_map.TOLERANCE`` (12 % for 40 slices: 1e-2)."""
    return min(slice_map.TOLERANCE, (GROWTH ** (1.0 / max(n_slices, 1)) - 1.0) / 10.0)


def spectral_radius(
    propagator: Any, system: System, x0: np.ndarray, t0: float, t1: float, seed: int = 0,
    tol: float = slice_map.TOLERANCE,
) -> slice_map.Radius:
    """ρ(DG) of the slice map x -> propagator(t0, t1, x) at ``x0`` on position perturbations
    (:func:`.slice_map.radius`: ARPACK with a small Krylov space, a fixed start, a tolerance and
    a bound on the calls; ``converged=False`` when it did not converge within that bound).

    A perturbation that makes the propagator blow up, or return a non-finite state, counts as
    infinite growth (``rho`` = inf, converged).
    """
    calls = [0]

    def propagate(x: np.ndarray) -> np.ndarray:
        calls[0] += 1
        return propagator(t0, t1, x)

    try:
        return slice_map.radius(slice_map.Probe(propagate, system.positions, x0), seed,
                                tol=tol)
    except (integrate.BlowUpError, slice_map.Diverged):
        return slice_map.Radius(math.inf, True, calls[0])


def allowed_radius(reference: float, n_slices: int) -> float:
    """The largest ρ(DG) accepted: the physics' own growth per slice (``reference``, at least 1)
    times GROWTH^(1/N_c), so that repeated coarse slices add at most a factor GROWTH over the
    run (a perturbation grows like ρ^n over n slices, after a transient bounded independently
    of n; docs/tuning.md, step 7)."""
    return max(1.0, reference) * GROWTH ** (1.0 / n_slices)
