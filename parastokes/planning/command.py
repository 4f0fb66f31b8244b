"""``parastokes plan CONFIG --cores N --target ETA --out PLAN.toml``: the route that finishes a
simulation soonest on N cores at accuracy η* (docs/planning.md).

1. the baseline: the fastest serial run reaching η* at T (:mod:`.baseline`), measured on the
   configuration's problem against its F, or reused from the cache beside it
   (CONFIG.best_serial.json);
2. F: the cheapest fixed-step run of that search with error at most η*/F_FACTOR;
3. the coarse solver: ``tune``'s search (:func:`parastokes.tuning.tune`) with that F on N slices,
   to the target (1 - 1/F_FACTOR) η* (F's own error takes the rest);
4. the routes (:mod:`.routes`): serial, spatial, Parareal in both schedules, both combined, in
   one table; the fastest is written as PLAN.toml, with PLAN.json (the record) and
   PLAN.best_serial.json (the baseline, keyed by PLAN.toml's own problem, so that ``run`` and
   ``predict`` of PLAN.toml name it), all three moved into place together.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

from .baseline import DEFAULT_BUDGET, F_FACTOR, RESOLUTION, Baseline, Run

__all__ = ["PlanError", "add_arguments", "main", "plan_config", "prepare", "resolvable"]

#: Share of the budget given to the serial search when the Parareal route is searched too.
SERIAL_SHARE = 0.5

#: Where forward Euler at its stability limit costs more than this fraction of F, no explicit
#: coarse solver can be cheap enough (pipelined at P = 40, K = 2, α = 0.1 gives 6.5; F at its own
#: limit leaves Euler α = 0.3-0.5: docs/benchmarks.md, "The target table"), and ``plan`` adds
#: :data:`IMPLICIT_COARSE` to tune's default schemes.
EXPLICIT_ALPHA = 0.1

#: The implicit coarse scheme that met the rods' targets on the fine grid (docs/benchmarks.md,
#: "What the frontier shows").
IMPLICIT_COARSE = "ros34pw2"


class PlanError(ValueError):
    """Bad input to ``plan``, found before any work (exit 2): the message names what to change."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``parastokes plan``."""
    p.add_argument("config", help="TOML configuration: the problem (model, T) and its F, the "
                   "reference of the accuracy")
    p.add_argument("--cores", type=int, required=True, help="cores N to finish on")
    p.add_argument("--target", type=float, required=True, metavar="ETA",
                   help="target relative error η* at T (eq. 34), in (0, 1)")
    p.add_argument("--out", required=True,
                   help="PLAN.toml to write (PLAN.json and PLAN.best_serial.json beside it)")
    p.add_argument("--budget", type=float, help=f"CPU seconds for the searches (default "
                   f"{DEFAULT_BUDGET:g} for the serial one, tune's default for the coarse one)")
    p.add_argument("--remeasure", action="store_true",
                   help="search the serial baseline again even when the cache holds it")
    p.add_argument("--overwrite", action="store_true",
                   help="replace PLAN.toml, .json and .best_serial.json if they exist")


def check_arguments(args: argparse.Namespace) -> None:
    """The command line, before anything is read (PlanError naming the option)."""
    target = args.target
    if not (math.isfinite(target) and 0.0 < target < 1.0):
        raise PlanError(f"--target: the relative error η* must be a number in (0, 1), got "
                        f"{target:g}")
    if args.cores < 1:
        raise PlanError(f"--cores must be at least 1, got {args.cores}")
    if args.budget is not None and not (math.isfinite(args.budget) and args.budget > 0):
        raise PlanError(f"--budget must be a positive number of CPU seconds, got {args.budget:g}")
    if Path(args.out).suffix.lower() != ".toml":
        raise PlanError(f"--out {args.out}: plan writes a configuration there (and PLAN.json "
                        "beside it): give a name ending in .toml")


def replaceable(cfg: Any) -> None:
    """Refuse (PlanError) a configuration whose F ``plan`` cannot replace or time: the GPU
    executor (its batches run F on the device, whose costs this search, on the CPU, does not
    measure; they also take explicit fixed steps only)."""
    if cfg.execution.executor == "gpu":
        raise PlanError(
            'execution.executor = "gpu": plan measures and compares CPU costs, and the GPU '
            "runs F in device batches of explicit fixed steps it cannot time; plan the "
            "configuration on the CPU (--set execution.executor=\"processes\") and move the "
            "chosen route to the GPU yourself")


def resolvable(found: Baseline) -> None:
    """Refuse (PlanError) a target the reference cannot judge: the reference's own error
    (Richardson's estimate at T_s; the reference is F, or F's scheme at F's step halved up to
    ``baseline.MOST_HALVINGS`` times where F is not accurate enough) must lie at least
    :data:`RESOLUTION` times below η*/F_FACTOR, the accuracy F for Parareal is chosen at."""
    goal = found.target / F_FACTOR
    if found.fine_error is not None and found.fine_error * RESOLUTION > goal:
        raise PlanError(
            f"--target: η*/{F_FACTOR:g} = {goal:.3g} is not {RESOLUTION:g} times above the "
            f"reference's own error (about {found.fine_error:.2g}; {found.reference.label()}, "
            "against which every run is measured): raise --target, or reduce fine.dt (a more "
            "accurate F)")


def cut_short(found: Baseline) -> str | None:
    """The warning for a serial search that stopped (budget or candidate cap) before measuring
    every candidate: its best run may be dearer than the true fastest one, and every speedup
    against it overstated; None when the search ran to its end."""
    if found.stopped is None:
        return None
    left = [r for r in found.runs if r.status == "skipped" and r.note.startswith("search stopped")]
    families = sorted({r.family for r in left})
    return (f"warning: the serial search stopped at its {found.stopped} with {len(left)} "
            f"candidate(s) not measured ({', '.join(families)}): the fastest serial run may be "
            "cheaper than the one found, and the speedups against it overstated; raise --budget")


def outputs(out: str | Path) -> tuple[Path, Path, Path]:
    """PLAN.toml, PLAN.json and PLAN.best_serial.json."""
    from ..parareal.best_serial import cache_path

    toml = Path(out)
    return toml, toml.with_suffix(".json"), cache_path(toml)


def _baseline(args: argparse.Namespace, cfg: Any, system: Any, budget: float,
              console: Any) -> tuple[Baseline, str]:
    """The cached search of this problem and target, or a new one (stored in the cache beside
    the configuration when its folder can be written); with the line that says which."""
    from .. import integrate
    from ..config import problem_key
    from ..parareal.best_serial import cache_path
    from . import baseline

    key = problem_key(cfg)
    cache = cache_path(args.config)
    found = None if args.remeasure else baseline.cached(cache, key, args.target)
    if found is not None:
        return found, f"the serial baseline is cached in {cache} (problem {key}); reused"
    fine = integrate.Propagator(system, cfg.fine.scheme, cfg.fine.dt, rtol=cfg.fine.rtol,
                                atol=cfg.fine.atol)
    console.print(f"searching the fastest serial run reaching η* = {args.target:g} (budget "
                  f"{budget:.3g} s CPU) ...")
    result = baseline.search(system, system.initial_state(), cfg.time.t0, cfg.time.t1, fine,
                             args.target, key, budget)
    try:
        baseline.store(cache, result)
        where = f"measured now and cached in {cache}"
    except OSError as error:
        where = f"measured now (not cached: {error})"
    return result, f"the serial baseline was {where} (problem {key})"


def _fine_config(run: Run) -> dict[str, Any]:
    table: dict[str, Any] = {"scheme": run.scheme, "dt": run.dt}
    if run.rtol is not None:
        table["rtol"] = run.rtol
    return table


def explicit_alpha(found: Baseline, fine: Run) -> float | None:
    """The least γ_G/γ_F an explicit coarse solver can reach here: the measured CPU of forward
    Euler at its largest measured step (the search runs it just below its stability limit) over
    F's, both over T; where the search measured no such run (a full-scale search can spend its
    budget on the reference), F's step over Euler's measured limit over F's evaluations per step
    (F explicit on fixed steps); None where neither is known."""
    from .. import integrate

    euler = [r for r in found.runs if r.scheme == "euler" and r.fixed and r.status == "measured"]
    if euler:
        return max(euler, key=lambda r: r.dt).cost / fine.cost
    scheme = integrate.lookup(fine.scheme)
    if found.euler_limit is None or not fine.fixed or scheme.implicit:
        return None
    return fine.dt / found.euler_limit / scheme.stages


def coarse_schemes(cfg: Any, found: Baseline, fine: Run) -> tuple[tuple[str, ...] | None, str]:
    """The schemes ``tune`` searches and why: the config's ``[tune] schemes`` where given;
    otherwise tune's defaults, with :data:`IMPLICIT_COARSE` added where explicit coarse solvers
    cannot be cheap (:func:`explicit_alpha` above :data:`EXPLICIT_ALPHA`); None: tune's
    defaults."""
    from ..tuning import Space

    if cfg.tune.schemes is not None:
        return None, "the configuration's [tune] schemes"
    alpha = explicit_alpha(found, fine)
    if alpha is None or alpha <= EXPLICIT_ALPHA:
        return None, "tune's default schemes"
    return ((*Space().schemes, IMPLICIT_COARSE),
            f"tune's default schemes and {IMPLICIT_COARSE}: forward Euler at its limit costs "
            f"{alpha:.2g} of F (explicit coarse solvers cannot reach α <= {EXPLICIT_ALPHA:g})")


def pilot_points(cfg: Any, fine: Run, cores: int, budget: float | None
                 ) -> tuple[int | None, str]:
    """Nodes per rod of tune's pilot, and why: the configuration's ``[tune] pilot_points``
    where given; None (the full problem) for a body that is not a rod; else the run's own (the
    full problem) where F over the pilot window fits
    ``coarse.FULL_PILOT_SHARE`` of tune's budget (:func:`.coarse.full_pilot`; tune's default
    budget where none is given, ``BUDGET_FRACTION`` of F), else ``PILOT_POINTS``."""
    from ..tuning.command import PILOT_POINTS
    from ..tuning.search import BUDGET_FRACTION
    from .coarse import FULL_PILOT_SHARE, full_pilot

    if cfg.tune.pilot_points is not None:
        return cfg.tune.pilot_points, "the configuration's [tune] pilot_points"
    points = getattr(cfg.model, "n_points", None)
    if points is None or points <= PILOT_POINTS:
        return None, "the full problem (no shorter pilot)"
    slices = min(cfg.tune.pilot_slices or 3, cores)
    allowed = BUDGET_FRACTION * fine.cost if budget is None else budget
    window = fine.cost * slices / cores
    if full_pilot(fine.cost, cores, slices, allowed):
        return points, (f"the full problem: F over the pilot's {slices} slices costs about "
                        f"{window:.3g} s, at most {FULL_PILOT_SHARE:g} of tune's budget "
                        f"{allowed:.3g} s")
    return PILOT_POINTS, (f"a rod of {PILOT_POINTS} nodes at the run's spacing: F over "
                          f"{slices} slices of the full problem would cost about {window:.3g} "
                          f"s, more than {FULL_PILOT_SHARE:g} of tune's budget {allowed:.3g} s")


def _tune(cfg: Any, resolved: Any, system: Any, fine: Run, cores: int, target: float,
          budget: float | None, schemes: tuple[str, ...] | None = None,
          points: int | None = None) -> tuple[Any, str | None]:
    """tune's search with F = ``fine`` on ``cores`` slices, over ``schemes`` where given (else
    the config's [tune] table or tune's defaults; with :data:`IMPLICIT_COARSE` among them, its
    plain solver's ladder searched first, ``coarse.leading``), on a pilot rod of ``points``
    nodes (default the config's or ``PILOT_POINTS``); (result, None) or (None, why)."""
    from dataclasses import replace

    from .. import integrate
    from ..tuning import TuningError, tune
    from ..tuning.command import PILOT_POINTS, config_space, pilot_system
    from .coarse import leading

    points = points or cfg.tune.pilot_points or PILOT_POINTS
    space = config_space(cfg)
    if schemes is not None:
        space = replace(space, schemes=schemes)
        if IMPLICIT_COARSE in schemes:
            space = replace(space, leading=leading(IMPLICIT_COARSE))
    try:
        result = tune(integrate.Propagator(system, fine.scheme, fine.dt, rtol=fine.rtol),
                      t0=cfg.time.t0, t1=cfg.time.t1, n_slices=cores, cores=cores, target=target,
                      space=space, budget=budget,
                      pilot=pilot_system(cfg, resolved, points),
                      pilot_slices=cfg.tune.pilot_slices)
    except TuningError as error:
        return None, f"tune: {error}"
    if result.chosen is None:
        return None, f"no coarse solver reaches {target:.3g} (tune measured " \
                     f"{len(result.candidates)} candidates)"
    return result, None


def coarse_solvers(tuned: Any, system: Any, fine: Run, cfg: Any, cores: int) -> list[Any]:
    """tune's accepted coarse solvers, ranked by the least predicted wall time of Parareal on
    ``cores`` slices (either schedule) with α measured on the full problem where tune's pilot
    was shortened (:func:`.coarse.full_alpha` over a few steps, then for the first of the
    ranking over a whole slice, :func:`.coarse.confirmed`), else tune's pilot's α (measured on
    the full problem already)."""
    from .. import integrate
    from ..parallel import TaskError
    from .coarse import confirmed, full_alpha, ranked
    from .routes import parareal_wall

    pilot = tuned.pilot
    shown = len(pilot.system.positions(pilot.x0))
    x0 = system.initial_state()
    propagator = integrate.Propagator(system, fine.scheme, fine.dt, rtol=fine.rtol)
    measure = shown < len(system.positions(x0))

    def alpha_of(cand: Any, whole: bool = False) -> tuple[float | None, str, Any]:
        if not measure:
            return cand.gamma_ratio, f"tune's pilot on the full problem ({shown} " \
                                     "points)", None
        span = "a whole slice" if whole else "a few steps"
        try:
            alpha, measured = full_alpha(cand.settings, system, propagator, x0, cfg.time.t0,
                                         pilot.slice_length, cores, whole=whole)
        except (integrate.BlowUpError, TaskError) as error:
            return None, f"blew up on the full problem over {span} ({error})", None
        return alpha, (f"measured on the full problem ({len(system.positions(x0))} points: G "
                       f"over {measured['coarse_span']:.3g} s ({span}), F over "
                       f"{measured['fine_span']:.3g} s; tune's pilot of {shown} points "
                       f"gave {cand.gamma_ratio:.3g})"), measured

    def wall(alpha: float, k: int) -> float:
        return min(parareal_wall(1.0, alpha, k, cores, s) for s in ("standard", "pipelined"))

    accepted = [c for c in tuned.candidates if c.status == "accepted"]
    rows = ranked(accepted, alpha_of, wall)
    if not measure:
        return rows
    return confirmed(rows, lambda row: alpha_of(row.candidate, whole=True), wall)


def rests_on(coarse: Any, pilot: Any, fine: Run) -> str:
    """What a Parareal row rests on: where its α was measured (:class:`.coarse.Coarse`'s
    ``alpha_source``), the pilot η^k its K comes from with the pilot's points and slices, G
    and F."""
    points = len(pilot.system.positions(pilot.x0))
    errors = ", ".join(f"{e:.2g}" for e in coarse.candidate.pilot_errors)
    return (f"α {coarse.alpha_source}; K from tune's pilot η^k = {errors} ({points} points, "
            f"{pilot.n_slices} slices) scaled to the run's slices; G = "
            f"{coarse.settings.label()} at {coarse.settings.coarse_dt:.3g} s; F = "
            f"{fine.label()} ({fine.cost:.4g} s)")


def _parareal_at(coarse: Any, pilot_slices: int, cores: int, target: float):
    """(α, K) of the coarse solver ``coarse`` (:class:`.coarse.Coarse`) on P slices: K from the
    pilot's η^k scaled to P slices (:func:`parastokes.tuning.cost.predicted_iterations`), α
    with its N_G auxiliary solves in ceil(N_G / P) rounds instead of ceil(N_G / N)."""
    from ..core.contracts import rounds
    from ..tuning import cost

    chosen = coarse.candidate
    n_aux = chosen.settings.n_auxiliary

    def at(slices: int) -> tuple[float, int] | None:
        k = cost.predicted_iterations(chosen.pilot_errors, pilot_slices, slices,
                                      target, chosen.contraction)
        if k is None:
            return None
        return coarse.alpha * rounds(n_aux, slices) / rounds(n_aux, cores), k

    return at


def plan_config(cfg: Any, route: Any, fine: Run, best: Run, coarse: Any) -> dict[str, Any]:
    """The configuration of the chosen route (a dict of TOML tables); ``coarse`` the coarse
    solver's settings of a Parareal route (``tuning.Settings``; None for the others)."""
    data = {k: v for k, v in cfg.model_dump(mode="json", exclude_none=True).items()
            if k not in ("model", "tune")} | cfg.model.tables()
    settings = route.settings
    execution = {k: v for k, v in data.get("execution", {}).items()
                 if k not in ("workers", "allow_oversubscribe")}
    output = {k: v for k, v in data.get("output", {}).items() if k != "every"}
    if "slices" not in settings:  # serial or spatial: the best serial run, on its threads
        data["fine"] = _fine_config(best)
        data["run"] = {"mode": "serial"}
        execution = {"executor": "serial", "threads": settings["threads"]}
    else:
        data["fine"] = _fine_config(fine)
        data["coarse"] = coarse.coarse_table()
        data["parareal"] = {**data["parareal"], "n_slices": settings["slices"],
                            "max_iterations": settings["iterations"],
                            "schedule": settings["schedule"], "tol": 0.0}
        data["run"] = {"mode": "parareal"}
        execution["threads"] = settings["threads"]
        if execution.get("executor", "processes") == "processes":
            execution["workers"] = settings["slices"]
        if coarse.n_auxiliary > settings["slices"]:
            execution["allow_oversubscribe"] = True
    data["execution"] = execution
    data["output"] = output
    return data


def prepare(args: argparse.Namespace) -> tuple[Any, Any]:
    """Every check made before any work: the options, the files to write, the configuration
    (loaded and validated) and whether its F can be replaced; returns (cfg, resolved)."""
    from .. import config as configuration
    from ..output import rundir

    check_arguments(args)
    try:
        rundir.check_files(list(outputs(args.out)), overwrite=args.overwrite)
    except rundir.RunDirectoryError as error:
        raise PlanError(str(error)) from None
    cfg, resolved = configuration.load(args.config, args.set)
    replaceable(cfg)
    return cfg, resolved


def main(args: argparse.Namespace, console: Any) -> int:
    """Run the command (module docstring); 0 when PLAN.toml was written."""
    from .. import config as configuration
    from ..config import problem_key
    from ..output import rundir
    from ..tuning.report import toml_dumps
    from . import routes as routing

    cfg, resolved = prepare(args)
    toml, record, cache = outputs(args.out)
    system = cfg.model.build(1)  # one kernel thread: the serial baseline on one core
    points = len(system.positions(system.initial_state()))
    parareal_possible = args.cores >= 2
    serial_budget = DEFAULT_BUDGET if args.budget is None else (
        args.budget * (SERIAL_SHARE if parareal_possible else 1.0))
    found, which = _baseline(args, cfg, system, serial_budget, console)
    console.print(which)
    resolvable(found)
    best, fine = found.best(), found.fine()
    console.print(f"fastest serial run reaching η* = {args.target:g}: {best.label()} (error "
                  f"{best.error:.3g}, {best.cost:.4g} s CPU over T)")
    console.print(f"F for Parareal (error <= η*/{F_FACTOR:g}): {fine.label()} (error "
                  f"{fine.error:.3g}, {fine.cost:.4g} s CPU over T)")
    cut = cut_short(found)
    if cut is not None:
        console.print(cut)
    best_text = f"{best.label()} ({best.cost:.4g} s)"
    rows = [routing.serial_route(best.cost, best_text)]
    unavailable: dict[str, str] = {}
    tuned, ranking, coarse, why_pilot = None, [], None, None
    if args.cores >= 2:
        rows.append(routing.spatial_route(best.cost, best_text, args.cores, points))
        goal = (1.0 - 1.0 / F_FACTOR) * args.target
        tune_budget = None if args.budget is None else args.budget * (1.0 - SERIAL_SHARE)
        schemes, searched = coarse_schemes(cfg, found, fine)
        console.print(f"tuning the coarse solver for F = {fine.label()} on {args.cores} slices "
                      f"to η^K <= {goal:.3g} ({searched}) ...")
        pilot, why_pilot = pilot_points(cfg, fine, args.cores, tune_budget)
        console.print(f"tune's pilot: {why_pilot}")
        tuned, why = _tune(cfg, resolved, system, fine, args.cores, goal, tune_budget, schemes,
                           pilot)
        if tuned is None:
            unavailable["parareal"] = why or "tune found no coarse solver"
        else:
            ranking = coarse_solvers(tuned, system, fine, cfg, args.cores)
            coarse = ranking[0]
            if coarse.alpha is None:
                unavailable["parareal"] = ("every coarse solver tune accepted on its pilot blew "
                                           f"up on the full problem (first: "
                                           f"{coarse.alpha_source})")
        if "parareal" not in unavailable:
            assert coarse is not None and tuned is not None
            evidence = rests_on(coarse, tuned.pilot, fine)
            for schedule in ("standard", "pipelined"):
                rows.append(routing.parareal_route(
                    best.cost, fine.cost, coarse.alpha, coarse.iterations,
                    args.cores, schedule, evidence))
            at = _parareal_at(coarse, tuned.pilot.n_slices, args.cores, goal)
            combined = routing.combined_route(best.cost, fine.cost, args.cores,
                                              points, "pipelined", at, evidence)
            if combined is None:
                unavailable["combined"] = (f"no split of {args.cores} cores into P >= 2 slices "
                                           "of t >= 2 threads reaches η*")
            else:
                rows.append(combined)
    chosen_route = min(rows, key=lambda r: r.predicted_wall_seconds)
    console.print(routing.table(rows, chosen_route.route))
    for route, why in unavailable.items():
        console.print(f"  {route}: not available ({why})")
    plan = {
        "config": str(args.config), "cores": args.cores, "target": args.target,
        "best_serial": {**{k: getattr(best, k) for k in ("scheme", "dt", "rtol", "error",
                                                          "cpu_seconds")},
                        "source": which, "complete": cut is None, "warning": cut},
        "fine": {k: getattr(fine, k) for k in ("scheme", "dt", "rtol", "error", "cpu_seconds")},
        "routes": [r.as_dict() for r in rows],
        "unavailable": unavailable,
        "chosen": chosen_route.route,
        "baseline": found.as_dict(),
        "tune": None if tuned is None else tuned.report,
        "coarse": None if tuned is None else {
            "pilot_points": len(tuned.pilot.system.positions(tuned.pilot.x0)),
            "pilot": why_pilot,
            "ranked": [row.as_dict() for row in ranking]},
    }
    data = plan_config(cfg, chosen_route, fine, best,
                       None if "parareal" in unavailable or coarse is None else coarse.settings)
    header = (f"Planned by `parastokes plan {args.config} --cores {args.cores} --target "
              f"{args.target:g}`: route {chosen_route.route}, predicted "
              f"{chosen_route.predicted_wall_seconds:.4g} s, "
              f"{chosen_route.speedup_vs_best_serial:.3g}x the fastest serial run "
              f"({best.label()}); see {record.name}")
    text = toml_dumps(data, header)
    planned, _ = configuration.loads(text, str(toml))  # (what check and run will read)
    with rundir.claim_files([toml, record, cache], overwrite=args.overwrite) as staging:
        _write(staging, toml, record, cache, text.encode(), plan,
               _rekeyed(found, problem_key(planned), data["fine"]))
    console.print(f"chosen: {chosen_route.route}; wrote {toml}, {record}, {cache.name}")
    sys.stdout.flush()
    return 0


def _write(staging: Any, toml: Path, record: Path, cache: Path, text: bytes,
           plan: dict[str, Any], planned: Baseline) -> None:
    """PLAN.json, PLAN.best_serial.json (the baseline under PLAN.toml's own problem) and
    PLAN.toml through one staging: moved into place together, or none of them."""
    from ..output import trajectory as io
    from .baseline import store

    io.write_summary(record, plan, staging)
    store(cache, planned, staging.write)
    staging.write(toml, lambda handle: handle.write(text))


def _rekeyed(found: Baseline, key: str, fine: dict[str, Any]) -> Baseline:
    """The baseline under PLAN.toml's problem ``key``, whose F is ``fine`` (the [fine] table
    written): that run becomes the reference row (its CPU time is F's in ``best_known``), the
    configuration's F an ordinary measured row."""
    from dataclasses import replace

    every = [replace(found.reference, status="measured"), *found.runs]
    same = [r for r in every if (r.scheme, r.dt, r.rtol) == (fine["scheme"], fine["dt"],
                                                               fine.get("rtol"))]
    reference = same[0] if same else every[0]
    return replace(found, key=key, reference=replace(reference, status="reference"),
                   runs=[r for r in every if r is not reference])
