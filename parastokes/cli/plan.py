"""``parastokes plan``: the command of :mod:`parastokes.planning.command`."""

from __future__ import annotations

import argparse

from .console import Console
from .exits import ExitCode


def cmd_plan(args: argparse.Namespace, console: Console) -> ExitCode:
    from ..planning import command

    return ExitCode(command.main(args, console))
