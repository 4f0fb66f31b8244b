"""``parastokes tune CONFIG.toml --cores N --target ETA --out TUNED.toml``: the command over
:func:`~.search.tune` (the CLI's ``tune`` subcommand calls :func:`main`; the heavy imports wait
until it runs, so that building the parser stays cheap).

It loads and validates the configuration, builds the run's fine solver and, for rods longer than
``pilot_points`` nodes, a shortened pilot rod at the same grid spacing (the step limits do not
depend on the rod's length, docs/validation.md), runs the search with a tqdm bar on a terminal,
and writes TUNED.toml, TUNED.json and TUNED.png (predicted speedup against the target error).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

__all__ = ["PILOT_POINTS", "add_arguments", "command_line", "config_space", "main", "outputs",
           "pilot_system"]

#: Nodes per rod of the pilot rod when the run's rod is longer (the quick variants' 61).
PILOT_POINTS = 61


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``parastokes tune``."""
    p.add_argument("config", help="TOML configuration (its [coarse] is replaced)")
    p.add_argument("--cores", type=int, required=True, help="cores N_c (= slices of the run)")
    p.add_argument("--target", type=float, required=True, help="target relative error η* (eq. 34)")
    p.add_argument("--out", required=True, help="TUNED.toml to write (TUNED.json, .png beside it)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace TUNED.toml, .json and .png if they exist (else refused)")
    p.add_argument("--budget", type=float, help="wall-time limit of the search in seconds")
    p.add_argument("--schemes", nargs="+", help="schemes of the auxiliary solvers")
    p.add_argument("--parameters", nargs="*", help="parameters to extrapolate in (none: [])")
    p.add_argument("--reach", type=int, nargs="+", help="node distance levels 0 1 2")
    p.add_argument("--nodes", type=int, nargs="+", help="node counts of the first parameter")
    p.add_argument("--richardson", type=int, nargs="+", help="Richardson depths m")
    p.add_argument("--grid-factors", type=int, nargs="+", help="coarse-grid factors (rods)")
    p.add_argument("--step-fractions", type=float, nargs="+", help="fractions of the safe step")
    p.add_argument("--coarse-rtols", type=float, nargs="+",
                   help="rtol ladder of the adaptive candidates (schemes with an error "
                        "estimate, and auto; default 1e-2 1e-3 1e-4)")
    p.add_argument("--pilot-slices", type=int,
                   help="slices of the pilot window (default 3; 2 when the budget is tight)")
    p.add_argument("--pilot-points", type=int, help="rods: nodes per pilot rod (default 61)")
    p.add_argument("--exhaustive", action="store_true",
                   help="measure every candidate (no pruning; slow, for checking the pruning)")
    p.add_argument("--compare", nargs="+", default=[], metavar="CONFIG",
                   help="configurations whose coarse solvers are measured too (never pruned)")


class _Bar:
    """The search's progress (``search.Progress``) on the console, with a tqdm bar on a
    terminal."""

    def __init__(self, console: Any) -> None:
        self.console = console
        self.bar = None

    def note(self, text: str) -> None:
        self.console.print(text)

    def start(self, total: int) -> None:
        self.console.print(f"searching {total} candidates ...")
        if self.console.bars:
            from tqdm import tqdm

            self.bar = tqdm(total=total, desc="tune", unit="candidate", leave=False,
                            file=sys.stderr)

    def advance(self, label: str) -> None:
        if self.bar is not None:
            self.bar.set_postfix_str(label[:40])
            self.bar.update()

    def finish(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None


def pilot_system(cfg: Any, resolved: Any, points: int) -> Any:
    """The run's system, or for a longer rod the same rods shortened to ``points`` nodes."""
    from .. import config as configuration
    from ..config.schema import RodModel

    model = cfg.model
    if not isinstance(model, RodModel) or model.n_points <= points:
        return None
    spacing = model.length / (model.n_points - 1)
    short = model.model_copy(update={"n_points": points, "length": spacing * (points - 1)})
    return configuration.build_system(cfg.model_copy(update={"model": short}), resolved)


def _given(*values: Any) -> Any:
    """The first value that is not None (the command line, then the config, then a default)."""
    return next((value for value in values if value is not None), None)


def config_space(cfg: Any) -> Any:
    """The search space of the config's [tune] table (the tuner's defaults where it is silent)."""
    from .space import parse_space

    return parse_space({k: v for k, v in cfg.tune.model_dump().items()
                        if k not in ("pilot_slices", "pilot_points")})


def _space(cfg: Any, args: argparse.Namespace, compare: tuple) -> Any:
    """The config's [tune] table, narrowed further by the command line; ``compare`` added."""
    from .space import parse_space

    flags = {
        "schemes": args.schemes, "parameters": args.parameters, "reach": args.reach,
        "nodes": args.nodes, "richardson": args.richardson, "grid_factors": args.grid_factors,
        "step_fractions": args.step_fractions, "coarse_rtols": args.coarse_rtols,
    }
    return replace(parse_space(flags, config_space(cfg)), extra=compare)


#: The options of ``tune`` that TUNED.toml's header records, in the order they are written.
_RECORDED = ("cores", "target", "budget", "schemes", "parameters", "reach", "nodes",
             "richardson", "grid_factors", "step_fractions", "coarse_rtols", "pilot_slices",
             "pilot_points", "exhaustive", "compare", "set")


def command_line(args: argparse.Namespace) -> str:
    """The ``parastokes tune`` command that ``args`` stand for, every option given (not
    ``--out`` and ``--overwrite``, which say where, not what): TUNED.toml's header."""
    words = ["parastokes", "tune", str(args.config)]
    for name in _RECORDED:
        value = getattr(args, name, None)
        flag = "--" + name.replace("_", "-")
        if value is None or value is False or (name in ("compare", "set") and not value):
            continue
        if value is True:
            words.append(flag)
        elif name == "set":
            words += [item for key in value for item in ("--set", str(key))]
        elif isinstance(value, list):
            words += [flag, *map(str, value)] if value else [flag]  # (--parameters: none)
        else:
            words += [flag, f"{value:g}" if isinstance(value, float) else str(value)]
    return " ".join(words)


def outputs(out: str | Path, overwrite: bool) -> tuple[Path, Path, Path]:
    """The three files ``tune`` writes (TUNED.toml, its .json record and its .png figure),
    checked before the search: distinct (``--out`` must not end in .json or .png), and as every
    command's files are (:func:`parastokes.output.rundir.check_files`): not a directory, in a
    directory that can be written, none of them an existing file unless ``overwrite``, none a run's
    own file even then; a TuningError (exit 2) says what to change."""
    from ..output import rundir
    from .space import TuningError

    toml = Path(out)
    record, figure = toml.with_suffix(".json"), toml.with_suffix(".png")
    if toml.suffix.lower() in (".json", ".png"):
        raise TuningError(f"--out {toml}: tune writes the configuration there and its record and "
                          f"figure beside it ({record.name}, {figure.name}), so it must not end "
                          f"in {toml.suffix}: give a name such as {toml.with_suffix('.toml')}")
    try:
        rundir.check_files([toml, record, figure], overwrite=overwrite)
    except rundir.RunDirectoryError as error:
        raise TuningError(str(error)) from None
    return toml, record, figure


def main(args: argparse.Namespace, console: Any) -> int:
    """Run the command; returns 0, or 130, 143, 129 when Ctrl-C, SIGTERM or SIGHUP stopped the
    search (what was measured is written)."""
    from .. import config as configuration
    from .. import integrate
    from ..output import rundir
    from ..output import trajectory as io
    from .report import config_text, draw_curves
    from .search import tune
    from .space import TuningError, settings_from_config

    if args.cores < 2:
        raise TuningError(f"--cores must be at least 2 (one slice per core; Parareal needs two "
                          f"slices), got {args.cores}")
    overwrite = getattr(args, "overwrite", False)
    out, record, figure = outputs(args.out, overwrite)
    cfg, resolved = configuration.load(args.config, args.set)
    pilot_slices = _given(args.pilot_slices, cfg.tune.pilot_slices)
    points = _given(args.pilot_points, cfg.tune.pilot_points, PILOT_POINTS)
    if pilot_slices is not None and pilot_slices < 2:
        raise TuningError(f"--pilot-slices must be at least 2, got {pilot_slices}")
    if points < 3:
        raise TuningError(f"--pilot-points must be at least 3 (nodes of the pilot rod), got "
                          f"{points}")
    compare = []
    for path in args.compare:
        other, other_resolved = configuration.load(path)
        compare.append(settings_from_config(other, other_resolved, name=Path(path).stem))
    space = _space(cfg, args, tuple(compare))
    system = configuration.build_system(cfg, resolved)
    pilot = pilot_system(cfg, resolved, points)
    fine = integrate.Propagator(system, cfg.fine.scheme, cfg.fine.dt, rtol=cfg.fine.rtol,
                                atol=cfg.fine.atol)
    console.print(f"tuning {cfg.title or args.config}: {args.cores} cores, η* = {args.target:g}")
    if cfg.coarse.kind != "extrapolated":
        console.print(f"note: tune searches extrapolated coarse solvers only; this configuration's "
                      f"[coarse] family {cfg.coarse.kind!r} is not searched, only compared with "
                      "what is found through `parastokes predict` (docs/tuning.md)")
    if pilot is not None:
        from ..kinds.rod.kind import RodModel

        assert isinstance(cfg.model, RodModel)  # only rods have a pilot (pilot_system)
        console.print(f"pilot rod: {points} nodes per rod at the run's spacing σ_f (the run has "
                      f"{cfg.model.n_points})")
    bar = _Bar(console)
    with rundir.claim_files([out, record, figure], overwrite=overwrite) as staging:
        try:
            result = tune(
                fine, t0=cfg.time.t0, t1=cfg.time.t1, n_slices=args.cores, cores=args.cores,
                target=args.target, space=space, budget=args.budget, pilot=pilot,
                pilot_slices=pilot_slices, progress=bar, exhaustive=args.exhaustive,
            )
        except KeyboardInterrupt:  # before the search (Ctrl-C during it is handled by tune)
            bar.finish()
            print("interrupted before the search began (pilot reference or baseline): nothing "
                  "was written", file=sys.stderr)
            return 130
        report = result.report
        report["config"] = str(args.config)
        report["against_best_serial"] = _against_best_serial(args, cfg, report)
        io.write_summary(record, report, staging)
        draw_curves(result, figure, args.cores, staging=staging)
        if result.chosen is not None:
            dumped = {k: v for k, v in cfg.model_dump(mode="json", exclude_none=True).items()
                      if k != "model"} | cfg.model.tables()
            text = config_text(dumped, result, args.cores, args.config,
                               command_line(args)).encode()
            staging.write(out, lambda handle: handle.write(text))
    _print_report(console, report)
    if result.chosen is None:
        raise TuningError(f"no candidate is stable and reaches η* = {args.target:g}; see "
                          f"{record} (raise --target or widen the search)")
    console.print(f"wrote {out}, {record}, {figure}")
    return {"interrupted": 130, "terminated": 143, "hung up": 129}.get(
        report["search"]["stopped"], 0)


def _against_best_serial(args: argparse.Namespace, cfg: Any, report: dict[str, Any]
                         ) -> dict[str, Any]:
    """What the speedups are against: F, and the fastest serial run reaching η* when the cache
    beside the configuration knows one (``parastokes plan``), with the chosen solver's predicted
    speedup against it; ``line`` says it (or how to measure it)."""
    from ..config import problem_key
    from ..parareal.best_serial import HOW_TO_MEASURE, best_known, cache_path

    fine = report["problem"]["fine"]
    against_f = f"speedups against F ({fine['scheme']} at dt = {fine['dt']:.3g})"
    known = best_known(cache_path(args.config), problem_key(cfg), args.target)
    if known is None:
        return {"known": None, "line": f"{against_f}; against the fastest serial run of the "
                f"same accuracy: none measured for this problem ({HOW_TO_MEASURE})"}
    chosen = report["chosen"]
    value = None if chosen is None else chosen["predicted"]["speedup"] / known.fine_over
    return {"known": {**known.row, "fine_cpu_seconds": known.fine_cpu, "source": known.source},
            "speedup": value,
            "line": f"{against_f}; against the fastest serial run reaching η*, "
                    f"{known.describe()} (cached in {known.source}), F takes "
                    f"{known.fine_over:.3g}x its CPU" + (
                        "" if value is None else f": the chosen solver's {value:.3g}")}


def _print_report(console: Any, report: dict[str, Any]) -> None:
    """The search's table, how it ended and what it cost."""
    from .report import table

    console.print(table(report))
    console.print(report["against_best_serial"]["line"])
    search = report["search"]
    if search["stopped"]:
        console.print(f"search stopped ({search['stopped']}) after {search['evaluated']} of "
                      f"{search['ordered']} candidates; what was measured is kept")
    cost = report["cost"]
    console.print(f"tuning took {cost['seconds']:.1f} s ({cost['cpu_seconds']:.1f} s CPU = "
                  f"{cost['fraction']:.1%} of the estimated serial fine solve, "
                  f"{cost['serial_fine_estimate']:.3g} s CPU)")
    console.print(report["extrapolation"]["note"])
    if report.get("caution"):
        console.print(report["caution"])
