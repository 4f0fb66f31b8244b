"""The tuner: search the coarse solvers of eq. 30 for the highest predicted speedup at η*.

:func:`tune` (exported as ``parastokes.tuning.tune``) checks the input, computes the pilot
reference and measures the plain baseline, then searches the candidates of the
:class:`~.space.Space` best first. Each candidate goes through two stages:

- screen: its step (the step limit of its most restrictive node, minus the derived margin,
  :mod:`.stability`), its optimistic speedup at that step (N_it = 1, γ_G/γ_F from operation
  counts), and one coarse call over the second slice, whose defect gives a screened prediction
  (:func:`.cost.screened_errors`, corrected by a measured candidate of the same structure);
- measure: the stability verdict of its combined slice map (ρ(DG), :mod:`.slice_map`), the pilot
  run (η^k, :mod:`.pilot`) and the prediction (:mod:`.cost`).

An adaptive candidate (``Settings.rtol``: its auxiliary solvers' controller chooses the steps)
skips the step limit and margin; its screen counts the steps it took, which set its bound, and
its pilot run measures γ_G from its real calls (an adaptive G's cost depends on the state).

The next candidate is the one with the highest estimate: its optimistic speedup before the
screen, its screened speedup after; the given candidates (``Space.extra``) come first, then the
leading ones (``Space.leading``, each screened and measured before any other is screened; not
pruned), then the rest (:func:`rank`). A candidate whose optimistic speedup at its own step cannot
beat the best measured one is pruned: without a budget the search chooses what measuring every
candidate would choose. docs/tuning.md explains the choices and reports measurements.
"""

from __future__ import annotations

import heapq
import logging
import math
import signal
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Protocol, TypeVar

import numpy as np

from .. import integrate
from ..core.contracts import System
from ..core.values import is_integer, is_real
from ..integrate import stability as stable_steps
from ..parallel import TaskError
from ..parareal.transfer import Transfer, take_step_counts
from . import cost, slice_map, stability
from .pilot import Pilot, Screen
from .space import Settings, Space, TuningError, adaptive_only, reach_table

T = TypeVar("T")

__all__ = ["Candidate", "Progress", "ProgressLike", "TuneResult", "tune"]

#: Default budget: this fraction of the estimated serial fine solve (15 %).
BUDGET_FRACTION = 0.15

#: How a search stopped by a signal is reported (the CLI raises SIGTERM and SIGHUP as
#: KeyboardInterrupts that carry ``signum``; Ctrl-C is "interrupted").
STOPPED_BY: dict[int | None, str] = {signal.SIGTERM: "terminated", signal.SIGHUP: "hung up"}

#: Fewest coarse steps per slice considered (the step-limit bisection starts below slice / 10).
MIN_STEPS = 10
#: The same for a linearly implicit scheme (docs/stiff.md): L-stable, its step is bounded by
#: accuracy, not stability, so the search reaches up to two steps per slice; the stability of
#: the slice map (ρ(DG)) and the pilot's η^k then judge it as any candidate.
IMPLICIT_MIN_STEPS = 2

#: The lower bracket of a linearly implicit scheme's step-limit search: this many steps per
#: slice (or τ_f where that is larger). At τ_f, F at its own limit on the rod of 601 points,
#: the bracket's first run took 33 000 implicit steps of the 61-node pilot and the whole of
#: plan's 300 s for tune (docs/planning.md, "Round 5, fourth session").
IMPLICIT_LO_STEPS = 400

#: A budget below this many fine slices of the pilot makes the search frugal: a two-slice pilot
#: window (one iteration), reference growth 1 instead of a measured ρ(DG) (docs/tuning.md, the
#: vesicle).
FRUGAL_SLICES = 20

#: Serial fine solves below this many CPU seconds are small: the default budget is then what
#: twenty candidates need, not 15 % (a search within seconds is not worth saving).
SMALL_PROBLEM = 60.0

#: Safety factor on the optimistic bound's γ_G/γ_F (operation counts, scaled by what the baseline
#: measured): pruning must not discard a candidate whose measured cost turns out lower.
BOUND_SAFETY = 0.8

FINE_ADVICE = "reduce fine.dt (or choose a higher-order fine.scheme) before tuning"

#: Exponents of the step-limit model used only to order candidates before their limit is measured
#: (the stiffest mode scales like bending/viscosity; ε relaxes it strongly, docs/validation.md).
_LIMIT_MODEL = {"epsilon": 4.0, "viscosity": 1.0, "bending": -1.0, "stiffness": -1.0}

#: Stability intervals of the schemes on the negative real axis (for that model only).
_INTERVAL = {"euler": 2.0, "rk2": 2.0, "rk4": 2.785}


class UnstableBaseline(TuningError):
    """The plain baseline scheme is unstable even at τ_f: :func:`tune` tries the next fixed-step
    scheme of the space as its baseline."""


class ProgressLike(Protocol):
    """What :func:`tune` reports its progress to: a :class:`Progress`, or any object with its
    methods (the CLI's bar)."""

    def note(self, text: str) -> None: ...

    def start(self, total: int) -> None: ...

    def advance(self, label: str) -> None: ...

    def finish(self) -> None: ...


class Progress:
    """Receives the tuner's progress (the CLI draws it with tqdm); this base class is silent."""

    def note(self, text: str) -> None:
        """A line of information."""

    def start(self, total: int) -> None:
        """The search over ``total`` candidates begins."""

    def advance(self, label: str) -> None:
        """One candidate is done."""

    def finish(self) -> None:
        """The search is over."""


@dataclass
class Candidate:
    """One candidate and everything measured about it."""

    settings: Settings
    status: str = "pending"  # accepted | rejected | pruned | not reached
    reason: str | None = None
    weight_sum: float = 1.0
    estimated_speedup: float | None = None
    given: bool = False  # given explicitly (Space.extra): measured whatever its estimate
    leading: bool = False  # searched before the others (Space.leading), budget and pruning bind
    screen: dict[str, Any] | None = None  # defect, screened eta and speedup, seconds
    step_limit: float | None = None
    margin: float | None = None  # 1 - step / step limit
    required_margin: float | None = None  # δ derived by stability.step_margin
    spectral_radius: float | None = None  # ρ(DG) of the combined slice map (NaN: not converged)
    radius_calls: int | None = None  # calls of the coarse map it took
    allowed_radius: float | None = None
    pilot_errors: list[float] = field(default_factory=list)
    contraction: float | None = None
    iterations: int | None = None
    gamma_ratio: float | None = None
    speedup: float | None = None
    seconds: float = 0.0  # on the budget's clock (wall with --budget, else CPU)
    coarse: Any = field(default=None, repr=False)  # the built propagator, between the stages
    shot: Screen | None = field(default=None, repr=False)  # its screen, between the stages
    #: Adaptive candidates: steps per slice of one auxiliary solver {accepted, rejected,
    #: switches}, over the coarse calls measured (the screen's, then the pilot's as well).
    steps: dict[str, float] | None = None

    @property
    def stability_margin(self) -> float | None:
        """allowed ρ(DG) / measured ρ(DG) - 1 (positive when stable; None when not measured or
        not converged)."""
        if (self.spectral_radius is None or self.allowed_radius is None
                or math.isnan(self.spectral_radius)):
            return None
        if self.spectral_radius == 0 or not math.isfinite(self.spectral_radius):
            return -1.0 if not math.isfinite(self.spectral_radius) else math.inf
        return self.allowed_radius / self.spectral_radius - 1.0

    def predicted(self) -> dict[str, Any]:
        return {"speedup": self.speedup, "iterations": self.iterations,
                "gamma_ratio": self.gamma_ratio}

    def as_dict(self, fine_dt: float) -> dict[str, Any]:
        margin = self.stability_margin
        stable = None if margin is None else bool(margin >= 0)
        return {
            **self.settings.as_dict(fine_dt),
            "given": self.given,
            "leading": self.leading,
            "status": self.status,
            "reason": self.reason,
            "weight_sum": self.weight_sum,
            "estimated_speedup": self.estimated_speedup,
            "stability": {
                "step_limit": self.step_limit,
                "step_margin": self.margin,
                "required_step_margin": self.required_margin,
                "spectral_radius": (None if self.spectral_radius is None
                                    or math.isnan(self.spectral_radius)
                                    else self.spectral_radius),
                "radius_converged": (None if self.spectral_radius is None
                                     else not math.isnan(self.spectral_radius)),
                "radius_calls": self.radius_calls,
                "allowed_spectral_radius": self.allowed_radius,
                "margin": margin,
                "stable": stable,
            },
            "screen": self.screen,
            "adaptive_steps": self.steps,
            "pilot": {"eta": self.pilot_errors, "eta1": self.pilot_errors[0] if
                      self.pilot_errors else None, "contraction": self.contraction},
            "predicted": self.predicted(),
            "seconds": self.seconds,
        }


@dataclass
class TuneResult:
    """The outcome of :func:`tune`: the chosen coarse propagator (on the run's system), its
    settings, the plain baseline and the report (the content of TUNED.json)."""

    coarse: Any
    settings: Settings | None
    chosen: Candidate | None
    baseline: Candidate
    candidates: list[Candidate]
    report: dict[str, Any]
    pilot: Pilot

    def curves(self, n_slices: int) -> dict[str, Any]:
        """Predicted speedup at the targets 1e-4 .. 1e-10 for every candidate measured on the
        pilot (the same measurements serve every target; only the step margins were derived for
        the requested one), and the best candidate per target."""
        targets = [10.0**-e for e in range(4, 11)]
        measured = [c for c in self.candidates if c.pilot_errors and c.gamma_ratio]
        rows = {f"{c.settings.label()} @ {c.settings.coarse_dt:.4g}":
                self.speedup_curve(c, np.array(targets), n_slices) for c in measured}
        best = {}
        for i, eta in enumerate(targets):
            values = [(v[i], k) for k, v in rows.items() if v[i] is not None]
            best[f"{eta:g}"] = None if not values else {"speedup": max(values)[0],
                                                         "candidate": max(values)[1]}
        return {"targets": targets, "speedup": rows, "best": best}

    def speedup_curve(
        self, candidate: Candidate, targets: np.ndarray, n_slices: int
    ) -> list[float | None]:
        """Predicted speedup (eq. 14) against η* for one measured candidate (Fig. 6b)."""
        out: list[float | None] = []
        for eta in targets:
            k = cost.predicted_iterations(candidate.pilot_errors, self.pilot.n_slices, n_slices,
                                          float(eta), candidate.contraction)
            if k is None:
                out.append(None)
                continue
            if candidate.gamma_ratio is None:
                raise ValueError(f"speedup_curve: {candidate.settings.label()} has no measured "
                                 "γ_G/γ_F (it was not run on the pilot)")
            out.append(cost.speedup(candidate.gamma_ratio, k, n_slices))
        return out


def _check_input(cores: Any, target: Any, n_slices: Any, t0: float, t1: float,
                 budget: Any, pilot_slices: Any) -> None:
    if not is_integer(cores, 1):
        raise TuningError(f"cores must be an integer >= 1, got {cores!r}")
    if not is_integer(n_slices, 2):
        raise TuningError(f"n_slices must be an integer >= 2 (Parareal needs two slices), got "
                          f"{n_slices!r}")
    if not (isinstance(target, int | float) and 0.0 < target < 1.0):
        raise TuningError(f"target: the relative error η* must lie in (0, 1), got {target!r}")
    if not t1 > t0:
        raise TuningError(f"t1 must exceed t0, got [{t0}, {t1}]")
    if budget is not None and not (is_real(budget) and budget > 0):
        raise TuningError(f"budget must be a positive number of seconds, got {budget!r}")
    if pilot_slices is not None and not (is_integer(pilot_slices)
                                         and 2 <= pilot_slices <= n_slices):
        raise TuningError(f"pilot_slices must lie in [2, n_slices = {n_slices}], got "
                          f"{pilot_slices}")


def _seconds_per_step(system: System, fine: integrate.Propagator, x0: np.ndarray, steps: int
                      ) -> float:
    """CPU seconds of F per ``fine.dt`` of time, over ``steps`` of them (its compiled loop is
    loaded before, in ``tune``): per step on fixed steps; with ``rtol`` (adaptive steps, or
    ``"auto"``) F's cost as it runs, whatever steps it takes."""
    start = time.process_time()
    integrate.run(system, x0, 0.0, steps * fine.dt, fine.scheme, fine.dt, rtol=fine.rtol,
                  atol=fine.atol)
    return (time.process_time() - start) / steps


def _coarsened(system: System, factor: int) -> tuple[System, Transfer]:
    """``system.coarsened(factor)``, an optional member of the System contract (AttributeError
    for a system without it)."""
    coarsened = getattr(system, "coarsened", None)
    if coarsened is None:
        raise AttributeError(f"{type(system).__name__} has no coarsened(factor) method")
    return coarsened(factor)


class _OutOfBudget(Exception):
    """The search's budget ran out inside a candidate's stage (its step-limit bisection)."""


class _HeldBack(logging.Filter):
    """Holds back and counts ``integrate.largest_stable_step``'s warning that the largest step
    tried is stable (implicit schemes: once per step-limit search); the search says it once."""

    def __init__(self) -> None:
        super().__init__()
        self.count = 0

    def filter(self, record: logging.LogRecord) -> bool:
        if record.getMessage().startswith("largest_stable_step: dt_hi="):
            self.count += 1
            return False
        return True


def steps_per_slice(counts: dict[str, int], calls: int, n_auxiliary: int) -> dict[str, float]:
    """The adaptive step counts ``{accepted, rejected, switches}`` of ``calls`` coarse calls of
    ``n_auxiliary`` auxiliary solvers each, per slice (one call) and per auxiliary solver."""
    return {key: value / (calls * n_auxiliary) for key, value in counts.items()}


def _accepted_speedup(cand: Candidate) -> float:
    assert cand.speedup is not None  # (set with the status "accepted")
    return cand.speedup


class _Search:
    """The state of one search (limits cache, pilot, best so far)."""

    def __init__(self, pilot: Pilot, space: Space, n_slices: int, cores: int, target: float,
                 points: int, clock: Callable[[], float]) -> None:
        self.pilot, self.space, self.clock = pilot, space, clock
        self.n_slices, self.cores, self.target = n_slices, cores, target
        self.system = pilot.system
        self.theta0 = dict(self.system.params)
        self.points = points
        self.limits: dict[tuple, float] = {}
        self.reference_radius: float | None = None
        self.unchecked: Candidate | None = None  # measured without the verdict on ρ(DG)
        self.notes: list[str] = []
        self.base_scheme = "euler"
        self.cost_scale = 1.0
        self.base_shot: Screen | None = None
        self.base_errors: list[float] = []
        self.base_rho: float | None = None
        self.calibrations: list[tuple[Settings, list[float]]] = []
        #: The budget's end on ``clock`` while a candidate that it binds is worked on, else None.
        self.deadline: float | None = None

    def charge(self) -> None:
        """Called before every trial run of a step-limit bisection: :class:`_OutOfBudget` once
        the budget is spent (an implicit scheme's bisection runs whole slices at the fine
        step)."""
        if self.deadline is not None and self.clock() > self.deadline:
            raise _OutOfBudget

    # ---- step limits ----
    def _grid_system(self, grid: int) -> tuple[System, np.ndarray]:
        if grid == 1:
            return self.system, self.pilot.x0
        coarse, transfer = _coarsened(self.system, grid)
        return coarse, transfer.restrict(self.pilot.x0)

    def limit(self, settings: Settings) -> float:
        corner = settings.corner()
        key = (settings.scheme, settings.grid, tuple(sorted(corner.items())))
        if key not in self.limits:
            system, x0 = self._grid_system(settings.grid)
            if corner:
                system = system.with_params(**corner)
            # at least MIN_STEPS steps per slice: a test over fewer steps cannot see growth
            span = self.pilot.slice_length
            implicit = integrate.lookup(settings.scheme).implicit
            fewest = IMPLICIT_MIN_STEPS if implicit else MIN_STEPS
            hi = span / fewest
            # an implicit scheme's lower bracket: IMPLICIT_LO_STEPS steps per slice where that
            # is above τ_f (its first run, the body's own change, then costs a few hundred
            # implicit steps instead of a slice of fine steps), τ_f where that run fails
            los = dict.fromkeys((max(self.pilot.fine.dt, span / IMPLICIT_LO_STEPS)
                                 if implicit else self.pilot.fine.dt, self.pilot.fine.dt))
            self.limits[key] = math.nan
            for lo in los:
                try:
                    self.limits[key] = stability.step_limit(
                        system, settings.scheme, x0, self.pilot.t0, span, lo, max(hi, 2 * lo),
                        stop=self.charge)
                    break
                except ValueError:
                    continue
        return self.limits[key]

    def estimated_step(self, settings: Settings) -> float:
        """The step limit model that orders unscreened candidates: the baseline scheme's measured
        plain limit (no bisection for another scheme before one of its candidates is screened),
        scaled by the schemes' real stability intervals and the parameters (_LIMIT_MODEL). An
        implicit scheme has no stability interval to scale: its largest step searched (half a
        slice), an optimistic bound measured by :meth:`step` when its turn comes; the same for
        ``"auto"``, which turns implicit where stiffness caps the explicit step (an adaptive
        candidate's real steps are counted by its screen)."""
        scheme = integrate.lookup(settings.scheme)
        if scheme.implicit or scheme is integrate.AUTO:
            return self.pilot.slice_length / IMPLICIT_MIN_STEPS * settings.step_fraction
        # an implicit baseline (every explicit one unstable at τ_f) scales nothing: Euler's limit
        base = "euler" if integrate.lookup(self.base_scheme).implicit else self.base_scheme
        plain = self.limit(Settings(base, grid=settings.grid))
        plain *= _INTERVAL.get(settings.scheme, 2.0) / _INTERVAL.get(base, 2.0)
        factor = math.prod((value / self.theta0[name]) ** _LIMIT_MODEL[name]
                           for name, value in settings.corner().items())
        return plain * factor * settings.step_fraction

    def coarse_points(self, grid: int) -> int:
        system, x0 = self._grid_system(grid)
        return len(system.positions(x0))

    def counted_ratio(self, settings: Settings, dt: float) -> float:
        """γ_G/γ_F from operation counts at step ``dt``."""
        return cost.estimated_ratio(
            replace(settings, dt=dt), self.pilot.slice_length, self.pilot.fine.scheme,
            integrate.n_steps(0.0, self.pilot.slice_length, self.pilot.fine.dt),
            self.points, self.coarse_points(settings.grid), self.cores)

    def estimate(self, settings: Settings, dt: float) -> float:
        """The optimistic speedup at step ``dt``: eq. 14 with N_it = 1 and the counted γ_G/γ_F
        times ``cost_scale`` (set by the baseline: BOUND_SAFETY times its measured/counted
        ratio, at most 1)."""
        return cost.speedup(self.counted_ratio(settings, dt) * self.cost_scale, 1,
                            self.n_slices)

    # ---- stage 1: step, bound, screen ----
    def timed(self, cand: Candidate, stage: Callable[[Candidate], T]) -> T:
        """``stage(cand)``, its time added to the candidate's seconds."""
        start = self.clock()
        try:
            return stage(cand)
        finally:
            cand.seconds += self.clock() - start

    def step(self, cand: Candidate) -> bool:
        """Set the candidate's step and optimistic bound; False if it is rejected. An adaptive
        candidate has no step limit (its controller keeps it within the tolerance, and the
        verdict on ρ(DG) and the pilot judge it): its first step tried is the model step, its
        bound stays at the model step until its screen counts its real steps."""
        s = cand.settings
        if s.adaptive:
            if s.dt is None:
                model = self.estimated_step(replace(s, rtol=None, atol=None))
                first = self.pilot.slice_length / math.ceil(self.pilot.slice_length / model - 1e-9)
                cand.settings = replace(s, dt=first)
            return True
        limit = self.limit(s)
        cand.step_limit = limit
        if not math.isfinite(limit):
            cand.status, cand.reason = "rejected", "not stable even at the fine step τ_f"
            return False
        _, cand.required_margin = stability.safe_step(limit, self.pilot.slice_length,
                                                      cand.weight_sum, self.target)
        dt = s.dt
        if dt is None:  # the largest safe step, times the candidate's fraction
            dt = limit * (1.0 - cand.required_margin) * s.step_fraction
            dt = self.pilot.slice_length / math.ceil(self.pilot.slice_length / dt - 1e-9)
            cand.settings = s = replace(s, dt=dt)
        cand.margin = 1.0 - dt / limit
        if s.m:
            counts = [integrate.n_steps(0.0, self.pilot.slice_length, dt * s.ratio**q)
                      for q in range(s.m + 1)]
            if len(set(counts)) < len(counts):
                cand.status, cand.reason = "rejected", f"Richardson steps coincide ({counts})"
                return False
        cand.estimated_speedup = self.estimate(s, dt)
        return True

    def screen(self, cand: Candidate) -> None:
        """One coarse call over the second slice; the screened prediction from its defect."""
        s = cand.settings
        coarse = s.build(self.system)
        try:
            shot = self.pilot.screen(coarse)
        except (integrate.BlowUpError, TaskError) as error:
            cand.status, cand.reason = "rejected", f"blew up over the first slice: {error}"
            return
        cand.coarse, cand.shot = coarse, shot
        cand.screen = {"defect": shot.defect, "seconds": shot.seconds}
        if s.adaptive:  # its bound at the steps it took (accepted and rejected: both cost)
            counts = take_step_counts(coarse)
            assert counts is not None  # (an adaptive coarse solver counts its steps)
            cand.screen["steps"] = counts
            cand.steps = steps_per_slice(counts, 1, s.n_auxiliary)
            taken = max(1.0, cand.steps["accepted"] + cand.steps["rejected"])
            cand.estimated_speedup = self.estimate(s, self.pilot.slice_length / taken)
        base = self.base_shot
        if base is not None and base.defect > 0 and self.base_errors:
            cand.screen |= {
                "model_eta": cost.screened_errors(shot.defect, base.defect, self.base_errors),
                "gamma_ratio": cost.gamma_ratio(s, self.pilot.slice_length, shot.seconds,
                                                self.pilot.gamma_f, self.cores)}
            self.rescreen(cand)

    def rescreen(self, cand: Candidate) -> None:
        """The screened prediction, corrected by a measured candidate of the same structure (the
        same parameters extrapolated and reach; the same Richardson depth if there is one): the
        ratio of its pilot η^k to its own screened η^k. The defect misses part of the Lagrange
        extrapolation's error (docs/tuning.md), and that part is alike within a structure."""
        info = cand.screen
        if not info or "model_eta" not in info:
            return
        s = cand.settings
        names = tuple(name for name, _ in s.lagrange)

        def likeness(other: Settings) -> tuple:
            return (tuple(n for n, _ in other.lagrange) == names
                    and other.adaptive == s.adaptive, other.reach == s.reach, other.m == s.m)

        like = max(self.calibrations, key=lambda item: likeness(item[0]), default=None)
        factors = like[1] if like is not None and all(likeness(like[0])[:2]) else []
        errors = [e * (factors[i] if i < len(factors) else (factors[-1] if factors else 1.0))
                  for i, e in enumerate(info["model_eta"])]
        k = cost.predicted_iterations(errors, self.pilot.n_slices, self.n_slices, self.target,
                                      self.base_rho)
        info |= {"eta": errors,
                 "calibrated_by": like[0].label() if like is not None and factors else "baseline",
                 "iterations": k,
                 "speedup": None if k is None else cost.speedup(info["gamma_ratio"], k,
                                                                self.n_slices)}

    def calibrate(self, cand: Candidate) -> None:
        """Record how far a measured candidate's screen was from its pilot (see rescreen)."""
        model = (cand.screen or {}).get("model_eta")
        if model and cand.pilot_errors and not cand.settings.plain:
            pairs = zip(cand.pilot_errors, model, strict=False)
            self.calibrations.append((cand.settings, [
                measured / screened for measured, screened in pairs if screened > 0]))

    # ---- stage 2: stability of the combined map, pilot run, prediction ----
    def window(self) -> tuple[float, float]:
        """The pilot's first slice."""
        return self.pilot.t0, self.pilot.t0 + self.pilot.slice_length

    def radius(self, cand: Candidate, coarse: Any) -> slice_map.Radius:
        """ρ(DG) of ``coarse`` over the first slice, recorded on ``cand``."""
        found = stability.spectral_radius(coarse, self.system, self.pilot.x0, *self.window(),
                                              tol=stability.radius_tolerance(self.n_slices))
        cand.spectral_radius, cand.radius_calls = found.rho, found.calls
        return found

    def stable(self, cand: Candidate, coarse: Any) -> bool:
        """The verdict on ρ(DG) of the combined slice map (docs/tuning.md, step 7); when False,
        ``cand.reason`` says why."""
        if cand.spectral_radius is None:
            self.radius(cand, coarse)
        assert self.reference_radius is not None  # (set by the baseline, measured first)
        assert cand.spectral_radius is not None  # (set just above)
        cand.allowed_radius = stability.allowed_radius(self.reference_radius, self.n_slices)
        if math.isnan(cand.spectral_radius):
            cand.reason = ("stability of the combined slice map not established: ρ(DG) did not "
                           f"converge within {cand.radius_calls} calls of the coarse map")
            return False
        if not cand.spectral_radius <= cand.allowed_radius:
            cand.reason = (f"combined slice map unstable: ρ(DG) = {cand.spectral_radius:.4g} > "
                           f"{cand.allowed_radius:.4g} allowed over {self.n_slices} slices")
            return False
        return True

    def measure(self, cand: Candidate) -> None:
        """The verdict on ρ(DG) (not for ``self.unchecked``), the pilot run, the prediction."""
        s = cand.settings
        coarse, shot = cand.coarse, cand.shot
        if cand is not self.unchecked and not self.stable(cand, coarse):
            cand.status = "rejected"
            return
        iterations = min(2, self.pilot.n_slices - 1)
        take_step_counts(coarse)  # (the calls of ρ(DG) are not the pilot's)
        try:
            run = self.pilot.measure(coarse, iterations, shot)
        except (integrate.BlowUpError, TaskError) as error:
            cand.status, cand.reason = "rejected", f"blew up in the pilot: {error}"
            return
        if s.adaptive and cand.screen is not None:  # the screen's call and the pilot's
            counts = take_step_counts(coarse)
            assert counts is not None  # (an adaptive coarse solver counts its steps)
            counts = {key: value + cand.screen["steps"][key] for key, value in counts.items()}
            cand.steps = steps_per_slice(counts, run.calls + 1, s.n_auxiliary)
        cand.pilot_errors = run.errors
        cand.contraction = cost.contraction(run.errors, run.eta0)
        cand.gamma_ratio = cost.gamma_ratio(s, self.pilot.slice_length, run.coarse_seconds,
                                            self.pilot.gamma_f, self.cores)
        cand.iterations = cost.predicted_iterations(run.errors, self.pilot.n_slices,
                                                    self.n_slices, self.target, cand.contraction)
        if cand.iterations is None:
            cand.status = "rejected"
            cand.reason = (f"does not reach η* = {self.target:g} in fewer than N_c iterations "
                           f"(pilot η^k = {', '.join(f'{e:.2e}' for e in run.errors)})")
            return
        cand.speedup = cost.speedup(cand.gamma_ratio, cand.iterations, self.n_slices)
        cand.status = "accepted"

    def baseline(self, scheme: str, frugal: bool) -> Candidate:
        """G_{Θ⁰,τ} at its largest safe step, measured in full; it fixes the physics' own ρ(DG)
        (at half the step limit), the bound's cost scale and the screen's calibration. It is not
        checked on ρ(DG) itself: a single solver at its safe step (step 6) has no combination to
        check. In a frugal search the reference is not measured either (its 22 or more coarse
        calls would take a large part of the budget): the reference growth is then 1."""
        self.base_scheme = scheme
        cand = Candidate(Settings(scheme))
        self.timed(cand, self.step)
        if cand.status == "rejected":
            raise UnstableBaseline(f"the plain {scheme} coarse solver is unstable even at τ_f")
        self.timed(cand, self.screen)
        if cand.status == "rejected":
            raise TuningError(f"the plain {scheme} coarse solver blows up over the first slice "
                              f"at its largest stable step ({cand.reason}); reduce fine.dt")
        self.unchecked = cand
        if frugal:
            self.reference_radius = 1.0
        else:
            assert cand.step_limit is not None  # (set by its step)
            half = replace(cand.settings, dt=self.pilot.slice_length /
                           math.ceil(self.pilot.slice_length / (0.5 * cand.step_limit)))
            reference = stability.spectral_radius(
                half.build(self.system), self.system, self.pilot.x0, *self.window(),
                tol=stability.radius_tolerance(self.n_slices))
            if math.isnan(reference.rho):
                self.notes.append(f"ρ(DG) of the reference did not converge within "
                                  f"{reference.calls} calls: reference growth 1 (no growth)")
            self.reference_radius = 1.0 if math.isnan(reference.rho) else reference.rho
        self.timed(cand, self.measure)
        self.base_shot = cand.shot
        self.base_errors = cand.pilot_errors
        self.base_rho = cand.contraction
        dt = cand.settings.dt
        assert dt is not None  # (set by its step)
        if cand.gamma_ratio:
            counted = self.counted_ratio(cand.settings, dt)
            self.cost_scale = min(1.0, BOUND_SAFETY * cand.gamma_ratio / counted)
        cand.estimated_speedup = self.estimate(cand.settings, dt)
        return cand


def _counts(candidates: list[Candidate]) -> dict[str, int]:
    """How many of ``candidates`` (the baseline among them) ended with each status; they add up
    to all of them."""
    counts: dict[str, int] = {}
    for cand in candidates:
        counts[cand.status] = counts.get(cand.status, 0) + 1
    return counts


def rank(cand: Candidate) -> int:
    """The first member of a candidate's place in the search's queue (then its estimate): 0
    given (``Space.extra``), 1 leading (``Space.leading``), 2 every other one; a screened
    candidate goes back with the same rank, so each leading candidate is measured before any
    other one is screened."""
    return 0 if cand.given else 1 if cand.leading else 2


def _key(search: _Search, cand: Candidate) -> float:
    """The search's estimate of a queued candidate: its (re)screened speedup once screened, else
    its optimistic speedup (at the model step until its real step is known)."""
    if cand.screen is None:
        return cand.estimated_speedup if cand.estimated_speedup is not None else -math.inf
    if "model_eta" not in cand.screen:  # no calibrated screen (the baseline's pilot failed)
        assert cand.estimated_speedup is not None  # (set by its step, before its screen)
        return cand.estimated_speedup
    search.rescreen(cand)
    estimate = cand.screen["speedup"]
    return 0.0 if estimate is None else estimate  # None: screened not to reach η*


def baseline_schemes(schemes: Sequence[str]) -> list[str]:
    """The schemes :func:`tune` tries in turn as its baseline: forward Euler first (also when the
    space has no fixed-step scheme), then the space's other fixed-step schemes in its order."""
    fixed = [name for name in schemes if not adaptive_only(name)]
    first = ["euler"] if "euler" in fixed or not fixed else []
    return first + [name for name in fixed if name != "euler"]


def _first_stable_baseline(search: _Search, bases: Sequence[str], frugal: bool,
                           progress: ProgressLike) -> Candidate:
    """The baseline of the first scheme of ``bases`` stable at τ_f (noted in the report for each
    one passed over); :class:`TuningError` naming them all when none is."""
    for scheme in bases:
        progress.note(f"baseline: plain {scheme} at its largest safe step")
        try:
            return search.baseline(scheme, frugal)
        except UnstableBaseline as error:
            search.notes.append(f"{error}: the baseline is the next fixed-step scheme")
    implicit = [name for name, scheme in integrate.SCHEMES.items() if scheme.implicit]
    raise TuningError(f"the plain coarse solvers of {', '.join(bases)} are unstable even at τ_f; "
                      f"add an implicit scheme to the schemes (one of {implicit})")


def tune(
    fine: integrate.Propagator,
    *,
    t0: float,
    t1: float,
    n_slices: int,
    cores: int,
    target: float,
    x0: np.ndarray | None = None,
    space: Space | None = None,
    budget: float | None = None,
    pilot: System | None = None,
    pilot_slices: int | None = None,
    progress: ProgressLike | None = None,
    clock: Callable[[], float] | None = None,
    exhaustive: bool = False,
) -> TuneResult:
    """Choose the coarse solver with the highest predicted speedup (eq. 14) that is stable and
    reaches the relative error ``target`` (η*, eq. 34) on ``n_slices`` slices with ``cores``.

    ``fine`` is the fine propagator F (its ``system`` is the run's); ``pilot`` an optional smaller
    system with the same parameters, grid spacing and stiffness (a shortened rod) on which every
    measurement is made, starting from its initial state (default: ``fine.system`` from ``x0``);
    ``pilot_slices`` the slices of the pilot window (run's slice length); ``budget`` a wall-time
    limit in seconds for the whole search (default: 15 % of the estimated serial fine solve in
    CPU time of this process, or what a minimal search needs on small problems, said in
    ``report["search"]["notes"]``). Costs are CPU times (``report["cost"]``: ``fraction`` is
    CPU time spent over the serial fine solve's estimated CPU time; ``seconds`` is wall time).
    ``exhaustive`` measures every candidate (no pruning; for checking the pruning).
    Bad input raises :class:`TuningError` before the search.
    Ctrl-C during the search stops it and keeps what was measured (``report["search"]``).
    Returns a :class:`TuneResult`; its ``coarse`` is None when no candidate reaches η*.
    """
    given_budget = budget is not None
    if clock is None:  # a given budget is wall time; the default one is CPU time (see above)
        clock = time.perf_counter if given_budget else time.process_time
    _check_input(cores, target, n_slices, t0, t1, budget, pilot_slices)
    space = space or Space()
    progress = progress or Progress()
    system = fine.system
    pilot_system = pilot if pilot is not None else system
    if x0 is None or pilot is not None:
        start_state = pilot_system.initial_state()
    else:
        start_state = np.asarray(x0, dtype=float)

    def grid_ok(factor: int) -> bool:
        try:
            for s in {id(system): system, id(pilot_system): pilot_system}.values():
                _coarsened(s, factor)
        except (AttributeError, ValueError):
            return False
        return True

    space.check(pilot_system.params, grid_ok)
    reaches = reach_table(pilot_system)
    # the baseline: plain forward Euler, else the space's fixed-step schemes in turn
    bases = baseline_schemes(space.schemes)
    for body, x in {id(system): (system, system.initial_state()),
                 id(pilot_system): (pilot_system, start_state)}.values():
        cost.compile_loops(body, x, t0, fine, (*space.schemes, *bases))
    started, wall, cpu = clock(), time.perf_counter(), time.process_time()
    slice_length = (t1 - t0) / n_slices
    fine_steps = integrate.n_steps(0.0, slice_length, fine.dt)
    pilot_fine = integrate.Propagator(pilot_system, fine.scheme, fine.dt, rtol=fine.rtol,
                                      atol=fine.atol)

    probe = max(1, min(fine_steps, 50))
    try:
        step_full = _seconds_per_step(system, fine, system.initial_state(), probe)
        step_pilot = (step_full if pilot_system is system else
                      _seconds_per_step(pilot_system, pilot_fine, start_state, probe))
    except integrate.BlowUpError as error:
        raise TuningError(f"the fine solver itself is unstable: {error}; {FINE_ADVICE}") from None
    serial_estimate = step_full * fine_steps * n_slices
    slice_seconds = step_pilot * fine_steps
    notes = []

    def needs(slices: int) -> tuple[float, float]:
        """(one candidate, the reference with the baseline and one candidate): a candidate's
        fine solves plus about two slices' worth of coarse calls and bisection."""
        iterations = min(2, slices - 1)
        one = slice_seconds * (sum(slices - k for k in range(1, iterations + 1)) + 2)
        return one, slice_seconds * (slices + 0.5) + 2 * one

    default_budget = BUDGET_FRACTION * serial_estimate
    if budget is None:  # 15 % of the serial fine solve; for small problems what a search needs
        one, needed = needs(pilot_slices or 3)
        if serial_estimate < SMALL_PROBLEM and default_budget < needed + 20 * one:
            budget = needed + 20 * one
            notes.append(f"the problem is too small for a search within {BUDGET_FRACTION:.0%} "
                         f"of its serial fine solve ({serial_estimate:.3g} s); budget "
                         f"{budget:.3g} s")
        else:
            budget = default_budget
    frugal = budget < FRUGAL_SLICES * slice_seconds
    if pilot_slices is None:  # never longer than the run
        pilot_slices = min(2 if frugal else 3, n_slices)
    one_candidate, needed = needs(pilot_slices)
    if given_budget and budget < needed:
        raise TuningError(
            f"budget: {budget:g} s is too small to test even one candidate; the pilot reference "
            f"and one candidate need about {needed:.3g} s (fine solves of {slice_seconds:.3g} s "
            "per slice); raise --budget or use fewer --pilot-slices"
        )
    if frugal:
        notes.append(f"frugal search (budget below {FRUGAL_SLICES} fine slices): "
                     f"{pilot_slices}-slice pilot, reference growth 1 (ρ(DG) of the plain "
                     "solver not measured)")
    progress.note(f"pilot: {pilot_slices} slices of {fine_steps} fine steps "
                  f"(about {slice_seconds:.3g} s each)")
    pilot_window = Pilot.prepare(pilot_fine, start_state, t0, slice_length, pilot_slices)
    if target < pilot_window.fine_error:
        raise TuningError(
            f"target: η* = {target:g} is below the fine solver's own time-discretization error "
            f"(about {pilot_window.fine_error:.2g} over the first slice); raise --target or "
            "reduce fine.dt"
        )
    search = _Search(pilot_window, space, n_slices, cores, target,
                     len(pilot_system.positions(start_state)), clock)
    search.notes = notes
    held = _HeldBack()  # (removed when the search ends)
    stable_steps.log.addFilter(held)
    try:
        baseline = _first_stable_baseline(search, bases, frugal, progress)
    except BaseException:
        stable_steps.log.removeFilter(held)
        raise
    base_scheme = search.base_scheme

    candidates = [Candidate(s) for s in space.candidates(pilot_system.params, reaches)
                  if s != Settings(base_scheme)]
    candidates += [Candidate(s) for s in dict.fromkeys(space.leading)
                   if s != Settings(base_scheme) and s not in {c.settings for c in candidates}]
    for cand in candidates:
        cand.leading = cand.settings in space.leading
    candidates += [Candidate(s, given=True) for s in space.extra]
    queue: list[tuple] = []
    for n, cand in enumerate(candidates):
        cand.weight_sum = cand.settings.weight_sum(search.theta0)
        if cand.weight_sum > space.max_weight and not cand.given:
            cand.status = "pruned"
            cand.reason = f"Σ|w_j v_q| = {cand.weight_sum:.3g} > {space.max_weight:g}"
            continue
        step = cand.settings.dt or search.estimated_step(cand.settings)
        # the optimistic speedup at the model step, until step() measures the real one
        cand.estimated_speedup = (search.estimate(cand.settings, step) if math.isfinite(step)
                                  else -math.inf)
        heapq.heappush(queue, (rank(cand), -cand.estimated_speedup, n))
    best = baseline.speedup if baseline.status == "accepted" else -math.inf
    stopped, done = None, 0
    spent: dict[bool, list[float]] = {False: [], True: []}  # screen / measure times
    ordered = len(queue)
    weighed_out = len(candidates) - ordered
    if weighed_out:
        progress.note(f"{len(candidates)} candidates besides the baseline: {weighed_out} pruned "
                      f"by their weights (Σ|w_j v_q| > {space.max_weight:g}), {ordered} to "
                      "search")
    progress.start(ordered)
    try:
        while queue:
            entry = queue[0]
            cand = candidates[entry[2]]
            screened = cand.screen is not None
            # the dearest stage of its kind so far (a new corner's bisection makes screens uneven)
            typical = (max(spent[screened]) if spent[screened] else
                       one_candidate if screened else 0.5 * slice_seconds)
            measuring = max(spent[True]) if spent[True] else one_candidate
            if not screened and clock() - started + typical + measuring > budget:
                # the budget keeps one measurement: spend it on the best screened candidate that
                # may beat the best measured, rather than on more screens that could not be used
                waiting = [e for e in queue
                           if candidates[e[2]].screen is not None and -e[1] > best]
                if waiting:
                    entry = min(waiting)
                    cand, screened, typical = candidates[entry[2]], True, measuring
            if clock() - started + typical > budget and not cand.given:
                stopped = "budget"
                break
            queue.remove(entry)
            heapq.heapify(queue)
            n = entry[2]
            before = cand.seconds
            search.deadline = None if cand.given else started + budget
            # the bound a candidate must beat: the best measured (not when given or exhaustive)
            floor = -math.inf if exhaustive or cand.given or cand.leading else best
            if screened:
                if cand.estimated_speedup > floor:
                    search.timed(cand, search.measure)
                    cand.coarse = cand.shot = None
                    if cand.status == "accepted" and cand.speedup > best:
                        best = cand.speedup
                    search.calibrate(cand)
                    queue = [(g, -_key(search, candidates[m]), m) for g, _, m in queue]
                    heapq.heapify(queue)
            elif search.timed(cand, search.step) and cand.estimated_speedup > floor:
                search.timed(cand, search.screen)
            if cand.status == "pending" and cand.estimated_speedup <= floor:
                cand.status = "pruned"
                cand.reason = (f"optimistic speedup {cand.estimated_speedup:.3g} at its step "
                               f"cannot beat the best measured {best:.3g}")
            if cand.status == "pending":
                if not screened:  # measured next when its screened estimate is the highest
                    heapq.heappush(queue, (rank(cand), -_key(search, cand), n))
                    spent[False].append(cand.seconds - before)
            else:
                if screened:
                    spent[True].append(cand.seconds - before)
                done += 1
                progress.advance(cand.settings.label())
    except _OutOfBudget:  # inside a candidate's step-limit bisection
        stopped = "budget"
    except KeyboardInterrupt as stop:  # Ctrl-C, or SIGTERM/SIGHUP as the CLI raises them
        stopped = STOPPED_BY.get(getattr(stop, "signum", None), "interrupted")
    finally:
        progress.finish()
        search.deadline = None
        stable_steps.log.removeFilter(held)
    if held.count:
        notes.append(f"the largest step tried was stable in {held.count} step-limit "
                     f"search{'es' if held.count > 1 else ''} (half a slice for an implicit "
                     "scheme, a tenth for an explicit one): those steps are bounded by accuracy, "
                     "which the pilot measures, not by stability")
        progress.note(f"note: {notes[-1]}")
    for cand in candidates:
        if cand.status == "pending":
            cand.status = "not reached"
            cand.reason = (f"search stopped ({stopped})" if cand.screen is None else
                           f"screened only, search stopped ({stopped})")
            cand.coarse = cand.shot = None

    everything = [baseline, *candidates]
    accepted = [c for c in everything if c.status == "accepted"]
    chosen = max(accepted, key=_accepted_speedup) if accepted else None
    seconds, cpu = time.perf_counter() - wall, time.process_time() - cpu
    from .report import build_report

    report = build_report(
        chosen=chosen, baseline=baseline, candidates=everything, fine=fine, pilot=pilot_window,
        n_slices=n_slices, cores=cores, target=target, t0=t0, t1=t1,
        cost={"seconds": seconds, "cpu_seconds": cpu, "serial_fine_estimate": serial_estimate,
              "fraction": cpu / serial_estimate, "budget": budget},
        search={"stopped": stopped, "evaluated": done, "ordered": ordered,
                "screened": sum(c.screen is not None for c in candidates),
                "total": len(everything), "weighed_out": weighed_out,
                "counts": _counts(everything), "reference_radius": search.reference_radius,
                "notes": notes},
        full_points=len(system.positions(system.initial_state())),
    )
    result = TuneResult(None, chosen.settings if chosen else None, chosen, baseline, everything,
                        report, pilot_window)
    report["curves"] = result.curves(n_slices)
    if chosen is not None:
        result.coarse = chosen.settings.build(system)
    return result

