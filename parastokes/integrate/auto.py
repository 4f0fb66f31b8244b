"""``scheme = "auto"``: adaptive steps that switch between an explicit embedded pair and a
linearly implicit scheme as stiffness comes and goes (Shampine 1977; Hairer & Wanner, *Solving
ODEs II*, IV.2; LSODA's idea, Petzold 1983).

A run starts with the explicit pair ``rk45`` (:data:`EXPLICIT`). After every accepted step it
estimates the dominant eigenvalue of the rates' Jacobian from the last two stages of the step,
both evaluated at its end: ``ρ ≈ |k_7 - k_6| / (h |Σ_l (b_l - a_(6,l)) k_l|)``, the difference
of two rates over the difference of their arguments, in the rates' own coordinates (Hairer &
Wanner's test in DOPRI5). Bogacki-Shampine has no two stages at one time: the difference of
its last two (at 3/4 and 1 of the step) is the smooth motion over h/4, which hides the stiff
part once it is damped (measured: the test missed a stiff run at rtol 1e-6), so ``auto`` does
not run it. Where ``h ρ`` exceeds :data:`STIFF_FRACTION` of the pair's stability boundary on the
negative real axis (:func:`.schemes.real_stability_boundary`: 3.31) for :data:`STIFF_STEPS`
accepted steps (a run of :data:`NONSTIFF_STEPS` below it starts
the count again, as DOPRI5 does), stability, not accuracy, sets the step: the run goes on
with the linearly implicit scheme :data:`IMPLICIT` (``ros34pw2``, with an error estimate).

In the implicit scheme, every accepted step advances a power iteration on the Jacobian by
finite differences of the rates (two evaluations, in the rates' coordinates through
``advance``), started from the explicit phase's last ``k_s - k_(s-1)``. Where the step the
accuracy wants, ``h``, stays below :data:`BACK_FRACTION` of the explicit limit (``h ρ`` below
that fraction of the boundary) for :data:`BACK_STEPS` steps, the explicit pair is cheaper
again and the run switches back.

Every switch is logged (INFO: the time, the schemes, ``ρ`` and ``h``) and kept in the result
(:attr:`RunResult.switches`, with the steps of each scheme in :attr:`RunResult.by_scheme`).
The switches depend on the states only: the same input gives the same steps.
"""

from __future__ import annotations

import logging

import numpy as np

from ..core.contracts import System
from .adaptive import Stepper, Watch, segment, stepper_for
from .base import RunResult, advance, projected, rates
from .explicit import PairStepper
from .schemes import SCHEMES, Scheme, real_stability_boundary

__all__ = ["auto_run", "pair_rho"]

log = logging.getLogger(__name__)

#: The explicit pair of the nonstiff phases (two stages at the step's end: the test of ρ).
EXPLICIT = "rk45"
#: The linearly implicit scheme of the stiff phases: third order with an embedded second
#: (measured against ros2 on the stiff test problem and a rod: docs/stiff.md).
IMPLICIT = "ros34pw2"
#: Stiff where h ρ > STIFF_FRACTION x the boundary for STIFF_STEPS accepted steps; a run of
#: NONSTIFF_STEPS steps below it resets the count (DOPRI5: 15 and 6).
STIFF_FRACTION, STIFF_STEPS, NONSTIFF_STEPS = 0.9, 15, 6
#: Back to explicit where h ρ < BACK_FRACTION x the boundary for BACK_STEPS implicit steps.
BACK_FRACTION, BACK_STEPS = 0.5, 5


def _norm(v: np.ndarray) -> float:
    return float(np.sqrt(np.sum(v * v)))


def pair_rho(s: Scheme, k: list[np.ndarray], h: float) -> tuple[float, np.ndarray]:
    """The dominant eigenvalue's size from the last two stages of a step of ``s`` (see the
    module docstring), and ``k_s - k_(s-1)``, the direction it acts along."""
    last, before = len(k) - 1, len(k) - 2
    dk = k[last] - k[before]
    a_last, a_before = s.a[last], s.a[before] + (0.0,)
    dy = sum(((p - q) * kl for p, q, kl in zip(a_last, a_before, k, strict=False)),
             np.zeros_like(dk))
    size = _norm(dy) * h
    return (_norm(dk) / size if size > 0 else 0.0), dk


class _Stiffness:
    """The explicit phase's detector: True after STIFF_STEPS steps with h ρ beyond the limit."""

    def __init__(self, stepper: PairStepper) -> None:
        self.stepper = stepper
        self.boundary = real_stability_boundary(stepper.scheme)
        self.stiff = self.calm = 0
        self.rho, self.direction = 0.0, np.zeros(0)

    def __call__(self, t: float, x: np.ndarray, step: float, h: float) -> bool:
        self.rho, self.direction = pair_rho(self.stepper.scheme, self.stepper.k, step)
        if step * self.rho > STIFF_FRACTION * self.boundary:
            self.stiff, self.calm = self.stiff + 1, 0
        else:
            self.calm += 1
            if self.calm >= NONSTIFF_STEPS:
                self.stiff = 0
        return self.stiff >= STIFF_STEPS


class _Calm:
    """The implicit phase's detector: a power iteration on the Jacobian, one step of it per
    accepted step; True after BACK_STEPS steps whose next step is below BACK_FRACTION of the
    explicit limit."""

    def __init__(self, system: System, direction: np.ndarray, boundary: float) -> None:
        self.system, self.boundary = system, boundary
        self.v = direction / max(_norm(direction), 1e-300)
        self.rho, self.below = 0.0, 0

    def __call__(self, t: float, x: np.ndarray, step: float, h: float) -> bool:
        f0 = rates(self.system, t, x)
        delta = 1e-7 * max(1.0, _norm(x) / np.sqrt(x.size))
        jv = (rates(self.system, t, advance(self.system, x, self.v, delta)) - f0) / delta
        self.rho = _norm(jv)
        if self.rho > 0:
            self.v = jv / self.rho
        self.below = self.below + 1 if h * self.rho < BACK_FRACTION * self.boundary else 0
        return self.below >= BACK_STEPS


def auto_run(system: System, x: np.ndarray, t0: float, t1: float, dt: float,
             tol: tuple[float, float], blowup_factor: float) -> RunResult:
    """:func:`parastokes.integrate.run` with ``scheme="auto"`` (the module docstring): ``dt`` the
    first step, ``tol`` its ``(rtol, atol)``."""
    pair = SCHEMES[EXPLICIT]
    assert isinstance(pair, Scheme)
    implicit = SCHEMES[IMPLICIT]
    boundary = real_stability_boundary(pair)
    x = projected(system, x, t0)
    watch = Watch(system, x, blowup_factor)
    t, h = t0, dt
    switches: list[tuple[float, str, str]] = []
    counts = {pair.name: [0, 0], implicit.name: [0, 0]}
    explicit, direction = True, np.zeros(0)
    while t < t1:
        stepper: Stepper = stepper_for(system, pair if explicit else implicit)
        detector = (_Stiffness(stepper) if explicit  # type: ignore[arg-type]
                    else _Calm(system, direction, boundary))
        x, done = segment(stepper, x, t, t1, h, tol, watch, detector)
        t, h = done.end, done.last_step
        counts[stepper.scheme.name][0] += done.accepted
        counts[stepper.scheme.name][1] += done.rejected
        if t >= t1:
            break
        rho = detector.rho
        if explicit:
            direction = detector.direction  # type: ignore[union-attr]
            reason = (f"stiff: h ρ > {STIFF_FRACTION:g} x {pair.name}'s stability boundary "
                      f"{boundary:.3g} for {STIFF_STEPS} steps (ρ = {rho:.4g}, h = {h:.4g})")
        else:
            h = min(h, STIFF_FRACTION * boundary / rho) if rho > 0 else h
            reason = (f"not stiff: the step wanted is below {BACK_FRACTION:g} x {pair.name}'s "
                      f"limit for {BACK_STEPS} steps (ρ = {rho:.4g}, h = {h:.4g})")
        explicit = not explicit
        name = pair.name if explicit else implicit.name
        switches.append((t, name, reason))
        log.info("auto: %s from t=%.10g, %s", name, t, reason)
    accepted = sum(c[0] for c in counts.values())
    return RunResult(projected(system, x, t1), watch.worst, accepted, h,
                     n_rejected=sum(c[1] for c in counts.values()), switches=tuple(switches),
                     by_scheme=tuple((n, a, r) for n, (a, r) in counts.items()))
