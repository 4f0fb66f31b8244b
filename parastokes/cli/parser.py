"""The argument parser of every command (also rendered in the documentation's CLI page)."""

from __future__ import annotations

import argparse

from .plan import cmd_plan
from .plot import cmd_plot
from .predict import cmd_predict
from .run import cmd_check, cmd_demo, cmd_run
from .tune import cmd_tune


def parser() -> argparse.ArgumentParser:
    from .. import __version__

    parser = argparse.ArgumentParser(
        prog="parastokes",
        description="Parareal with extrapolated coarse solvers for rods and vesicles in Stokes "
        "flow (Liu & Rostami).",
        epilog="Exit codes: 0 ok, 1 unexpected error (a bug), 2 bad configuration, usage or output "
        "directory (in use, finished, damaged file, unwritable), 3 numerical blow-up (last good "
        "state saved; or a monitor above its limit with --monitor-fatal), 4 worker/parallel "
        "failure, 130 interrupted (Ctrl-C), 143 terminated "
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
    running.add_argument(
        "--monitor-fatal",
        action="store_true",
        help="a stability monitor above its limit at the end is an error (exit 3), not a "
        "warning (output.monitor_fatal)",
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
    p.add_argument("--serial", metavar="FILE.json",
                   help="measured serial runs of this problem (benchmarks/stiff.py's "
                        "best_serial.json): also the speedup against the fastest serial run "
                        "that reaches --target")
    p.add_argument("--case", help="the case of --serial (needed when it holds several)")
    p.add_argument("--target", type=float, metavar="ETA",
                   help="the accuracy at T to compare at (default with --measured: the run's "
                        "last error η^K)")
    p.set_defaults(func=cmd_predict)

    p = sub.add_parser(
        "tune",
        parents=[common, overrides],
        help="choose the coarse solver for a core count and a target error (docs/tuning.md)",
    )
    from ..tuning.command import add_arguments

    add_arguments(p)
    p.set_defaults(func=cmd_tune)

    p = sub.add_parser(
        "plan",
        parents=[common, overrides],
        help="the fastest route to the end on N cores at a target error: serial, spatial, "
        "Parareal or both, against the fastest serial run (docs/planning.md)",
    )
    from ..planning.command import add_arguments as add_plan_arguments

    add_plan_arguments(p)
    p.set_defaults(func=cmd_plan)

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
