"""``parastokes predict``: the speedup of eq. 14 predicted for a configuration on given
numbers of cores, from the coarse family's estimate of γ_G/γ_F or a measured run."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

from ..parareal.best_serial import HOW_TO_MEASURE
from .console import Console
from .exits import ExitCode
from .run import load


def estimated_gamma_ratio(cfg, resolved, cores: int) -> float:
    """γ_G/γ_F of one coarse solve with ``cores`` cores, estimated by the coarse-solver family
    (:meth:`parastokes.registry.coarse.CoarseSection.gamma_ratio`; the extrapolated G counts
    rate evaluations times (points)²)."""
    return cfg.coarse.gamma_ratio(cfg, resolved, cores)


def measured_auxiliary_ratio(summary: dict) -> float:
    """γ of one auxiliary solve over γ_F, from a Parareal run's ``summary``: its γ_G is a
    whole coarse step, whose N_G auxiliary solves ran in ceil(N_G / W) rounds on its W workers
    (one worker without an executor); the pipelined schedule records one round already (the
    longest auxiliary solve plus the combination). The combination's share is divided with the
    rounds, a small part of a step."""
    ratio = float(summary["speedup"]["gamma_ratio"])
    if summary["timings"].get("schedule") == "pipelined":
        return ratio
    n_auxiliary = summary["config"]["resolved"]["n_auxiliary"]
    workers = summary.get("workers") or 1
    from ..core.contracts import rounds

    return ratio / rounds(n_auxiliary, workers)


def cmd_predict(args: argparse.Namespace, console: Console) -> ExitCode:
    from .. import parareal
    from ..output import trajectory as io

    bad = [n for n in args.cores if n < 1]
    if bad:
        raise ValueError(f"predict: --cores must be at least 1, got {bad}")
    if args.workers is not None and args.workers < 1:
        raise ValueError(f"predict: --workers must be at least 1, got {args.workers}")
    if args.iterations is not None and args.iterations < 1:
        raise ValueError(f"predict: --iterations must be at least 1, got {args.iterations}")
    if args.case is not None and args.serial is None:
        raise ValueError("predict: --case goes with --serial FILE.json")
    for name, value in (("--ratio", args.ratio), ("--target", args.target)):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise ValueError(f"predict: {name} must be a positive finite number, got {value:g}")
    cfg, resolved = load(args.config, args.set)
    measured = io.read_summary(Path(args.measured) / "summary.json") if args.measured else None
    if measured is not None and not measured.get("speedup"):
        raise ValueError(f"{args.measured} holds no Parareal run")
    against = best_serial(args, cfg, measured)
    iterations = args.iterations or (
        measured["iterations"] if measured else cfg.parareal.max_iterations
    )
    n_aux = resolved.n_auxiliary
    if args.ratio is not None:
        source, auxiliary = "given", args.ratio
    elif measured is not None:
        source = f"measured in {args.measured}"
        auxiliary = measured_auxiliary_ratio(measured)
    else:
        source = f"estimated by the coarse-solver family ({cfg.coarse.kind!r})"
        auxiliary = estimated_gamma_ratio(cfg, resolved, n_aux)  # one auxiliary solve
    workers = "W = N_c" if args.workers is None else f"W = {args.workers}"
    print(
        f"γ_G/γ_F {source} (one auxiliary solve: {auxiliary:.4g}; N_G = {n_aux} in ceil(N_G/W) "
        f"rounds); N_it = {iterations}; {workers} workers; std/pipe: closed formulas, "
        "sim: simulated schedules (docs/parareal.md)"
    )
    print(f"speedups against F ({cfg.fine.scheme} at dt = {cfg.fine.dt:.3g}); "
          + (against[1] if against is not None else
             f"against the fastest serial run of the same accuracy: none measured for this "
             f"problem ({HOW_TO_MEASURE})"))
    print(
        f"{'N_c':>6} {'N_it':>5} {'γ_G/γ_F':>9} {'speedup (eq. 14)':>17} {'bound (eq. 15)':>15}"
        f" {'std':>7} {'std sim':>8} {'pipe':>7} {'pipe sim':>9}"
        + ("" if against is None else f" {'vs best serial':>15}")
    )
    skipped = []
    for n in args.cores:
        (row,) = parareal.predict_schedules(auxiliary, iterations, [n], n_aux, args.workers)
        ((_, theory, bound),) = parareal.predict(row["alpha"], iterations, [n])
        if not row["simulated"]:
            skipped.append(n)
        print(
            f"{n:>6} {row['iterations']:>5} {row['alpha']:>9.4f} {theory:>17.3f} {bound:>15.3f}"
            f" {row['standard_formula']:>7.3f} {row['standard']:>8.3f}"
            f" {row['pipelined_formula']:>7.3f} {row['pipelined']:>9.3f}".replace("nan", "  -")
            + ("" if against is None else f" {theory / against[0]:>15.3f}")
        )
    if skipped:
        from ..parareal.schedule_model import MAX_SIMULATED_TASKS

        print(f"sim -: not simulated for N_c = {', '.join(map(str, skipped))} (more than "
              f"{MAX_SIMULATED_TASKS} tasks); the closed formulas std and pipe hold there")
    return ExitCode.OK


def best_serial(args: argparse.Namespace, cfg: Any, measured: dict | None
                ) -> tuple[float, str] | None:
    """F's CPU time over that of the fastest serial run reaching the target, and the line that
    says which run it is: from ``--serial`` (measured runs of this very problem,
    :mod:`parastokes.parareal.best_serial`), else from the cache beside the configuration that
    ``parastokes plan`` writes; None when neither knows one."""
    from ..config import problem_key
    from ..parareal.best_serial import best_known, cache_path, load_serial_runs

    target = args.target
    if target is None:
        errors = (measured or {}).get("errors") or []
        target = float(errors[-1]) if errors else None
        if target is not None and not (math.isfinite(target) and target > 0):
            if args.serial is None:  # no serial run reaches it; the cache is only consulted
                return None
            raise ValueError(f"predict: the last error η^K of the run in {args.measured} is "
                             f"{target:g}, which no serial run is measured to reach: give "
                             "--target ETA")
    key = problem_key(cfg)
    if args.serial is None:
        known = best_known(cache_path(args.config), key, target)
        if known is None:
            return None
        return known.fine_over, (
            f"against the fastest serial run reaching η* = {known.target:.3g} at T (cached in "
            f"{known.source}): {known.describe()}, {known.fine_over:.3g}x less CPU than F; "
            "vs best serial = eq. 14 over that factor")
    runs = load_serial_runs(args.serial, args.case)
    runs.check_fine(cfg.fine.scheme, cfg.fine.dt, cfg.time.t1 - cfg.time.t0)
    runs.check_problem(key)
    if target is None:
        raise ValueError("predict: --serial needs --target ETA (the accuracy at T of the "
                         "Parareal result), or --measured DIR of a run with a reference")
    best = runs.best(target)
    who = ("F itself (no faster measured run reaches it)" if best is runs.reference else
           f"{best.describe()} (error {best.error:.3g}), {best.fine_over:.3g}x less CPU than F")
    return best.fine_over, (f"against the fastest serial run reaching η* = {target:.3g} at T "
                            f"(case {runs.case!r} of {args.serial}): {who}; vs best serial = "
                            "eq. 14 over that factor")
