"""The ``parastokes`` command line (docs/tutorial.md).

::

    parastokes run CONFIG.toml --out DIR [--resume] [--set KEY=VALUE ...]
    parastokes demo --out DIR [--resume] [--set KEY=VALUE ...]
    parastokes plot DIR [DIR ...] [--out FIGDIR] [--formats png pdf]
    parastokes plot --benchmark FILE.json [--out FIGDIR] [--formats png pdf]
    parastokes check CONFIG.toml [CONFIG.toml ...] [--set KEY=VALUE ...]
    parastokes predict CONFIG.toml --cores N [N ...] [--ratio R | --measured DIR] [--iterations K]
    parastokes tune CONFIG.toml --cores N --target ETA --out TUNED.toml [--budget SECONDS]

Exit codes (:class:`ExitCode`): 0 success; 1 unexpected error (a bug: please report the
traceback); 2 bad configuration or usage; 3 numerical blow-up (a step too large for the problem:
the message names time, step and monitor); 4 worker or parallel failure (a worker died or raised;
rerun with ``--resume`` to continue from the last completed iteration); 130 interrupted (Ctrl-C;
the checkpoint is consistent, ``--resume`` continues).

Progress bars (tqdm) are drawn only when stderr is a terminal, only by the manager (rank 0 of an
MPI launch) and never with ``--quiet``; ``--quiet`` also silences the tables (errors still go to
stderr).
"""

from __future__ import annotations

import argparse
import enum
import logging
import math
import os
import sys
from collections.abc import Sequence
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

__all__ = ["ExitCode", "main"]

logger = logging.getLogger("parastokes")

#: Environment variables that carry the rank of an MPI process (MPICH/Intel MPI, Open MPI, PMIx).
_RANK_VARIABLES = ("PMI_RANK", "OMPI_COMM_WORLD_RANK", "PMIX_RANK")


class ExitCode(enum.IntEnum):
    """Exit statuses of ``parastokes`` that scripts can rely on."""

    OK = 0
    UNEXPECTED = 1
    CONFIG = 2
    BLOWUP = 3
    PARALLEL = 4
    INTERRUPTED = 130


def is_manager() -> bool:
    """False on the non-root ranks of an MPI launch (read from the launcher's environment)."""
    return all(os.environ.get(name, "0") == "0" for name in _RANK_VARIABLES)


def _causes(error: BaseException):
    """The error, what it wraps (``TaskError.original``) and its chained causes."""
    seen: set[int] = set()
    stack = [error]
    while stack:
        item = stack.pop()
        if item is None or id(item) in seen:
            continue
        seen.add(id(item))
        yield item
        stack += [getattr(item, "original", None), item.__cause__, item.__context__]


def exit_code(error: BaseException) -> ExitCode:
    """The exit status for an error that ended a command."""
    from .config import ConfigError
    from .integrate import BlowUpError
    from .parallel import TaskError

    causes = list(_causes(error))
    if any(isinstance(e, KeyboardInterrupt) for e in causes):
        return ExitCode.INTERRUPTED
    if any(isinstance(e, BlowUpError) for e in causes):
        return ExitCode.BLOWUP
    if isinstance(error, ConfigError):
        return ExitCode.CONFIG
    if any(isinstance(e, TaskError | BrokenProcessPool) for e in causes):
        return ExitCode.PARALLEL
    if isinstance(error, ValueError | FileNotFoundError | ImportError):
        return ExitCode.CONFIG
    return ExitCode.UNEXPECTED


# ---- console output --------------------------------------------------------------------------
class Console:
    """Prints notes and the per-iteration table; draws tqdm bars on a terminal (manager only)."""

    def __init__(self, quiet: bool) -> None:
        self.quiet = quiet
        self.bars = not quiet and is_manager() and sys.stderr.isatty()
        self._bar = None

    def print(self, text: str = "") -> None:
        if self.quiet:
            return
        if self._bar is not None:
            self._bar.write(text)
        else:
            print(text, flush=True)

    # the interface of runner.Reporter
    def note(self, text: str) -> None:
        self.print(text)

    def start(self, what: str, total: int) -> None:
        if what == "parareal":
            self.print(f"{'k':>3}  {'increment η̃^k':>14}  {'error η^k':>10}  {'elapsed [s]':>11}")
        else:
            self.print(f"serial fine run over {total} slices ...")
        if self.bars:
            from tqdm import tqdm

            unit = "slice" if what == "serial" else "iteration"
            self._bar = tqdm(total=total, desc=what, unit=unit, leave=False, file=sys.stderr)

    def advance(self) -> None:
        if self._bar is not None:
            self._bar.update()

    def finish(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def iteration(self, k: int, increment: float, error: float | None, elapsed: float) -> None:
        err = "-" if error is None else f"{error:.3e}"
        self.print(f"{k:>3}  {increment:>14.3e}  {err:>10}  {elapsed:>11.2f}")


# ---- commands --------------------------------------------------------------------------------
def _load(path: str | None, overrides: Sequence[str], text: str | None = None):
    from . import config

    if text is not None:
        return config.loads(text, "demo configuration", overrides)
    return config.load(path, overrides)


def _execute(args: argparse.Namespace, cfg, resolved, console: Console) -> ExitCode:
    from . import runner

    for warning in resolved.warnings:
        console.print(f"note: {warning}")
    summary = runner.execute(cfg, resolved, args.out, resume=args.resume, reporter=console)
    if summary["speedup"] is not None:
        console.print(runner.speedup_table(summary))
    monitor = summary["monitor"]
    console.print(
        f"stability monitor: max {monitor['max']:.3g} at the slice boundaries "
        f"(limit {monitor['limit']:g})"
    )
    console.print(f"results in {args.out}/ (summary.json, trajectory.h5/.xdmf, figures)")
    return ExitCode.OK


def cmd_run(args: argparse.Namespace, console: Console) -> ExitCode:
    cfg, resolved = _load(args.config, args.set)
    console.print(f"{cfg.title or args.config}")
    return _execute(args, cfg, resolved, console)


def cmd_demo(args: argparse.Namespace, console: Console) -> ExitCode:
    from .config import DEMO

    cfg, resolved = _load(None, args.set, text=DEMO)
    Path(args.out).mkdir(parents=True, exist_ok=True)
    (Path(args.out) / "config.toml").write_text(DEMO, encoding="utf-8")
    console.print(cfg.title)
    console.print(f"(configuration written to {args.out}/config.toml; edit it and use `run`)")
    return _execute(args, cfg, resolved, console)


def cmd_check(args: argparse.Namespace, console: Console) -> ExitCode:
    from .config import ConfigError

    status = ExitCode.OK
    for path in args.config:
        try:
            cfg, r = _load(path, args.set)
        except ConfigError as error:
            print(error, file=sys.stderr)
            status = ExitCode.CONFIG
            continue
        console.print(
            f"{path}: ok ({cfg.model.kind}, {r.n_points} points, ε⁰ = {r.epsilon:.6g}; "
            f"{cfg.parareal.n_slices} slices of {r.fine_steps} fine steps; coarse τ_c = "
            f"{r.coarse_dt:.6g} ({r.coarse_dt / r.fine_dt:.4g} τ_f), N_G = {r.n_auxiliary}, "
            f"workers = {r.workers})"
        )
        for warning in r.warnings:
            console.print(f"  note: {warning}")
    return status


def estimated_gamma_ratio(cfg, resolved, cores: int) -> float:
    """γ_G/γ_F from operation counts: rate evaluations per slice times (points)² (the O(N²)
    Stokeslet sums dominate), with the N_G auxiliary solvers in ceil(N_G / cores) waves."""
    from .integrate import SCHEMES

    fine = resolved.fine_steps * SCHEMES[cfg.fine.scheme].stages * resolved.n_points**2
    slowest = max(resolved.coarse_steps) * SCHEMES[cfg.coarse.scheme].stages
    waves = math.ceil(resolved.n_auxiliary / cores)
    return waves * slowest * resolved.coarse_points**2 / fine


def cmd_predict(args: argparse.Namespace, console: Console) -> ExitCode:
    from . import io, parareal

    cfg, resolved = _load(args.config, args.set)
    measured = io.read_summary(Path(args.measured) / "summary.json") if args.measured else None
    if measured is not None and not measured.get("speedup"):
        raise ValueError(f"{args.measured} holds no Parareal run")
    iterations = args.iterations or (
        measured["iterations"] if measured else cfg.parareal.max_iterations
    )
    if args.ratio is not None:
        source = "given"
    elif measured is not None:
        source = f"measured in {args.measured}"
    else:
        source = "estimated from step counts and (points)², N_G in ceil(N_G/N_c) waves"
    print(f"γ_G/γ_F {source}; N_it = {iterations}")
    print(f"{'N_c':>6} {'N_it':>5} {'γ_G/γ_F':>9} {'speedup (eq. 14)':>17} {'bound (eq. 15)':>15}")
    for n in args.cores:
        if args.ratio is not None:
            ratio = args.ratio
        elif measured is not None:
            ratio = measured["speedup"]["gamma_ratio"]
        else:
            ratio = estimated_gamma_ratio(cfg, resolved, n)
        ((_, theory, bound),) = parareal.predict(ratio, iterations, [n])
        print(f"{n:>6} {min(iterations, n):>5} {ratio:>9.4f} {theory:>17.3f} {bound:>15.3f}")
    return ExitCode.OK


def cmd_tune(args: argparse.Namespace, console: Console) -> ExitCode:
    from .tuning import command

    return ExitCode(command.main(args, console))


def cmd_plot(args: argparse.Namespace, console: Console) -> ExitCode:
    from . import plots

    formats = args.formats
    if args.benchmark is not None:
        if args.dirs:
            raise ValueError("plot: give run directories or --benchmark FILE.json, not both")
        out = args.out if args.out is not None else Path(args.benchmark).parent
        written = plots.draw_benchmark(args.benchmark, out, formats)
    elif not args.dirs:
        raise ValueError("plot: give run directories or --benchmark FILE.json")
    elif len(args.dirs) == 1 and args.out is None:
        written = plots.draw_run(args.dirs[0], formats)
    else:
        written = plots.draw_comparison(args.dirs, args.out or "comparison", formats)
    for path in written:
        console.print(str(path))
    return ExitCode.OK


# ---- parser and main -------------------------------------------------------------------------
def _parser() -> argparse.ArgumentParser:
    from . import __version__

    parser = argparse.ArgumentParser(
        prog="parastokes",
        description="Parareal with extrapolated coarse solvers for rods and vesicles in Stokes "
        "flow (Liu & Rostami).",
        epilog="Exit codes: 0 ok, 1 unexpected error, 2 bad configuration or usage, 3 numerical "
        "blow-up, 4 worker/parallel failure, 130 interrupted.",
    )
    parser.add_argument("--version", action="version", version=f"parastokes {__version__}")
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")
    common.add_argument("-v", "--verbose", action="store_true", help="log the solvers' details")
    overrides = argparse.ArgumentParser(add_help=False)
    overrides.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a key (TOML value), e.g. --set parareal.n_slices=8; repeatable",
    )
    running = argparse.ArgumentParser(add_help=False)
    running.add_argument("--out", required=True, help="output directory")
    running.add_argument(
        "--resume", action="store_true", help="continue from the checkpoint in --out"
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("run", parents=[common, overrides, running], help="run a configuration file")
    p.add_argument("config", help="TOML configuration (see docs/config.md)")
    p.set_defaults(func=cmd_run)

    p = sub.add_parser(
        "demo", parents=[common, overrides, running], help="a short rod swimmer with Parareal"
    )
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("check", parents=[common, overrides], help="validate configurations")
    p.add_argument("config", nargs="+", help="TOML configurations")
    p.set_defaults(func=cmd_check)

    p = sub.add_parser(
        "predict", parents=[common, overrides], help="predicted speedup for N cores (eq. 14)"
    )
    p.add_argument("config", help="TOML configuration")
    p.add_argument("--cores", type=int, nargs="+", required=True, help="core counts N_c")
    source = p.add_mutually_exclusive_group()
    source.add_argument("--ratio", type=float, help="γ_G/γ_F to use")
    source.add_argument("--measured", metavar="DIR", help="take γ_G/γ_F from a run directory")
    p.add_argument("--iterations", type=int, help="N_it (default: measured, else max_iterations)")
    p.set_defaults(func=cmd_predict)

    p = sub.add_parser(
        "tune",
        parents=[common, overrides],
        help="choose the coarse solver for a core count and a target error (docs/tuning.md)",
    )
    from .tuning.command import add_arguments

    add_arguments(p)
    p.set_defaults(func=cmd_tune)

    p = sub.add_parser("plot", parents=[common], help="figures from run directories")
    p.add_argument("dirs", nargs="*", help="run directories (several: comparison figures)")
    p.add_argument(
        "--benchmark",
        metavar="FILE.json",
        help="figures of Figs. 9 and 10 from benchmarks/parareal.py --json",
    )
    p.add_argument(
        "--out",
        help="directory for comparison figures (default: ./comparison) or benchmark figures "
        "(default: the JSON file's directory)",
    )
    p.add_argument("--formats", nargs="+", choices=["png", "pdf"], default=["png", "pdf"])
    p.set_defaults(func=cmd_plot)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """The ``parastokes`` command; returns the exit status (see :class:`ExitCode`)."""
    args = _parser().parse_args(argv)
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.ERROR if args.quiet else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    console = Console(args.quiet)
    try:
        return int(args.func(args, console))
    except BaseException as error:  # map every failure to a documented exit status
        if isinstance(error, SystemExit):
            raise
        code = exit_code(error)
        console.finish()
        if code is ExitCode.INTERRUPTED:
            print("interrupted; rerun with --resume to continue", file=sys.stderr)
        elif code is ExitCode.UNEXPECTED:
            logger.exception("unexpected error")
        else:
            print(f"error: {error}", file=sys.stderr)
            if code is ExitCode.PARALLEL:
                print("rerun with --resume to continue from the last iteration", file=sys.stderr)
        return int(code)


if __name__ == "__main__":
    sys.exit(main())
