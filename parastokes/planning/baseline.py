"""The fastest serial run of a given accuracy, found by a bounded search (``parastokes plan``).

Given a problem (a system, its initial state, [t0, T] and the configuration's fine solver F) and a
target error η* at T (eq. 34's measure, as :mod:`parastokes.parareal.best_serial` uses), find the
serial run that reaches η* in the least CPU time. The candidates come from
:data:`parastokes.integrate.SCHEMES`, read through what every scheme says of itself (``implicit``,
``order``, ``adaptive``), so schemes added there are searched too:

- explicit schemes at fixed steps near their stability limit (not the embedded pairs, which
  ``check`` refuses on a fixed step: ``rk4`` is cheaper there): forward Euler's limit is bisected
  on the problem (``integrate.largest_stable_step``), another explicit scheme's is that times the
  ratio of the schemes' stability intervals on the negative real axis
  (:func:`real_stability_interval`, from the tableau); steps :data:`EXPLICIT_FRACTIONS` of it;
- linearly implicit schemes at fixed steps :data:`IMPLICIT_MULTIPLES` times Euler's limit;
- every scheme with an error estimate (and ``scheme = "auto"`` where ``integrate`` offers it) at
  tolerances :data:`RTOL_FACTORS` times η*.

Errors are measured against F's own run (the reference) over a shortened interval [t0, t0 + T_s]
when the whole one is too costly: T_s is the longest span whose reference run costs at most
:data:`REFERENCE_SHARE` of the budget. Errors are taken at T_s as they are (not scaled to T): a
candidate can only look more accurate than it is at T, so the baseline found is at most as
costly as the true one and a speedup against it is not overstated, provided the search ran to
its end (one stopped by its budget records ``stopped``, and ``plan`` warns that its baseline may
be dearer than the true one). CPU times are scaled linearly in T (T / T_s). Within a family (one
scheme, fixed or adaptive), candidates go from cheap to dear, and the families are measured
rank by rank (:func:`by_rank`: every family's cheapest run, then every family's second, ...),
so that a search cut short has tried every family. A family stops at its first run reaching
η*/:data:`F_FACTOR` (``plan`` also chooses F from the same runs) or once it costs more than
the cheapest run reaching it. The search stops at the budget (CPU seconds, exceeded by at most
one candidate) or after :data:`MAX_CANDIDATES` runs; a candidate runs in pieces and is abandoned
once its CPU time passes that of the cheapest run reaching η*/F_FACTOR so far. Everything is
deterministic given the measurements; :func:`choose_runs` is the whole decision, apart from the
integration (``measure``).
docs/planning.md has the why.
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from .. import integrate
from ..core.contracts import System
from ..core.files import atomic_write
from ..integrate.schemes import Scheme, real_stability_boundary
from ..parareal.best_serial import cached_entries
from ..parareal.metrics import relative_change
from ..tuning.cost import compile_loops
from ..tuning.pilot import own_error

__all__ = ["F_FACTOR", "Baseline", "Run", "cached", "candidates", "cheapest", "choose_runs",
           "real_stability_interval", "search", "store"]

#: F (of ``plan``'s Parareal route) must have an error at most η*/F_FACTOR: its own error then
#: leaves 90 % of η* to Parareal's iterations (docs/planning.md).
F_FACTOR = 10.0
#: The reference run takes at most this share of the search's budget (sets T_s).
REFERENCE_SHARE = 0.25
#: The reference's own error must lie this many times below η*/F_FACTOR (``plan`` refuses a
#: target it cannot judge: ``planning.command.resolvable``).
RESOLUTION = 10.0
#: Most halvings of F's step for a reference that can judge η* (:func:`refinements`).
MOST_HALVINGS = 4
#: Default budget of the search, CPU seconds.
DEFAULT_BUDGET = 120.0
#: Most candidate runs measured.
MAX_CANDIDATES = 24
#: Fixed steps of explicit schemes, as fractions of their stability limit.
EXPLICIT_FRACTIONS = (0.9, 0.45, 0.225)
#: Fixed steps of implicit schemes, as multiples of forward Euler's stability limit.
IMPLICIT_MULTIPLES = (20.0, 10.0, 5.0, 2.5)
#: Adaptive steps: rtol = these times η* (atol = rtol).
RTOL_FACTORS = (1.0, 0.1, 0.01)
#: Fewest steps of a fixed-step candidate over T_s (its CPU time is then worth scaling).
MIN_STEPS = 10
#: A candidate runs over T_s in this many pieces, so that one too dear is abandoned early.
CHUNKS = 8


@dataclass
class Run:
    """One serial run: ``scheme`` at fixed step ``dt`` or adaptive within ``rtol`` (first step
    ``dt``); after measuring, its ``error`` at T_s against the reference, its CPU time over T_s
    (``cpu_measured``) and scaled to T (``cpu_seconds``), or ``status`` "blew up"."""

    scheme: str
    dt: float
    rtol: float | None = None
    family: str = ""
    status: str = "pending"  # measured | blew up | abandoned | skipped | reference
    error: float | None = None
    cpu_measured: float | None = None
    cpu_seconds: float | None = None
    note: str = ""

    @property
    def fixed(self) -> bool:
        return self.rtol is None

    @property
    def cost(self) -> float:
        """CPU seconds over T of a measured run (ValueError for one not measured)."""
        if self.cpu_seconds is None:
            raise ValueError(f"{self.label()} was not measured ({self.status})")
        return self.cpu_seconds

    @property
    def accuracy(self) -> float:
        """Its error at T_s of a measured run (ValueError for one not measured)."""
        if self.error is None:
            raise ValueError(f"{self.label()} was not measured ({self.status})")
        return self.error

    def label(self) -> str:
        step = f"rtol = {self.rtol:.3g}" if self.rtol is not None else f"dt = {self.dt:.3g}"
        return f"{self.scheme} at {step}"

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def real_stability_interval(scheme: Any) -> float | None:
    """The stability interval [-Y, 0] of an explicit Runge-Kutta tableau on the negative real
    axis (:func:`parastokes.integrate.schemes.real_stability_boundary`: forward Euler and RK2:
    2, classical RK4: 2.785); None for a scheme without an explicit tableau."""
    if not isinstance(scheme, Scheme) or scheme.implicit:
        return None
    return real_stability_boundary(scheme)


def _auto_available(system: System) -> bool:
    """Whether ``integrate`` offers ``scheme = "auto"`` (added by the stiffness switching)."""
    try:
        integrate.Propagator(system, "auto", 1.0, rtol=1e-6)
    except (ValueError, TypeError):
        return False
    return True


def _round(value: float) -> float:
    return float(f"{value:.3g}")


def candidates(euler_limit: float | None, target: float, span: float,
               schemes: dict[str, Any] | None = None, auto: bool = False) -> list[Run]:
    """The candidate runs of every family (explicit, implicit, adaptive), each family from
    cheap to dear, in the order :func:`by_rank` gives (module docstring); fixed steps keep at
    least :data:`MIN_STEPS` steps over ``span`` (T_s)."""
    schemes = integrate.SCHEMES if schemes is None else schemes
    euler = real_stability_interval(schemes["euler"]) if "euler" in schemes else None
    runs: list[Run] = []
    largest = span / MIN_STEPS
    if euler_limit is not None:
        for name, s in schemes.items():
            interval = real_stability_interval(s)
            if interval is not None and euler and not s.adaptive:  # (a pair: rtol only)
                limit = euler_limit * interval / euler
                runs += [Run(name, _round(min(f * limit, largest)), family=f"{name} fixed")
                         for f in EXPLICIT_FRACTIONS]
        for name, s in schemes.items():
            if s.implicit:
                runs += [Run(name, _round(min(m * euler_limit, largest)), family=f"{name} fixed")
                         for m in IMPLICIT_MULTIPLES]
    first = euler_limit if euler_limit is not None else largest
    adaptive = [name for name, s in schemes.items() if s.adaptive] + (["auto"] if auto else [])
    for name in adaptive:
        runs += [Run(name, _round(min(first, largest)), rtol=_round(f * target),
                     family=f"{name} adaptive") for f in RTOL_FACTORS]
    unique: dict[tuple, Run] = {}
    for run in runs:  # (a step capped at span / MIN_STEPS may repeat)
        unique.setdefault((run.scheme, run.dt, run.rtol), run)
    return by_rank(list(unique.values()))


def by_rank(runs: list[Run]) -> list[Run]:
    """``runs`` (each family from cheap to dear) reordered rank by rank: every family's cheapest
    run, then every family's second, and so on (stable within a rank), so that a search cut by
    its budget has tried every family at its cheapest step before any family's dearer ones."""
    rank: dict[str, int] = {}
    ranked = []
    for run in runs:
        ranked.append((rank.get(run.family, 0), run))
        rank[run.family] = rank.get(run.family, 0) + 1
    return [run for _, run in sorted(ranked, key=lambda pair: pair[0])]


def cheapest(runs: Iterable[Run], target: float, fixed_only: bool = False) -> Run | None:
    """The measured run of least CPU time whose error is at most ``target`` (ties: the first);
    ``fixed_only``: among fixed steps (F of a Parareal run)."""
    reaching = [r for r in runs if r.status in ("measured", "reference")
                and r.accuracy <= target and (r.fixed or not fixed_only)]
    return min(reaching, key=lambda r: r.cost, default=None)


def choose_runs(runs: list[Run], measure: Callable[[Run, float], None], threshold: float,
                over_budget: Callable[[], bool], most: int = MAX_CANDIDATES) -> str | None:
    """Measure ``runs`` in order (``measure(run, cap)`` sets status, error and CPU; it may
    abandon a run whose CPU time passes ``cap``, the cheapest run reaching ``threshold`` so far),
    family by family from cheap to dear: a family stops after its first run reaching
    ``threshold``, or once one of its runs costs more than the cheapest reaching it (a finer one
    costs more still); runs left out are marked "skipped" with the reason. Returns why the
    search stopped early ("budget", "candidates") or None."""
    done: dict[str, str] = {}  # family -> why it stopped
    measured = 0
    for i, run in enumerate(runs):
        if run.family in done:
            run.status, run.note = "skipped", done[run.family]
            continue
        if over_budget() or measured >= most:
            stopped = "budget" if measured < most else "candidates"
            for rest in runs[i:]:
                rest.status = "skipped"
                rest.note = f"search stopped ({stopped})"
            return stopped
        best = cheapest(runs[:i], threshold)
        measure(run, math.inf if best is None else best.cost)
        measured += 1
        if run.status == "abandoned":
            done[run.family] = f"a cheaper run of {run.family} was abandoned: {run.note}"
        elif run.status != "measured":
            continue
        elif run.accuracy <= threshold:
            done[run.family] = f"a cheaper run of {run.family} reaches {threshold:.3g}"
        elif best is not None and run.cost > best.cost:
            done[run.family] = (f"dearer than {best.label()} ({best.cost:.3g} s), "
                                "which reaches it; finer steps cost more")
    return None


@dataclass
class Baseline:
    """What :func:`search` found: the reference (F over T_s, its CPU scaled to T), every run,
    and the interval measured on."""

    key: str
    target: float
    t0: float
    t1: float
    measured_t1: float
    reference: Run
    fine_error: float | None
    euler_limit: float | None
    runs: list[Run]
    budget: float
    spent: float
    stopped: str | None = None
    notes: list[str] = field(default_factory=list)
    #: The configuration's F as a measured row, where the reference is F's scheme at a finer
    #: step (:func:`refinements`); None where the reference is F itself.
    own: Run | None = None

    def best(self, target: float | None = None) -> Run:
        """The fastest run reaching ``target`` (default η*); F itself when none does."""
        goal = self.target if target is None else target
        return cheapest(self.runs, goal) or self.reference

    def fine(self) -> Run:
        """The cheapest fixed-step run with error at most η*/:data:`F_FACTOR`: ``plan``'s F
        (F itself when none is cheaper)."""
        found = cheapest(self.runs, self.target / F_FACTOR, fixed_only=True)
        if found is None or found.cost >= self.reference.cost:
            return self.reference
        return found

    def as_dict(self) -> dict[str, Any]:
        """The cache entry (:func:`parastokes.parareal.best_serial.best_known` reads ``problem``,
        ``target``, ``fine`` and ``rows``)."""
        best = self.best()
        return {
            "problem": self.key, "target": self.target,
            "fine": (self.own or self.reference).as_dict(), "fine_error": self.fine_error,
            "interval": {"t0": self.t0, "t1": self.t1, "measured_t1": self.measured_t1,
                         "cpu_scale": (self.t1 - self.t0) / (self.measured_t1 - self.t0)},
            "euler_limit": self.euler_limit,
            "best_serial": best.as_dict(),
            "rows": [r.as_dict() for r in [self.reference, *self.runs]
                     if r.status in ("measured", "reference")],
            "skipped": [r.as_dict() for r in self.runs if r.status not in ("measured",)],
            "budget": self.budget, "spent": self.spent, "stopped": self.stopped,
            "notes": self.notes,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Baseline:
        """The inverse of :meth:`as_dict` (a cache entry)."""
        rows = [Run(**r) for r in data["rows"]]
        reference = next(r for r in rows if r.status == "reference")
        runs = [r for r in rows if r is not reference] + [Run(**r) for r in data["skipped"]]
        interval = data["interval"]
        fine = Run(**data["fine"])
        own = next((r for r in runs if (r.scheme, r.dt, r.rtol, r.status) ==
                    (fine.scheme, fine.dt, fine.rtol, "measured")), None)
        return cls(data["problem"], float(data["target"]), interval["t0"], interval["t1"],
                   interval["measured_t1"], reference, data["fine_error"], data["euler_limit"],
                   runs, data["budget"], data["spent"], data["stopped"], data["notes"], own)


def refinements(error: float, target: float, order: int) -> int:
    """How many halvings of F's step bring its own ``error`` (Richardson's estimate, falling
    like the step to the scheme's ``order``) to at most η*/(:data:`F_FACTOR` :data:`RESOLUTION`)
    for ``target`` = η*: 0 when it is there already, at most :data:`MOST_HALVINGS`."""
    goal = target / (F_FACTOR * RESOLUTION)
    if not error > goal:
        return 0
    return min(MOST_HALVINGS, math.ceil(math.log2(error / goal) / order))


def search(system: System, x0: np.ndarray, t0: float, t1: float, fine: integrate.Propagator,
           target: float, key: str, budget: float = DEFAULT_BUDGET,
           clock: Callable[[], float] = time.process_time) -> Baseline:
    """Search the fastest serial run reaching ``target`` at ``t1`` (module docstring) within
    ``budget`` CPU seconds; ``fine`` is the configuration's F (the reference), ``key`` the
    problem's fingerprint recorded with the result."""
    notes: list[str] = []
    x0 = np.asarray(x0, dtype=float)
    compile_loops(system, x0, t0, fine, integrate.SCHEMES)
    started = clock()
    probe_steps = max(1, min(50, integrate.n_steps(t0, t1, fine.dt)))
    start = clock()
    integrate.run(system, x0, t0, t0 + probe_steps * fine.dt, fine.scheme, fine.dt,
                  rtol=fine.rtol, atol=fine.atol)
    per_time = max(clock() - start, 1e-9) / (probe_steps * fine.dt)

    def reference_run(step: float) -> tuple[float, np.ndarray, float]:
        """(T_s - t0, the state at T_s, CPU) of F's scheme at ``step`` over the longest span
        whose run costs at most :data:`REFERENCE_SHARE` of the budget."""
        cost = per_time * fine.dt / step
        length = max(min(t1 - t0, REFERENCE_SHARE * budget / cost),
                     min(t1 - t0, probe_steps * fine.dt))
        begin = clock()
        state = integrate.run(system, x0, t0, t0 + length, fine.scheme, step, rtol=fine.rtol,
                              atol=fine.atol).state
        return length, state, clock() - begin

    span, reference_state, reference_cpu = reference_run(fine.dt)
    fine_error, step, own = None, fine.dt, None
    name = integrate.lookup(fine.scheme).name
    if fine.rtol is None:  # Richardson's estimate (as tune's pilot)
        fine_error = own_error(system, x0, t0, t0 + span, fine.scheme, fine.dt, reference_state)
        halvings = refinements(fine_error, target, integrate.scheme_order(fine.scheme))
        if halvings:  # F cannot judge η*/F_FACTOR: its scheme at a finer step is the reference
            step = fine.dt / 2**halvings
            notes.append(f"the configuration's F ({name} at {fine.dt:g}) has its own error "
                         f"{fine_error:.3g}, not {RESOLUTION:g} times below η*/{F_FACTOR:g}: "
                         f"the reference is {name} at {step:g} (F's step / {2**halvings}), F "
                         "a measured row")
            span, reference_state, reference_cpu = reference_run(step)
            fine_error = own_error(system, x0, t0, t0 + span, fine.scheme, step,
                                   reference_state)
            begin = clock()
            state = integrate.run(system, x0, t0, t0 + span, fine.scheme, fine.dt).state
            own = Run(name, fine.dt, None, "F", "measured", relative_change(
                state, reference_state, system.positions), clock() - begin,
                note="the configuration's F")
    else:
        notes.append("F takes adaptive steps: its own error is not estimated")
    measured_t1 = t0 + span
    scale = (t1 - t0) / span
    if own is not None:
        own.cpu_seconds = (own.cpu_measured or 0.0) * scale
    if measured_t1 < t1:
        notes.append(f"errors measured at T_s = {measured_t1:.4g} (the reference run over the "
                     f"whole T = {t1:g} would exceed {REFERENCE_SHARE:.0%} of the budget); CPU "
                     f"times scaled by T/T_s = {scale:.3g}")
    reference = Run(name, step, fine.rtol, "F", "reference",
                    0.0 if fine_error is None else fine_error, reference_cpu,
                    reference_cpu * scale, "the configuration's F (the reference)" if own is None
                    else f"{name} at F's step / {round(fine.dt / step)} (the reference)")
    euler_limit = None
    for lowest in (fine.dt, fine.dt / 10, fine.dt / 100):  # F's step may lie above Euler's limit
        try:
            euler_limit = integrate.largest_stable_step(
                system, "euler", span, lowest, max(span / MIN_STEPS, 2 * lowest), x0=x0, t0=t0,
                rtol=0.05, relative=True)
            break
        except ValueError as error:
            reason = str(error)
    if euler_limit is None:
        notes.append(f"forward Euler's stability limit not found ({reason}): no explicit or "
                     "implicit fixed steps searched")

    def measure(run: Run, cap: float) -> None:
        """The run over T_s in :data:`CHUNKS` pieces, abandoned after the piece that takes its
        CPU time (scaled to T) past ``cap`` or the search past its budget."""
        x, spent, first = x0, 0.0, run.dt
        n = integrate.n_steps(t0, measured_t1, run.dt)
        for k in range(CHUNKS):
            if run.fixed:  # pieces of whole steps: the same steps as one run
                a, b = (k * n) // CHUNKS, ((k + 1) * n) // CHUNKS
                if a == b:
                    continue
                h = span / n
                piece = (t0 + a * h, measured_t1 if b == n else t0 + b * h, h)
            else:
                piece = (t0 + k * span / CHUNKS, t0 + (k + 1) * span / CHUNKS, first)
            begin = clock()
            try:
                result = integrate.run(system, x, piece[0], piece[1], run.scheme, piece[2],
                                       rtol=run.rtol)
            except integrate.BlowUpError as error:
                run.status, run.note = "blew up", str(error)[:160]
                return
            finally:
                spent += clock() - begin
            x, first = result.state, result.dt
            if spent * scale > cap or clock() - started > budget:
                run.status = "abandoned"
                run.note = (f"after {k + 1}/{CHUNKS} of T_s: {spent * scale:.3g} s CPU over T, "
                            + (f"dearer than the cheapest run reaching η*/{F_FACTOR:g} "
                               f"({cap:.3g} s)" if spent * scale > cap else "budget spent"))
                return
        run.cpu_measured = spent
        run.cpu_seconds = spent * scale
        run.error = relative_change(x, reference_state, system.positions)
        run.status = "measured"

    runs = candidates(euler_limit, target, span, auto=_auto_available(system))
    runs = [r for r in runs if (r.scheme, r.dt, r.rtol) != (fine.scheme, fine.dt, fine.rtol)]
    stopped = choose_runs(runs, measure, target / F_FACTOR,
                          lambda: clock() - started > budget)
    if own is not None:
        runs.append(own)
    return Baseline(key, target, t0, t1, measured_t1, reference, fine_error, euler_limit, runs,
                    budget, clock() - started, stopped, notes, own)


def cached(path: str | os.PathLike, key: str, target: float) -> Baseline | None:
    """The search of the cache ``path`` for the problem ``key`` and this very ``target``."""
    for entry in cached_entries(path, key):
        if entry.get("target") == target:
            try:
                return Baseline.from_dict(entry)
            except (KeyError, TypeError, StopIteration):
                return None  # (an entry of another layout: searched again and replaced)
    return None


def store(path: str | os.PathLike, baseline: Baseline, write: Callable | None = None) -> None:
    """Add (or replace) ``baseline`` in the cache ``path``, keyed by problem and target, keeping
    the other entries; written atomically (through ``write(path, writer)`` when given, e.g. a
    staging of several files)."""
    try:
        data = json.loads(open(path).read())
        entries = data["entries"] if isinstance(data.get("entries"), dict) else {}
    except (OSError, ValueError, AttributeError):
        entries = {}
    entries[f"{baseline.key}:{baseline.target!r}"] = baseline.as_dict()
    text = json.dumps({"format": 1, "entries": entries}, indent=1, sort_keys=True).encode()
    (write or atomic_write)(path, lambda handle: handle.write(text))
