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
- :func:`amplification`: ‖DG‖ over one slice, the largest amplification of a position perturbation
  by the whole coarse map (power iteration with finite differences). A combination can amplify
  although every member is stable (docs/validation.md, section 3); :func:`verdict` compares it with
  the growth allowed over the run.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .. import integrate
from ..contracts import System

__all__ = ["GROWTH", "allowed_amplification", "amplification", "step_limit", "step_margin"]

#: The extra growth of coarse perturbations over the whole run that a stable candidate may add to
#: that of the physics (‖DG‖ of the plain solver at half its step limit): two orders of magnitude.
GROWTH = 100.0


def step_limit(
    system: System, scheme: str, x0: np.ndarray, t0: float, span: float, dt_lo: float, dt_hi: float
) -> float:
    """Largest step (1 % bisection) keeping ``system.monitor`` within its limit of its value at
    ``dt_lo`` over ``span`` (the monitor's physical change at a perturbed parameter, e.g. the
    area of a vesicle of larger viscosity, is not an instability).

    Raises ValueError (caught by the caller) when even ``dt_lo`` blows up.
    """
    return integrate.largest_stable_step(
        system, scheme, span, dt_lo, dt_hi, x0=x0, t0=t0, rtol=0.01, relative=True
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


def _positions_view(system: System, state: np.ndarray) -> np.ndarray | None:
    """The positions as a writable view of ``state`` when they are its first three columns."""
    if state.ndim == 2 and state.shape[1] >= 3:
        view = state[:, :3]
        if np.array_equal(np.asarray(system.positions(state)), view):
            return view
    return None


def amplification(
    propagator: Any,
    system: System,
    x0: np.ndarray,
    t0: float,
    t1: float,
    iterations: int = 4,
    seed: int = 0,
) -> float:
    """‖DG‖ over [t0, t1] at ``x0``: power iteration with finite differences on the positions.

    Each iteration costs one call of ``propagator``. The perturbation has norm 1e-6 times the size
    of the body (linear regime, well above the round-off of sums with weights up to 1e5). A
    perturbation that makes the propagator blow up counts as infinite amplification.
    """
    x0 = np.array(x0, dtype=float)
    try:
        base = np.asarray(system.positions(propagator(t0, t1, x0)))
    except integrate.BlowUpError:
        return math.inf
    size = float(np.abs(system.positions(x0)).max()) or 1.0
    h = 1e-6 * size
    rng = np.random.default_rng(seed)
    d = rng.standard_normal(np.asarray(system.positions(x0)).shape)
    d /= np.linalg.norm(d)
    gain = 0.0
    for _ in range(iterations):
        y = x0.copy()
        view = _positions_view(system, y)
        if view is None:
            y = y + h * d.reshape(y.shape)
        else:
            view += h * d
        try:
            moved = np.asarray(system.positions(propagator(t0, t1, y)))
        except integrate.BlowUpError:
            return math.inf
        diff = (moved - base) / h
        gain = float(np.linalg.norm(diff))
        if not math.isfinite(gain):
            return math.inf
        if gain == 0.0:
            return 0.0
        d = diff / gain
    return gain


def allowed_amplification(reference: float, n_slices: int) -> float:
    """The largest ‖DG‖ accepted: the physics' own growth per slice (``reference``, at least 1)
    times GROWTH^(1/N_c), so that the candidate adds at most a factor GROWTH over the run."""
    return max(1.0, reference) * GROWTH ** (1.0 / n_slices)
