"""``parastokes run``, ``demo`` and ``check``: a configuration loaded, checked, and run into
its directory (:func:`parastokes.run.execute`)."""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Sequence

from .console import Console
from .exits import ExitCode


def load(path: str | None, overrides: Sequence[str], text: str | None = None):
    from .. import config

    if text is not None:
        return config.loads(text, "demo configuration", overrides)
    assert path is not None  # the commands give a path or a text
    return config.load(path, overrides)


def run_and_report(
    args: argparse.Namespace, cfg, resolved, console: Console, files: dict[str, str] | None = None
) -> ExitCode:
    from ..run import execute, speedup_table

    for warning in resolved.warnings:
        console.print(f"note: {warning}")
    summary = execute(
        cfg,
        resolved,
        args.out,
        resume=args.resume,
        overwrite=args.overwrite,
        reporter=console,
        files=files,
    )
    if summary["speedup"] is not None:
        from ..config import problem_key
        from ..run.speedups import against_best_serial

        console.print(speedup_table(summary))
        console.print(against_best_serial(summary, getattr(args, "config", None),
                                          problem_key(cfg)))
    monitor = summary["monitor"]
    console.print(
        f"stability monitor: max {monitor['max']:.3g} at the slice boundaries "
        f"(limit {monitor['limit']:g})"
    )
    output = cfg.output
    written = ["summary.json", *(["trajectory.h5/.xdmf"] if output.trajectory else []),
               *(["flow.h5/.xdmf/.png"] if output.trajectory and output.flow_every is not None
                 else []),
               *(["figures"] if output.figures else [])]
    console.print(f"results in {args.out}/ ({', '.join(written)})")
    return ExitCode.OK


def _sets(args: argparse.Namespace) -> list[str]:
    """The ``--set`` overrides with those of the flags (``--monitor-fatal``)."""
    return [*args.set, *(["output.monitor_fatal=true"] if args.monitor_fatal else [])]


def cmd_run(args: argparse.Namespace, console: Console) -> ExitCode:
    cfg, resolved = load(args.config, _sets(args))
    console.print(f"{cfg.title or args.config}")
    return run_and_report(args, cfg, resolved, console)


def _toml(value: object) -> str:
    """A TOML value (the configuration's types: tables, arrays, strings, numbers, booleans)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {_toml(v)}" for k, v in value.items()) + " }"
    if isinstance(value, list):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    return repr(value)


def demo_text(overrides: Sequence[str]) -> str:
    """The demo's configuration file with ``overrides`` applied (the annotated text without)."""
    import tomllib

    from ..config import DEMO, apply_overrides

    if not overrides:
        return DEMO
    data = apply_overrides(tomllib.loads(DEMO), overrides)
    lines = [f"# parastokes demo --set {' --set '.join(overrides)}"]
    lines += [f"{k} = {_toml(v)}" for k, v in data.items() if not isinstance(v, dict)]
    for section, table in data.items():
        if isinstance(table, dict):
            lines += ["", f"[{section}]", *(f"{k} = {_toml(v)}" for k, v in table.items())]
    return "\n".join(lines) + "\n"


def cmd_demo(args: argparse.Namespace, console: Console) -> ExitCode:
    from ..config import DEMO

    cfg, resolved = load(None, _sets(args), text=DEMO)
    console.print(cfg.title)
    status = run_and_report(args, cfg, resolved, console,
                            files={"config.toml": demo_text(args.set)})
    console.print(f"(its configuration is in {args.out}/config.toml; edit it and use `run`)")
    return status


def cmd_check(args: argparse.Namespace, console: Console) -> ExitCode:
    from ..bodies.contract import BodyError
    from ..config import ConfigError, preflight

    status = ExitCode.OK
    for path in args.config:
        try:
            cfg, r = load(path, args.set)
            preflight(cfg, r, path)  # as a run does before its workers start
        except ConfigError as error:
            print(error, file=sys.stderr)
            status = ExitCode.CONFIG
            continue
        except BodyError as error:
            print(f"{path}: {error}", file=sys.stderr)
            status = ExitCode.CONFIG
            continue
        steps = (f"{r.fine_steps} fine steps" if cfg.fine.rtol is None else
                 f"adaptive fine steps (their number set by fine.rtol = {cfg.fine.rtol:g})")
        console.print(
            f"{path}: ok ({cfg.model.kind}, {r.n_points} points"
            f"{'' if math.isnan(r.epsilon) else f', ε⁰ = {r.epsilon:.6g}'}; "
            f"{cfg.parareal.n_slices} slices of {steps}; coarse τ_c = "
            f"{r.coarse_dt:.6g} ({r.coarse_dt / r.fine_dt:.4g} τ_f), N_G = {r.n_auxiliary}, "
            f"Σ|w| = {r.weight_sum:.3g}, workers = {r.workers})"
        )
        for warning in r.warnings:
            console.print(f"  note: {warning}")
    return status
