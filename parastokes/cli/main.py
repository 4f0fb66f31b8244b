"""The ``parastokes`` command: parse, run the command, map every failure to its exit status."""

from __future__ import annotations

import logging
import signal
import sys
from collections.abc import Sequence

from ..core import signals
from .console import Console
from .exits import PIPE_CLOSED, catch_termination, reader_gone, report
from .launch import check_launch, check_shadowing
from .parser import parser


def main(argv: Sequence[str] | None = None) -> int:
    """The ``parastokes`` command; returns the exit status (see :class:`ExitCode`)."""
    args = parser().parse_args(argv)
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.ERROR if args.quiet else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    console = Console(args.quiet)
    check_shadowing()
    handlers = catch_termination()
    unraisable = sys.unraisablehook
    sys.unraisablehook = signals.quiet(unraisable)
    try:
        check_launch(sys.argv[1:] if argv is None else argv)
        status = int(args.func(args, console))
        signals.honour()  # a stop asked for during the command and lost on the way
        return status
    except BaseException as error:  # map every failure to a documented exit status
        if isinstance(error, SystemExit):
            raise
        if reader_gone(error):
            return PIPE_CLOSED
        return int(report(error, console, args.command))
    finally:
        signals.clear()
        sys.unraisablehook = unraisable
        for signum, handler in handlers.items():
            signal.signal(signum, handler)
