"""``parastokes tune``: the command of :mod:`parastokes.tuning.command`."""

from __future__ import annotations

import argparse

from .console import Console
from .exits import ExitCode


def cmd_tune(args: argparse.Namespace, console: Console) -> ExitCode:
    from ..tuning import command

    return ExitCode(command.main(args, console))
