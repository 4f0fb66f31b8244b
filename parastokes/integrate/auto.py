"""``scheme = "auto"``: adaptive steps that switch between an explicit embedded pair and a
linearly implicit scheme by their cost per unit of time, as stiffness comes and goes (LSODA's
rule, Petzold 1983: switch where the other method's step, at its cost, covers more time per
evaluation; Shampine 1977; Hairer & Wanner, *Solving ODEs II*, IV.2).

The costs, in rate evaluations per step (:class:`Costs`): the explicit pair ``rk23``
(:data:`EXPLICIT`, first same as last) 3 new stages a step plus ``1/RHO_EVERY`` for the
estimate of ρ below; the implicit scheme (:func:`implicit_scheme`: ``ros34pw2``, the W-method
on the local ``A``, where ``rtol >= W_RTOL``, else ``ros34pw2-krylov`` on the exact Jacobian,
whose error follows the tolerance where the W-method's does not) its counted work per accepted
step (:class:`Tally`: stage sets, rejected ones included, at :data:`STEP_EVALS` and GMRES
products at :data:`PRODUCT_EVALS`, measured prices by the kind of factorization; docs/stiff.md),
plus the two evaluations of ρ's power iteration. Both estimate their error at order 2, so the
step the accuracy allows is about the same for both; the explicit one is capped by stability
at ``h ρ`` below its boundary on the negative real axis
(:func:`.schemes.real_stability_boundary`: 2.51).

- **Explicit phase.** After every :data:`RHO_EVERY` accepted steps, one step of a power
  iteration on the rates' Jacobian by a finite difference of the rates at the step's end (one
  evaluation: the rates there are the pair's last stage), started from the direction of the
  step's error estimate ``Σ (b_l - b̂_l) k_l`` (where stability limits the step, the stiff
  modes dominate it). Where ``h ρ`` exceeds :data:`STIFF_FRACTION` of the boundary,
  stability sets the step, and the implicit scheme is tried with one step of :data:`TRIAL`
  times the break-even size ``h_E C_I / C_E``
  (:meth:`Costs.break_even`): if its error estimate accepts it, implicit steps cover time at
  least TRIAL times more cheaply and the run goes on implicit from there (the step is kept);
  else the run stays explicit and tries again once the explicit phase has spent
  ``RETRY 2^(n-1) err^(1/(q+1))`` times the counted work of the ``n``-th failed trial in a row,
  of error ``err`` (a geometric back-off, longer the farther the trial missed: the trials cost
  a bounded and falling share of the run; ρ is estimated only where a trial could follow). A
  trial accepted by its error estimate whose counted cost (:class:`Tally`) makes the implicit
  steps no cheaper per unit time than the explicit ones is a failed trial too, of error 1.
  One implicit stepper serves the whole run, so that a trial reuses the approximate Jacobian
  and its factorization of the last one while they are fresh (``stiff.REFRESH`` steps; a
  W-method keeps its order with an older ``A``). Below ``W_RTOL`` the trial of the exact
  Jacobian's scheme is preceded by a **probe**: one step of the W-method (its own stepper: a
  banded LU and no GMRES, some 12 evaluations against 80-170 for the Krylov step at a trial's
  size) of the same size, whose error (each scheme's estimate bounds its step's error within
  1.6 on the paper's rod: docs/stiff.md) sizes the trial by the controller's law
  (:func:`sized_trial`); where the step it points to is below :data:`PROBE_GAIN` x the
  break-even, the probe is the failed trial, backed off by its own small work.
- **Euler phase.** Where stability sets rk23's step and no trial is due, forward Euler (one
  evaluation a step at ``h ρ = 0.9 x 2``, against rk23's three at ``0.9 x 2.51``: 2.4 times
  cheaper per unit time) takes over, in chunks of :data:`EULER_EVERY` fixed steps of
  :func:`euler_step` (``0.9 x 2 / ρ``, ρ by one power-iteration step after each chunk), each
  followed by the rates at its end: the sum of the chunk's Heun estimates telescopes to
  :func:`euler_drift` ``|h/2 (f_end - f_start)|``, which must stay within the chunk's
  :func:`euler_share` of the tolerance (an error per unit step, since Euler propagates the
  solution its estimate measures). The first chunk of a phase damps the pair's noise (riding
  its stability limit, at the tolerance's level) and is checked with the second; a chunk
  beyond its share is dropped (with the first, if it was the second) and rk23 goes on from
  the last kept state, the next Euler phase backed off by :func:`euler_retry`. A trial of the
  implicit scheme is due in an Euler phase as in rk23's, at the break-even with Euler's cost.
- **Implicit phase.** After every accepted step, a power-iteration step (two evaluations);
  where the explicit pair at ``min(h, EXPLICIT_FRACTION boundary / ρ)`` (``h`` the step the
  accuracy allows now; rk23's step where stability limits it) would cost less per unit time
  than the implicit step ``h`` at its counted cost (:meth:`Costs.explicit_cheaper`) for
  :data:`BACK_STEPS` steps in a row, the run switches back, from that step.

Every switch is logged (INFO: the time, the scheme, the costs compared) and kept in the result
(:attr:`RunResult.switches`, with the steps of each scheme in :attr:`RunResult.by_scheme`; a
rejected trial step counts as a rejected step of the implicit scheme, a dropped Euler step as
a rejected one of ``euler``). Every decision depends
on the states and counts only, never on a clock: the same input gives the same steps.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from .. import stiff
from ..core.contracts import StepFailure, System
from .adaptive import Watch, segment, stepper_for
from .base import BlowUpError, RunResult, advance, projected, rates
from .controller import SAFETY, error_norm, estimate_order, factor
from .explicit import PairStepper
from .loop import CompiledPair
from .schemes import SCHEMES, Scheme, real_stability_boundary

__all__ = ["Costs", "Tally", "auto_run", "euler_drift", "euler_share", "euler_step",
           "implicit_scheme", "power_step", "probe_step", "sized_trial", "step_cost"]

log = logging.getLogger(__name__)

#: The explicit pair of the nonstiff phases: of the pairs, the fewest evaluations per unit
#: time at the stability limit (3 per step at h ρ < 2.51, against 6 at 3.31 for rk45).
EXPLICIT = "rk23"
#: The linearly implicit scheme of the stiff phases where ``rtol >= W_RTOL``: third order with an
#: embedded second, as rk23 (measured against ros2 on the stiff test problem and a rod:
#: docs/stiff.md), a W-method on the local ``A``.
IMPLICIT = "ros34pw2"
#: The implicit scheme where ``rtol < W_RTOL``: ROS34PW2 whose stages solve with the exact
#: Jacobian by GMRES (no W-defect ``A - J``). On the rods of 301-1201 points the W-method's
#: final error is 2-200 times rtol below 1e-2 (its third order lost to the W-defect, each step
#: spends most of the tolerance and the errors add up), this one's 0.1-1.8 times
#: (docs/stiff.md, "Why the exact Jacobian below rtol 1e-2").
IMPLICIT_EXACT = "ros34pw2-krylov"
#: The loosest rtol at which the W-method's error is trusted (measured: docs/stiff.md).
W_RTOL = 1e-2
#: Rate evaluations' worth of CPU per stage set (accepted or rejected step) of the implicit
#: scheme, beyond its GMRES products, by the kind of its factorization (True: LAPACK's banded
#: LU), and per GMRES product of ``IMPLICIT_EXACT`` (a rate evaluation, a solve with the
#: preconditioner, the orthogonalization): fitted over adaptive runs of both implicit schemes
#: against one evaluation in the same process (``benchmarks/adaptive.py --prices``,
#: docs/figures/stiff/auto_prices.json; round 5, fourth session): 12.7 and 2.0 on the rod of
#: 301 points, 8.3 and 1.66 on 601, 7.6 and 1.72 on 1201 (banded: their means), 72 and 3.9 on
#: the vesicle of 642 points (SuperLU). Before: 12 and 2.5, 90 and 5.7 (the stage solves then
#: twice as slow).
STEP_EVALS = {True: 9.5, False: 72.0}
PRODUCT_EVALS = {True: 1.8, False: 3.9}
#: GMRES products per stage set of ``IMPLICIT_EXACT`` before the run has counted any (the same
#: runs at rtol 1e-3 and 1e-4: 43 and 37, 55 and 44, 41 and 35 on the rods of 301, 601, 1201
#: points).
PRIOR_PRODUCTS = 40.0
#: Evaluations of ρ's power iteration per implicit step (the rates at the state and at a
#: shifted one).
PROBE_EVALS = 2.0
#: One power-iteration step (one evaluation) every RHO_EVERY accepted explicit steps.
RHO_EVERY = 8
#: Stability sets the explicit step where h ρ > STIFF_FRACTION x the boundary.
STIFF_FRACTION = 0.8
#: Where stability limits it, rk23's step under the PI controller is h ρ ≈ EXPLICIT_FRACTION x
#: its boundary (measured on the paper's rod: 2.27 / 2.51).
EXPLICIT_FRACTION = 0.9
#: The trial step of the implicit scheme: TRIAL x the break-even step (a switch must win by
#: that much at least, so that a run near the break-even does not switch back and forth).
TRIAL = 2.0
#: Back to explicit where it is the cheaper for BACK_STEPS implicit steps in a row.
BACK_STEPS = 5
#: After a switch back, no trial before the explicit phase has spent RETRY implicit steps'
#: worth of evaluations; after the n-th failed trial in a row, with error err, RETRY 2^(n-1)
#: min(err, ERR_MAX)^(1/(q+1)) times the trial's counted work (the last factor: how far the
#: implicit step the accuracy allows was below the trial's, by the controller's law).
RETRY, ERR_MAX = 10.0, 1e3
#: Forward Euler (``SCHEMES["euler"]``) where stability alone sets the step: in chunks of
#: EULER_EVERY fixed steps of EULER_FRACTION x its boundary (2) / ρ, each chunk followed by one
#: evaluation of the rates (for its error estimate) and one power-iteration step.
EULER_FRACTION = 0.9
EULER_EVERY = 32
#: A probe of the W-method (no GMRES) before a trial of ``IMPLICIT_EXACT``: the trial is taken
#: at the step the probe's error points to, if that is at least PROBE_GAIN x the break-even.
PROBE_GAIN = 1.2


@dataclass(frozen=True)
class Costs:
    """Rate evaluations per step of the explicit scheme and of the implicit scheme."""

    explicit: float
    implicit: float

    @classmethod
    def of(cls, pair: Scheme, implicit: float, every: int = RHO_EVERY) -> Costs:
        """The costs of ``pair`` (its new stages a step, plus its share of the ρ estimate, one
        evaluation every ``every`` steps) and of an implicit step of ``implicit`` evaluations
        (:meth:`Tally.cost`)."""
        new_stages = pair.stages - 1 if pair.fsal else pair.stages
        return cls(new_stages + 1.0 / every, implicit)

    def explicit_cheaper(self, explicit_step: float, implicit_step: float) -> bool:
        """Whether explicit steps of ``explicit_step`` cost fewer evaluations per unit time
        than implicit steps of ``implicit_step``: ``C_E / h_E < C_I / h_I``."""
        return self.explicit * implicit_step < self.implicit * explicit_step

    def retry(self, failed: int, err: float, q: int) -> float:
        """The evaluations the explicit phase spends before the next trial after the
        ``failed``-th failed trial in a row, of error ``err`` (estimate of order ``q``):
        ``RETRY C_I 2^(failed-1) min(err, ERR_MAX)^(1/(q+1))``."""
        return RETRY * self.implicit * 2.0 ** (failed - 1) * min(err, ERR_MAX) ** (1 / (q + 1))

    def break_even(self, explicit_step: float) -> float:
        """The implicit step that costs as much per unit time as ``explicit_step``:
        ``h_E C_I / C_E``."""
        return explicit_step * self.implicit / self.explicit


EULER = SCHEMES["euler"]
#: The stability boundaries on the negative real axis of forward Euler (2) and of rk23 (2.51).
EULER_BOUNDARY = real_stability_boundary(EULER)  # type: ignore[arg-type]
PAIR_BOUNDARY = real_stability_boundary(SCHEMES[EXPLICIT])  # type: ignore[arg-type]
#: Evaluations per step of forward Euler in its phase (one, and two a chunk: the rates at its
#: end and a power-iteration step) and of rk23 (3, and its share of ρ).
EULER_COST = 1.0 + 2.0 / EULER_EVERY
PAIR_COST = Costs.of(SCHEMES[EXPLICIT], 0.0).explicit  # type: ignore[arg-type]


def euler_step(rho: float) -> float:
    """Forward Euler's step where stability alone sets it: ``EULER_FRACTION 2 / ρ``."""
    return EULER_FRACTION * EULER_BOUNDARY / rho


def pair_step(rho: float) -> float:
    """rk23's step where stability limits it: ``EXPLICIT_FRACTION 2.51 / ρ``."""
    return EXPLICIT_FRACTION * PAIR_BOUNDARY / rho


def euler_share(duration: float, span: float) -> float:
    """The share of the tolerance of an Euler chunk of ``duration`` in a run over ``span``:
    ``min(1, duration / span)`` (an error per unit step: the chunks' errors, added, stay within
    the tolerance where nothing damps them)."""
    return min(1.0, duration / span)


def euler_retry(failed: int, wasted: float, over: float) -> float:
    """The evaluations of the explicit pair before the next Euler phase after the ``failed``-th
    one that ended for its accuracy, its last chunk's drift ``over`` times its share, its
    dropped chunks ``wasted`` evaluations: ``RETRY wasted 2^(failed-1) min(over,
    ERR_MAX)^(1/2)`` (as :meth:`Costs.retry`, for an estimate of order 1: the failed phases
    cost a bounded, falling share of the run, the farther they missed the less)."""
    return RETRY * wasted * 2.0 ** (failed - 1) * min(over, ERR_MAX) ** 0.5


def probe_step(trial: float, err: float, q: int) -> float:
    """The implicit step the accuracy allows after a probe of ``trial`` of error ``err``
    (estimate of order ``q``): ``trial min(1, SAFETY err^(-1/(q+1)))``, the controller's law
    without its clipping."""
    return trial * min(1.0, SAFETY * err ** (-1.0 / (q + 1))) if err > 0 else trial


def sized_trial(trial: float, err: float, q: int, break_even: float) -> float | None:
    """The trial of the exact Jacobian's scheme after a probe of ``trial`` of error ``err``:
    :func:`probe_step`, or None (no trial: the probe's is the failed one) where that is below
    ``PROBE_GAIN x break_even``."""
    step = probe_step(trial, err, q)
    return step if step >= PROBE_GAIN * break_even else None


def implicit_scheme(rtol: float) -> str:
    """The implicit scheme of ``auto`` at ``rtol``: :data:`IMPLICIT` (the W-method on the local
    ``A``) where ``rtol >= W_RTOL``, else :data:`IMPLICIT_EXACT` (the exact Jacobian)."""
    return IMPLICIT if rtol >= W_RTOL else IMPLICIT_EXACT


def step_cost(sets: int, products: int, accepted: int, banded: bool) -> float:
    """Evaluations per accepted implicit step, the rejected ones' work included:
    ``(STEP_EVALS sets + PRODUCT_EVALS products) / accepted + PROBE_EVALS`` (``sets`` stage
    sets, accepted or rejected, ``products`` GMRES products, the constants of the kind of
    factorization, ``banded`` or not)."""
    return (STEP_EVALS[banded] * sets + PRODUCT_EVALS[banded] * products) / accepted + PROBE_EVALS


class Tally:
    """The counted work of a run's implicit stepper ``solver`` (its ``steps``: stage sets,
    ``iterations``: GMRES products) over its :attr:`accepted` steps, less the work of the trials
    rejected by their error estimate (:meth:`exclude`: a step sized by the trial, not by the
    accuracy)."""

    def __init__(self, solver: stiff.Stepper) -> None:
        self.solver, self.accepted, self.excluded = solver, 0, (0, 0)

    def mark(self) -> tuple[int, int]:
        """The stepper's counts now (stage sets, GMRES products)."""
        return self.solver.steps, self.solver.iterations

    def spent(self, since: tuple[int, int]) -> float:
        """The work done since the :meth:`mark` ``since``, in evaluations (:func:`step_cost`
        of it as one step)."""
        now = self.mark()
        return step_cost(now[0] - since[0], now[1] - since[1], 1, self.solver.banded is not False)

    def exclude(self, since: tuple[int, int]) -> None:
        """Leave out the work done since the :meth:`mark` ``since``."""
        now = self.mark()
        self.excluded = (self.excluded[0] + now[0] - since[0],
                         self.excluded[1] + now[1] - since[1])

    def cost(self) -> float:
        """Evaluations per implicit step: :func:`step_cost` of the counts, or before any
        accepted step its prior (one stage set, :data:`PRIOR_PRODUCTS` GMRES products for a
        scheme that takes them, banded until a factorization says otherwise)."""
        banded = self.solver.banded is not False
        if not self.accepted:
            prior = PRIOR_PRODUCTS if self.solver.scheme.krylov else 0.0
            return STEP_EVALS[banded] + PRODUCT_EVALS[banded] * prior + PROBE_EVALS
        sets, products = self.mark()
        return step_cost(sets - self.excluded[0], products - self.excluded[1], self.accepted,
                         banded)


def _norm(v: np.ndarray) -> float:
    return float(np.sqrt(np.sum(v * v)))


def power_step(system: System, t: float, x: np.ndarray, v: np.ndarray,
               f: np.ndarray | None = None) -> tuple[float, np.ndarray]:
    """One step of a power iteration on the Jacobian of the rates at ``(t, x)``: ``|J v|``
    for the unit vector along ``v`` (in the rates' coordinates, through ``advance``; a forward
    difference, ``f`` the rates at ``x`` when known) and the new direction ``J v / |J v|``."""
    v = v / max(_norm(v), 1e-300)
    f0 = rates(system, t, x) if f is None else f
    delta = 1e-7 * max(1.0, _norm(x) / np.sqrt(x.size))
    jv = (rates(system, t, advance(system, x, v, delta)) - f0) / delta
    rho = _norm(jv)
    return rho, (jv / rho if rho > 0 else v)


def _error_direction(pair: Scheme, k: np.ndarray | list[np.ndarray]) -> np.ndarray:
    """``Σ_l (b_l - b̂_l) k_l``: the difference of the pair's two solutions over ``h``."""
    assert pair.b_low is not None
    return sum(((p - q) * k[j] for j, (p, q) in enumerate(zip(pair.b, pair.b_low, strict=True))
                if p != q), np.zeros_like(k[0]))


class _Explicit:
    """The explicit pair's watch (``until`` of :func:`.adaptive.segment`): True where stability
    sets its step and a trial of the implicit scheme is due (:attr:`wants` ``"trial"``) or
    else an Euler phase may begin (``"euler"``); the module docstring."""

    boundary = PAIR_BOUNDARY

    def __init__(self, system: System, stepper: PairStepper | CompiledPair, costs: Costs,
                 budget: float, euler_budget: float, direction: np.ndarray, t1: float) -> None:
        self.system, self.stepper, self.costs, self.t1 = system, stepper, costs, t1
        self.budget, self.euler_budget = budget, euler_budget
        self.rho, self.direction, self.step, self.wants = 0.0, direction, math.nan, ""

    def __call__(self, t: float, x: np.ndarray, step: float, h: float) -> bool:
        """After every RHO_EVERY-th accepted step (``step`` the last)."""
        spent = RHO_EVERY * self.costs.explicit
        self.budget, self.euler_budget = self.budget - spent, self.euler_budget - spent
        self.step = step
        if self.budget > 0 and self.euler_budget > 0:
            return False  # no trial and no Euler phase due, whatever ρ: not estimated
        scheme = self.stepper.scheme
        assert isinstance(scheme, Scheme) and scheme.fsal  # its last stage: the rates at x
        if not self.direction.size:
            self.direction = _error_direction(scheme, self.stepper.k)
        self.rho, self.direction = power_step(self.system, t, x, self.direction,
                                              np.array(self.stepper.k[-1]))
        if step * self.rho <= STIFF_FRACTION * self.boundary:
            return False
        # an Euler phase checks its first chunk with its second: time for both
        euler = t + 2 * EULER_EVERY * euler_step(self.rho) < self.t1
        self.wants = "trial" if self.budget <= 0 else "euler" if euler else ""
        return bool(self.wants)


def euler_drift(system: System, x: np.ndarray, f_start: np.ndarray, f_end: np.ndarray,
                step: float, tol: tuple[float, float]) -> float:
    """The error of a chunk of forward Euler steps ``step`` that ended at ``x``, in the
    controller's norm (:func:`.controller.error_norm`): ``|step/2 (f_end - f_start)|``, the sum
    of Heun's estimates ``step/2 (f_(n+1) - f_n)`` of its steps (it telescopes), ``f_start`` and
    ``f_end`` the rates at the chunk's ends. Summed, the noise of the stiff modes (damped at
    ``|1 - h ρ| <= 0.8`` a step) cancels and the drift of the smooth motion, which adds up over
    the run, stays (on the vesicle at rtol 1e-3: 1.06e-5 a step either way, where the error of a
    single step's estimate at the start of a phase is the pair's noise, some 1e5 times more)."""
    return error_norm(x, x, advance(system, x, f_end - f_start, 0.5 * step), *tol)


class _Euler:
    """An Euler phase: chunks of :data:`EULER_EVERY` steps of forward Euler at
    :func:`euler_step` (ρ from the last power-iteration step, one after each chunk) in the
    system's loop of fixed steps (compiled where it has one), while each chunk's
    :func:`euler_drift` stays within its :func:`euler_share` of the tolerance; it ends
    (:attr:`wants`) where one does not (``"pair"``: that chunk dropped, and the first with it
    if it was the second), where a step blows up (``"unstable"``: the unchecked chunks
    dropped), where no time is left for two chunks (``"end"``), where a trial of the implicit
    scheme is due (``"trial"``) or at ``t1``."""

    boundary = EULER_BOUNDARY

    def __init__(self, system: System, rho: float, direction: np.ndarray, budget: float,
                 span: float, tol: tuple[float, float], blowup_factor: float,
                 compiled: bool) -> None:
        self.system, self.rho, self.direction, self.budget = system, rho, direction, budget
        self.span, self.tol, self.blowup_factor, self.compiled = span, tol, blowup_factor, compiled
        self.step, self.wants, self.worst = euler_step(rho), "", -math.inf
        self.steps = self.rejected = self.dropped = 0  # steps kept, dropped, dropped last
        self.drift, self.share = 0.0, 1.0  # the last chunk's and its share

    def run(self, t: float, x: np.ndarray, t1: float) -> tuple[float, np.ndarray]:
        """Chunks from ``(t, x)`` until the phase ends: where it ended. The first chunk is
        kept once the second is (its estimate starts where the pair's noise is damped); a chunk
        beyond its share is dropped, with the first if it was the second."""
        from .runs import stepping  # (runs imports this module)

        kept, f, pending = (t, x), None, 0  # f: the rates at the chunk's start, once damped
        if t + 2 * EULER_EVERY * euler_step(self.rho) >= t1:
            self.wants, self.dropped = "end", 0  # no time left for two chunks: none checked
            return t, x
        while t < t1:
            self.step = euler_step(self.rho)
            n = min(EULER_EVERY, math.ceil((t1 - t) / self.step * (1 - 1e-12)))
            step = min(self.step, (t1 - t) / n)
            try:
                chunk = stepping(self.system, EULER, x, t, step, n, self.blowup_factor,
                                 compiled=self.compiled)
            except BlowUpError:
                self.wants = "unstable"
                break
            t = t1 if n * step >= (t1 - t) * (1 - 1e-12) else t + n * step
            x, pending = chunk.state, pending + n
            self.worst = max(self.worst, chunk.max_monitor)
            self.budget -= n * EULER_COST
            f_end = rates(self.system, t, x)
            self.drift = 0.0 if f is None else euler_drift(self.system, x, f, f_end, step,
                                                           self.tol)
            self.share = euler_share(n * step, self.span)
            if self.drift > self.share:
                self.wants = "pair"
                break
            if t >= t1 or f is not None:  # checked (the first chunk with the second)
                kept, self.steps, pending = (t, x), self.steps + pending, 0
            if t >= t1:
                break
            self.rho, self.direction = power_step(self.system, t, x, self.direction, f_end)
            f = f_end
            if self.budget <= 0 and not pending:
                self.wants = "trial"
                break
        self.rejected, self.dropped = self.rejected + pending, pending
        return kept
class _Implicit:
    """The implicit phase's watch: a power-iteration step per accepted step; True after
    BACK_STEPS steps in a row where the explicit pair would be the cheaper, the implicit step
    costed by the run's counted work (:class:`Tally`, the rejected steps' included)."""

    def __init__(self, system: System, direction: np.ndarray, costs: Costs, boundary: float,
                 tally: Tally | None = None) -> None:
        self.system, self.costs, self.boundary, self.tally = system, costs, boundary, tally
        self.direction, self.rho, self.cheaper = direction, 0.0, 0

    def explicit_step(self, h: float) -> float:
        """The explicit pair's step where the accuracy allows ``h``: capped by stability."""
        return min(h, EXPLICIT_FRACTION * self.boundary / self.rho) if self.rho > 0 else h

    def __call__(self, t: float, x: np.ndarray, step: float, h: float) -> bool:
        self.rho, self.direction = power_step(self.system, t, x, self.direction)
        if self.tally is not None:
            self.tally.accepted += 1
            self.costs = Costs(self.costs.explicit, self.tally.cost())
        cheaper = self.costs.explicit_cheaper(self.explicit_step(h), h)
        self.cheaper = self.cheaper + 1 if cheaper else 0
        return self.cheaper >= BACK_STEPS


def _probe(probe: stiff.Stepper, t: float, x: np.ndarray, step: float,
           tol: tuple[float, float], failed_cost: float) -> tuple[float, float]:
    """The error of a step ``step`` of the W-method ``probe`` from ``(t, x)`` (infinite where
    its solve fails) and its counted work in evaluations (``failed_cost`` where it failed: the
    stepper counts a step's work as it ends)."""
    tally = Tally(probe)
    mark = tally.mark()
    try:
        x_new, x_low = probe.step_with_estimate(t, x, step)
        err = error_norm(x, x_new, x_low, *tol)
    except (stiff.StiffSolveError, StepFailure):
        err = math.inf
    return err, max(tally.spent(mark), failed_cost if math.isinf(err) else 0.0)


def auto_run(system: System, x: np.ndarray, t0: float, t1: float, dt: float,
             tol: tuple[float, float], blowup_factor: float, compiled: bool = True
             ) -> RunResult:
    """:func:`parastokes.integrate.run` with ``scheme="auto"`` (the module docstring): ``dt``
    the first step, ``tol`` its ``(rtol, atol)``; the explicit schemes in the system's compiled
    loops where it has them and ``compiled``."""
    pair, implicit = SCHEMES[EXPLICIT], SCHEMES[implicit_scheme(tol[0])]
    assert isinstance(pair, Scheme)
    q = estimate_order(implicit)
    x = projected(system, x, t0)
    watch = Watch(system, x, blowup_factor)
    t, h = t0, dt
    switches: list[tuple[float, str, str]] = []
    counts = {pair.name: [0, 0], EULER.name: [0, 0], implicit.name: [0, 0]}
    budget, euler_budget, failed, euler_failed, previous = 0.0, 0.0, 0, 0, None
    solver = stepper_for(system, implicit)  # one for the run: its Jacobian serves every trial
    # the W-method's probe before a trial of the exact Jacobian's scheme (its own A and LU)
    probe = stepper_for(system, SCHEMES[IMPLICIT]) if getattr(implicit, "krylov", False) else None
    assert probe is None or isinstance(probe, stiff.Stepper)
    stepper = stepper_for(system, pair, compiled)  # goes on after a failed trial
    assert isinstance(solver, stiff.Stepper) and not isinstance(stepper, stiff.Stepper)
    tally, direction = Tally(solver), np.zeros(0)
    phase: _Euler | None = None  # the Euler phase a trial interrupted, if any
    while t < t1:
        costs = Costs.of(pair, tally.cost())
        if isinstance(phase, _Euler):  # an Euler phase goes on after its failed trial
            explicit: _Explicit | _Euler = phase
            costs = Costs(EULER_COST, costs.implicit)
            phase.budget, phase.wants, taken = budget, "", (phase.steps, phase.rejected)
            t, x = phase.run(t, x, t1)
            counts[EULER.name][0] += phase.steps - taken[0]
            counts[EULER.name][1] += phase.rejected - taken[1]
            watch.worst = max(watch.worst, phase.worst)
        else:
            explicit = _Explicit(system, stepper, costs, budget, euler_budget, direction, t1)
            x, done = segment(stepper, x, t, t1, h, tol, watch, explicit, RHO_EVERY, previous)
            t, h, previous = done.end, done.last_step, done.previous
            counts[pair.name][0] += done.accepted
            counts[pair.name][1] += done.rejected
            euler_budget = explicit.euler_budget
        budget, direction, phase = explicit.budget, explicit.direction, None
        if t >= t1:
            break
        if explicit.wants == "euler":
            phase = _Euler(system, explicit.rho, direction, budget, t1 - t0, tol, blowup_factor,
                           compiled)
            _switch(switches, t, EULER.name, (
                f"stability sets the step: h ρ = {explicit.step * explicit.rho:.3g} > "
                f"{STIFF_FRACTION:g} x {pair.name}'s stability boundary {PAIR_BOUNDARY:.3g}: "
                f"{EULER.name} at {EULER_FRACTION:g} x {EULER_BOUNDARY:.3g}/ρ = {phase.step:.4g} "
                f"({EULER_COST:.4g} evaluations a step against {PAIR_COST:g}), in chunks of "
                f"{EULER_EVERY} steps, each within its share of the tolerance"))
            continue
        if isinstance(explicit, _Euler) and explicit.wants != "trial":
            euler_failed += explicit.wants == "pair"
            euler_budget = (euler_retry(euler_failed, explicit.dropped * EULER_COST,
                                        explicit.drift / explicit.share)
                            if explicit.wants == "pair" else math.inf)
            h, previous = pair_step(explicit.rho), None
            _switch(switches, t, pair.name, {
                "unstable": f"{EULER.name} blew up at {explicit.step:.4g}: no {EULER.name} "
                            "from here",
                "end": f"too little time left for two chunks of {EULER.name}",
                "pair": f"{EULER.name}'s error over its last chunk {explicit.drift:.3g} exceeds"
                        f" its share of the tolerance: no {EULER.name} before "
                        f"{euler_budget:g} evaluations"}[explicit.wants])
            continue
        # a trial of the implicit scheme (explicit.wants == "trial")
        trial = TRIAL * costs.break_even(explicit.step)
        if t + trial >= t1:  # too little time left to pay for a switch: explicit to the end
            budget, phase = math.inf, explicit if isinstance(explicit, _Euler) else None
            continue
        mark = tally.mark()
        spent, err, x_new, probed, take = 0.0, math.inf, x, "", True
        if probe is not None:  # the W-method's step sizes the trial, at a few evaluations
            p_err, spent = _probe(probe, t, x, trial, tol, costs.implicit)
            sized = sized_trial(trial, p_err, q, costs.break_even(explicit.step))
            probed = f" (a probe of {IMPLICIT} at {trial:.4g} had err {p_err:.3g})"
            take = sized is not None
            err, trial = (err, sized) if sized is not None else (p_err, trial)
        if take:
            try:
                x_new, x_low = solver.step_with_estimate(t, x, trial)
                err = error_norm(x, x_new, x_low, *tol)
            except (stiff.StiffSolveError, StepFailure):  # a failed trial, as a step too large
                err = math.inf
            # the trial's work, by which the next one waits; a solve that failed is not
            # counted (the stepper counts a step's work as it ends): priced as an implicit step
            spent += max(tally.spent(mark), costs.implicit if math.isinf(err) else 0.0)
        name = EULER.name if isinstance(explicit, _Euler) else pair.name
        if not (err <= 1.0 and watch(t + trial, x_new, 0)):
            tally.exclude(mark)
            counts[implicit.name][1] += 1
            failed += 1
            budget = Costs(costs.explicit, spent).retry(failed, err, q)
            phase = explicit if isinstance(explicit, _Euler) else None
            log.info("auto: stays %s at t=%.10g: a step of %s of %.4g (%g x the break-even "
                     "%.4g/%.4g x the explicit %.4g) has err %.3g > 1 (counted: %.4g "
                     "evaluations)%s", name, t, implicit.name, trial, TRIAL, costs.implicit,
                     costs.explicit, explicit.step, err, spent, probed)
            continue
        tally.accepted += 1  # the trial's work: a measure of the implicit step's
        measured = Costs(costs.explicit, tally.cost())
        if measured.explicit_cheaper(explicit.step, trial):
            counts[implicit.name][1] += 1
            failed += 1
            budget = Costs(costs.explicit, spent).retry(failed, 1.0, q)
            phase = explicit if isinstance(explicit, _Euler) else None
            log.info("auto: stays %s at t=%.10g: a step of %s of %.4g has err %.3g but costs "
                     "%.4g evaluations (counted), more per unit time than %s's %.4g at %.4g",
                     name, t, implicit.name, trial, err, measured.implicit, name,
                     measured.explicit, explicit.step)
            continue
        _switch(switches, t, implicit.name, (
            f"stiff: h ρ = {explicit.step * explicit.rho:.3g} > {STIFF_FRACTION:g} x "
            f"{name}'s stability boundary {explicit.boundary:.3g}, and {implicit.name} took a "
            f"step of {trial:.4g}{probed} against {TRIAL:g} x {costs.implicit:.4g}/"
            f"{costs.explicit:.4g} x {name}'s {explicit.step:.4g} (err {err:.3g}; counted: "
            f"{measured.implicit:.4g} evaluations a step): cheaper per unit time"))
        t, x, failed, previous = t + trial, x_new, 0, None
        counts[implicit.name][0] += 1
        calm = _Implicit(system, direction, Costs(PAIR_COST, measured.implicit), PAIR_BOUNDARY,
                         tally)
        x, done = segment(solver, x, t, t1, trial * factor(err, q, True), tol, watch, calm)
        t, h = done.end, done.last_step
        counts[implicit.name][0] += done.accepted
        counts[implicit.name][1] += done.rejected
        if t >= t1:
            break
        _switch(switches, t, pair.name, (
            f"not stiff enough: {pair.name} at {calm.explicit_step(h):.4g} (ρ = "
            f"{calm.rho:.4g}) costs {calm.costs.explicit:g} evaluations a step, {implicit.name} "
            f"at {h:.4g} {calm.costs.implicit:.4g} (counted): explicit the cheaper for "
            f"{BACK_STEPS} steps"))
        h, budget, direction = calm.explicit_step(h), RETRY * calm.costs.implicit, calm.direction
    accepted = sum(c[0] for c in counts.values())
    return RunResult(projected(system, x, t1), watch.worst, accepted, h,
                     n_rejected=sum(c[1] for c in counts.values()), switches=tuple(switches),
                     by_scheme=tuple((n, a, r) for n, (a, r) in counts.items()))


def _switch(switches: list[tuple[float, str, str]], t: float, scheme: str, why: str) -> None:
    """Keep and log (INFO) the switch to ``scheme`` at ``t``."""
    switches.append((t, scheme, why))
    log.info("auto: %s from t=%.10g, %s", scheme, t, why)
