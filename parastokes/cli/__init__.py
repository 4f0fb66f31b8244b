"""The ``parastokes`` command line (docs/tutorial.md).

::

    parastokes run CONFIG.toml --out DIR [--resume | --overwrite] [--set KEY=VALUE ...]
    parastokes demo --out DIR [--resume | --overwrite] [--set KEY=VALUE ...]
    parastokes plot DIR [DIR ...] [--out FIGDIR] [--formats png pdf]
    parastokes plot --benchmark FILE.json [--out FIGDIR] [--formats png pdf]
    parastokes check CONFIG.toml [CONFIG.toml ...] [--set KEY=VALUE ...]
    parastokes predict CONFIG.toml --cores N [N ...] [--workers W] [--ratio R | --measured DIR]
                       [--iterations K]
    parastokes tune CONFIG.toml --cores N --target ETA --out TUNED.toml [--budget SECONDS]
    parastokes flow RUN_DIR [--frame I | --time T | --average T0 T1] [--plane z=5 | --box ...]
    parastokes movie RUN_DIR [--out swim.mp4] [--flow]

Exit codes (:class:`ExitCode`): 0 success; 1 unexpected error (a bug: please report the
traceback); 2 bad configuration or usage, or an output directory or file that cannot be used
(in use by another run, a finished run without ``--overwrite``, damaged, unwritable); 3 numerical
blow-up (a step too large for the problem: the message names the solver, time and step, and the
last good state is saved); 4 worker or parallel failure (a worker died or raised; rerun with
``--resume`` to continue from the last completed iteration and the solves completed since);
130 interrupted (Ctrl-C), 143
terminated (SIGTERM: ``kill``, ``timeout``, Slurm's time limit), 129 hung up (SIGHUP): in these
three cases the workers are stopped, the checkpoint is consistent and ``--resume`` continues.

An MPI launch of several processes without ``-m mpi4py.futures`` would run the whole problem once
per process: it is refused with the command line to use.

Progress bars (tqdm) are drawn only when stderr is a terminal, only by the manager (rank 0 of an
MPI launch) and never with ``--quiet``; ``--quiet`` also silences the tables (errors still go to
stderr).
"""

from __future__ import annotations

import argparse
import enum
import json
import logging
import math
import os
import shlex
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeAlias

if TYPE_CHECKING:
    from types import FrameType

    #: A signal handler as ``signal.signal`` takes and returns it.
    _Handler: TypeAlias = Callable[[int, FrameType | None], Any] | int | signal.Handlers | None

__all__ = ["ExitCode", "main"]

logger = logging.getLogger("parastokes")

#: Environment variables that carry the rank of an MPI process (MPICH/Intel MPI, Open MPI, PMIx).
_RANK_VARIABLES = ("PMI_RANK", "OMPI_COMM_WORLD_RANK", "PMIX_RANK")
#: ... and the number of processes of the launch (MPICH/Intel MPI, Open MPI).
_SIZE_VARIABLES = ("PMI_SIZE", "OMPI_COMM_WORLD_SIZE")
#: Seconds between redraws of a progress bar inside a step.
_TICK_SECONDS = 0.5
#: Signals handled like Ctrl-C: the run stops with a consistent checkpoint.
_TERMINATING = (signal.SIGTERM, signal.SIGHUP)
#: The exit status when the reader of standard output has gone (as a process ended by SIGPIPE).
_PIPE_CLOSED = 128 + 13
#: The commands other than a run that write files (through rundir.claim_files).
_WRITERS = ("flow", "movie", "tune", "plot")
#: What to make smaller when a command runs out of memory.
_SMALLER = {
    "flow": "use a smaller --resolution or --dpi (a plane rather than a box)",
    "movie": "use a smaller --size or --resolution, or fewer --frames",
    "plot": "plot fewer runs at once",
}


class ExitCode(enum.IntEnum):
    """Exit statuses of ``parastokes`` that scripts can rely on."""

    OK = 0
    UNEXPECTED = 1
    CONFIG = 2
    BLOWUP = 3
    PARALLEL = 4
    HANGUP = 129
    INTERRUPTED = 130
    TERMINATED = 143


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP arrived: stop like Ctrl-C (a KeyboardInterrupt, so every clean-up that
    an interrupt runs runs too); ``signum`` is the signal."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def _terminate(signum: int, _frame: object) -> None:
    raise Terminated(signum)


def is_manager() -> bool:
    """False on the non-root ranks of an MPI launch (read from the launcher's environment)."""
    return all(os.environ.get(name, "0") == "0" for name in _RANK_VARIABLES)


def mpi_processes() -> int:
    """The number of processes of the MPI launch this process belongs to (1 without one)."""
    sizes = [os.environ.get(name, "") for name in _SIZE_VARIABLES]
    return max([int(v) for v in sizes if v.isdigit()] or [1])


def _under_futures_launcher() -> bool:
    """Whether ``python -m mpi4py.futures`` runs this process (its pool of the other ranks)."""
    core = sys.modules.get("mpi4py.futures._core")
    return getattr(core, "SharedPool", None) is not None


def _check_launch(argv: Sequence[str]) -> None:
    """Refuse an MPI launch of several copies of the command (each would run everything)."""
    size = mpi_processes()
    if size > 1 and not _under_futures_launcher():
        command = f"mpiexec -n {size} python -m mpi4py.futures -m parastokes {shlex.join(argv)}"
        raise ValueError(
            f"launched as {size} MPI processes without the futures launcher: each would run the "
            f"whole problem into the same directory. Use\n    {command}\nwith "
            'execution.executor = "mpi" (docs/parallel.md, "mpi")'
        )


def shadowing_note(package: Path, cwd: Path, installed: Path | None) -> str | None:
    """A note when the package directory ``package`` that runs lies in the current directory
    ``cwd`` (``python -m`` puts it first on the path: a checkout's parent folder, or a checkout's
    root) while another copy is installed in ``installed`` (None: none)."""
    if installed is None or package.parent != cwd or installed == package:
        return None
    return (
        f"note: running the parastokes of {package} (python -m looks in the current directory "
        f"first), not the installed one in {installed}; run from another directory to use the "
        "installed package"
    )


def _installed_package() -> Path | None:
    """The directory of the installed (non-editable) parastokes, if there is one."""
    from importlib import metadata

    try:
        located = Path(str(metadata.distribution("parastokes").locate_file("parastokes")))
    except metadata.PackageNotFoundError:
        return None
    return located.resolve() if (located / "__init__.py").is_file() else None


def _check_shadowing() -> None:
    """Print :func:`shadowing_note` if the package runs from the current directory."""
    here = Path(__file__).resolve().parent
    if here.parent != Path.cwd().resolve():
        return
    note = shadowing_note(here, Path.cwd().resolve(), _installed_package())
    if note and is_manager():
        print(note, file=sys.stderr)


def _causes(error: BaseException):
    """The error, what it wraps (``TaskError.original``) and its chained causes."""
    seen: set[int] = set()
    stack: list[BaseException | None] = [error]
    while stack:
        item = stack.pop()
        if item is None or id(item) in seen:
            continue
        seen.add(id(item))
        yield item
        stack += [getattr(item, "original", None), item.__cause__, item.__context__]


def _body_error(error: BaseException) -> BaseException | None:
    """The :class:`~parastokes.bodies.contract.BodyError` that ``error`` is or wraps (a worker's
    task), if any: a user's body that broke the System contract."""
    from ..bodies.contract import BodyError

    return next((e for e in _causes(error) if isinstance(e, BodyError)), None)


def exit_code(error: BaseException) -> ExitCode:
    """The exit status for an error that ended a command."""
    from ..config import ConfigError
    from ..core.files import is_resource_error
    from ..integrate import BlowUpError
    from ..parallel import TaskError

    causes = list(_causes(error))
    for cause in causes:
        if isinstance(cause, Terminated):
            return ExitCode(128 + cause.signum)
    if any(isinstance(e, KeyboardInterrupt) for e in causes):
        return ExitCode.INTERRUPTED
    if any(isinstance(e, BlowUpError) for e in causes):
        return ExitCode.BLOWUP
    if isinstance(error, ConfigError) or _body_error(error) is not None:
        return ExitCode.CONFIG
    if any(isinstance(e, MemoryError) or is_resource_error(e) for e in causes):
        return ExitCode.CONFIG  # out of memory, a full disk, too many open files: the machine's
    if any(isinstance(e, TaskError | BrokenProcessPool) for e in causes):
        return ExitCode.PARALLEL
    if isinstance(error, ValueError | OSError | ImportError):
        return ExitCode.CONFIG  # bad input, or a file or directory that cannot be used
    return ExitCode.UNEXPECTED


# ---- console output --------------------------------------------------------------------------
class Console:
    """Prints notes and the per-iteration table; draws tqdm bars on a terminal (manager only)."""

    def __init__(self, quiet: bool) -> None:
        self.quiet = quiet
        self.bars = not quiet and is_manager() and sys.stderr.isatty()
        self._bar = None
        self._times: list[float] = []  # start of the phase, then the end of every step
        self._expected: float | None = None
        self._ticking = threading.Event()

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
        self._times, self._expected = [time.monotonic()], None
        if self.bars:
            from tqdm import tqdm

            unit = "slice" if what == "serial" else "iteration"
            self._bar = tqdm(total=total, desc=what, unit=unit, leave=False, file=sys.stderr)
            self._ticking.clear()
            threading.Thread(target=self._tick, daemon=True).start()

    def expect(self, seconds: float) -> None:
        """An estimate of one step of the current phase, used until a step has been timed."""
        self._expected = seconds

    def progress(self, now: float) -> float:
        """Steps of the current phase done by ``now``, the running one counted by its elapsed
        time over the expected time of a step (the mean of those done, else the estimate), so
        that a bar moves, and gives an ETA, inside long slices; always below the next step."""
        done = len(self._times) - 1
        expected = (self._times[-1] - self._times[0]) / done if done else self._expected
        if not expected:
            return float(done)
        return done + min(0.99, (now - self._times[-1]) / expected)

    def _tick(self) -> None:
        while not self._ticking.wait(_TICK_SECONDS):
            bar = self._bar
            if bar is not None:
                bar.n = self.progress(time.monotonic())
                bar.refresh()

    def advance(self) -> None:
        self._times.append(time.monotonic())
        if self._bar is not None:
            self._bar.n = len(self._times) - 1
            self._bar.refresh()

    def finish(self) -> None:
        self._ticking.set()
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def iteration(self, k: int, increment: float, error: float | None, elapsed: float) -> None:
        err = "-" if error is None else f"{error:.3e}"
        self.print(f"{k:>3}  {increment:>14.3e}  {err:>10}  {elapsed:>11.2f}")


# ---- commands --------------------------------------------------------------------------------
def _load(path: str | None, overrides: Sequence[str], text: str | None = None):
    from .. import config

    if text is not None:
        return config.loads(text, "demo configuration", overrides)
    assert path is not None  # the commands give a path or a text
    return config.load(path, overrides)


def _execute(
    args: argparse.Namespace, cfg, resolved, console: Console, files: dict[str, str] | None = None
) -> ExitCode:
    from ..run import runner

    for warning in resolved.warnings:
        console.print(f"note: {warning}")
    summary = runner.execute(
        cfg,
        resolved,
        args.out,
        resume=args.resume,
        overwrite=args.overwrite,
        reporter=console,
        files=files,
    )
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

    cfg, resolved = _load(None, args.set, text=DEMO)
    console.print(cfg.title)
    console.print(f"(configuration written to {args.out}/config.toml; edit it and use `run`)")
    return _execute(args, cfg, resolved, console, files={"config.toml": demo_text(args.set)})


def cmd_check(args: argparse.Namespace, console: Console) -> ExitCode:
    from ..bodies.contract import BodyError
    from ..config import ConfigError, preflight

    status = ExitCode.OK
    for path in args.config:
        try:
            cfg, r = _load(path, args.set)
            preflight(cfg, r, path)  # as a run does before its workers start
        except ConfigError as error:
            print(error, file=sys.stderr)
            status = ExitCode.CONFIG
            continue
        except BodyError as error:
            print(f"{path}: {error}", file=sys.stderr)
            status = ExitCode.CONFIG
            continue
        console.print(
            f"{path}: ok ({cfg.model.kind}, {r.n_points} points"
            f"{'' if math.isnan(r.epsilon) else f', ε⁰ = {r.epsilon:.6g}'}; "
            f"{cfg.parareal.n_slices} slices of {r.fine_steps} fine steps; coarse τ_c = "
            f"{r.coarse_dt:.6g} ({r.coarse_dt / r.fine_dt:.4g} τ_f), N_G = {r.n_auxiliary}, "
            f"Σ|w| = {r.weight_sum:.3g}, workers = {r.workers})"
        )
        for warning in r.warnings:
            console.print(f"  note: {warning}")
    return status


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
    cfg, resolved = _load(args.config, args.set)
    measured = io.read_summary(Path(args.measured) / "summary.json") if args.measured else None
    if measured is not None and not measured.get("speedup"):
        raise ValueError(f"{args.measured} holds no Parareal run")
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
    print(
        f"{'N_c':>6} {'N_it':>5} {'γ_G/γ_F':>9} {'speedup (eq. 14)':>17} {'bound (eq. 15)':>15}"
        f" {'std':>7} {'std sim':>8} {'pipe':>7} {'pipe sim':>9}"
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
        )
    if skipped:
        from ..parareal.schedule_model import MAX_SIMULATED_TASKS

        print(f"sim -: not simulated for N_c = {', '.join(map(str, skipped))} (more than "
              f"{MAX_SIMULATED_TASKS} tasks); the closed formulas std and pipe hold there")
    return ExitCode.OK


def cmd_tune(args: argparse.Namespace, console: Console) -> ExitCode:
    from ..tuning import command

    return ExitCode(command.main(args, console))


def cmd_plot(args: argparse.Namespace, console: Console) -> ExitCode:
    from ..output import plots, rundir

    formats = args.formats
    if args.benchmark is not None:
        if args.dirs:
            raise ValueError("plot: give run directories or --benchmark FILE.json, not both")
        out = Path(args.out if args.out is not None else Path(args.benchmark).parent)
        with rundir.claim_files(_figures(out, plots.BENCHMARK_FIGURES, formats)):
            written = plots.draw_benchmark(args.benchmark, out, formats)
    elif not args.dirs:
        raise ValueError("plot: give run directories or --benchmark FILE.json")
    elif len(args.dirs) == 1 and args.out is None:
        with rundir.locked(args.dirs[0]) as directory:  # not while a run writes there
            written = plots.draw_run(args.dirs[0], formats)
            directory.add_results([path.name for path in written])
    else:
        out = Path(args.out or "comparison")
        with rundir.claim_files(_figures(out, plots.COMPARISON_FIGURES, formats),
                                reads=args.dirs):
            written = plots.draw_comparison(args.dirs, out, formats)
    for path in written:
        console.print(str(path))
    return ExitCode.OK


def _figures(out: Path, stems: Sequence[str], formats: Sequence[str]) -> list[Path]:
    """The files of the figures ``stems`` in ``formats`` in the directory ``out``."""
    return [out / f"{stem}.{fmt}" for stem in stems for fmt in formats]


# ---- parser and main -------------------------------------------------------------------------
def _parser() -> argparse.ArgumentParser:
    from .. import __version__

    parser = argparse.ArgumentParser(
        prog="parastokes",
        description="Parareal with extrapolated coarse solvers for rods and vesicles in Stokes "
        "flow (Liu & Rostami).",
        epilog="Exit codes: 0 ok, 1 unexpected error (a bug), 2 bad configuration, usage or output "
        "directory (in use, finished, damaged file, unwritable), 3 numerical blow-up (last good "
        "state saved), 4 worker/parallel failure, 130 interrupted (Ctrl-C), 143 terminated "
        "(SIGTERM), 129 hung up (SIGHUP); after 4, 130, 143 and 129 the checkpoint is consistent "
        "and --resume continues.",
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
    again = running.add_mutually_exclusive_group()
    again.add_argument(
        "--resume",
        action="store_true",
        help="continue the interrupted (or finished) run in --out; refused if the configuration "
        "differs",
    )
    again.add_argument(
        "--overwrite",
        action="store_true",
        help="replace the run in --out (its results stay until the new run completes)",
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
        "predict",
        parents=[common, overrides],
        help="predicted speedup for N cores: eq. 14, both schedules (formula and simulation)",
    )
    p.add_argument("config", help="TOML configuration")
    p.add_argument("--cores", type=int, nargs="+", required=True, help="core counts N_c")
    p.add_argument(
        "--workers", type=int, help="workers W for the simulation (default: W = N_c, one per slice)"
    )
    source = p.add_mutually_exclusive_group()
    source.add_argument("--ratio", type=float,
                        help="γ/γ_F of one auxiliary solve (a coarse step: ceil(N_G/W) of them)")
    source.add_argument("--measured", metavar="DIR",
                        help="take it from a run directory (its coarse step over its rounds)")
    p.add_argument("--iterations", type=int, help="N_it (default: measured, else max_iterations)")
    p.set_defaults(func=cmd_predict)

    p = sub.add_parser(
        "tune",
        parents=[common, overrides],
        help="choose the coarse solver for a core count and a target error (docs/tuning.md)",
    )
    from ..tuning.command import add_arguments

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

    from ..flow.command import add_commands as add_flow_commands

    add_flow_commands(sub, [common])  # flow, movie
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """The ``parastokes`` command; returns the exit status (see :class:`ExitCode`)."""
    args = _parser().parse_args(argv)
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.ERROR if args.quiet else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    console = Console(args.quiet)
    _check_shadowing()
    handlers = _catch_termination()
    try:
        _check_launch(sys.argv[1:] if argv is None else argv)
        return int(args.func(args, console))
    except BaseException as error:  # map every failure to a documented exit status
        if isinstance(error, SystemExit):
            raise
        if _reader_gone(error):
            return _PIPE_CLOSED
        return int(_report(error, console, args.command))
    finally:
        for signum, handler in handlers.items():
            signal.signal(signum, handler)


def _catch_termination() -> dict[int, _Handler]:
    """Handle SIGTERM and SIGHUP like Ctrl-C (main thread only); returns the previous handlers."""
    if threading.current_thread() is not threading.main_thread():
        return {}
    handlers: dict[int, _Handler] = {
        signum: signal.signal(signum, _terminate) for signum in _TERMINATING
    }
    if hasattr(signal, "SIGXFSZ"):  # past a file-size limit a write fails (EFBIG), not the process
        handlers[signal.SIGXFSZ] = signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    return handlers


def _reader_gone(error: BaseException) -> bool:
    """Whether ``error`` is the reader of standard output closing it (``parastokes check ... |
    head -2``); then the output goes nowhere from now on (no second error at exit)."""
    if not isinstance(error, BrokenPipeError):
        return False
    try:  # a pipe without a reader polls as an error on its writing end
        import select

        poller = select.poll()
        poller.register(sys.stdout.fileno(), select.POLLOUT)
        if not any(event & select.POLLERR for _, event in poller.poll(0)):
            return False  # (another pipe broke: a worker's, say)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):  # no such file descriptor, or no poll()
        return False
    return True


def _machine_limit(error: BaseException, command: str = "run") -> str | None:
    """A line naming the machine's limit (memory, disk, open files) behind ``error`` when its
    own message does not; out of memory, what to make smaller for ``command``."""
    from ..core.files import describe_os_error, is_resource_error

    for cause in _causes(error):
        if isinstance(cause, MemoryError):
            smaller = _SMALLER.get(command, "use fewer points, slices or workers")
            return f"cause: out of memory (MemoryError): {smaller}, or a machine with more memory"
        if is_resource_error(cause) and isinstance(cause, OSError):
            text = describe_os_error(cause)
            return None if text in str(error) else f"cause: {text}"
    return None


def _report(error: BaseException, console: Console, command: str = "run") -> ExitCode:
    """Print what ended ``command`` (with the notes that say what was saved); its exit status.
    A run (``run``, ``demo``) is continued by ``--resume``; the other commands that write keep
    the previous files."""
    resumable = command in ("run", "demo")
    code = exit_code(error)
    console.finish()
    if not is_manager() and mpi_processes() > 1 and code is ExitCode.CONFIG:
        return code  # the launch was refused: rank 0 says so
    notes = [f"  {note}" for note in getattr(error, "__notes__", ())]
    if code in (ExitCode.INTERRUPTED, ExitCode.TERMINATED, ExitCode.HANGUP):
        what = {130: "interrupted", 143: "terminated (SIGTERM)", 129: "hung up (SIGHUP)"}[code]
        if resumable:
            lines = [f"{what}: the workers are stopped and the checkpoint is consistent; rerun "
                     "with --resume to continue"]
        else:
            kept = ("; the files it was writing are dropped, the previous ones kept"
                    if command in _WRITERS else "")
            lines = [f"{what}; no run was in progress, so there is nothing to resume{kept}"]
    elif code is ExitCode.UNEXPECTED:
        logger.exception("unexpected error")
        return code
    else:
        limit = _machine_limit(error, command)
        lines = [f"error: {_body_error(error) or error}", *notes, *([limit] if limit else [])]
        if code is ExitCode.PARALLEL and resumable:
            lines.append("rerun with --resume to continue from the last iteration")
    print("\n".join(lines), file=sys.stderr)
    return code


if __name__ == "__main__":
    sys.exit(main())
