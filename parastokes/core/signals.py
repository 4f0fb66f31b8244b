"""A stop that was asked for and must not be lost.

SIGTERM and SIGHUP are raised as :class:`Terminated` (a ``KeyboardInterrupt``, so every clean-up
that Ctrl-C runs runs too), and Ctrl-C as ``KeyboardInterrupt``, wherever Python delivers them.
One delivered while a finalizer or a weakref callback runs (the garbage collector's work, at any
moment) is printed as "Exception ignored" and dropped, and the command would go on as if nothing
had happened. So the handlers record the signal first, and the places where a command can stop
cleanly (between parallel tasks, between slices and frames, while an encoder finishes, before
results are moved into place, at the end of a command) call :func:`honour`, which raises it
again; :func:`quiet` keeps Python's "Exception ignored" traceback of the first raise off the
terminal.
"""

from __future__ import annotations

import signal
from collections.abc import Callable
from typing import Any

__all__ = ["Terminated", "clear", "completed", "honour", "interrupt", "quiet", "terminate",
           "what_completed"]

#: The signal asked for and not yet ended the command with (at most one).
_pending: list[int] = []
#: What the command has completed and put in place (said if a stop comes after it).
_completed: list[str] = []


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP arrived: stop like Ctrl-C; ``signum`` is the signal."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def terminate(signum: int, _frame: object = None) -> None:
    """The signal handler: record ``signum``, then raise :class:`Terminated`."""
    _pending[:] = [signum]
    raise Terminated(signum)


def interrupt(signum: int, _frame: object = None) -> None:
    """The handler of Ctrl-C (SIGINT): record it, then raise ``KeyboardInterrupt`` as Python's
    own handler does."""
    _pending[:] = [signum]
    raise KeyboardInterrupt


def honour() -> None:
    """Raise the stop asked for again (its first raise may have been lost in a finalizer):
    ``KeyboardInterrupt`` for Ctrl-C, :class:`Terminated` for SIGTERM and SIGHUP; nothing when
    none was asked for."""
    if _pending:
        if _pending[0] == signal.SIGINT:
            raise KeyboardInterrupt
        raise Terminated(_pending[0])


def quiet(previous: Callable[[Any], object]) -> Callable[[Any], object]:
    """A ``sys.unraisablehook`` that drops a :class:`Terminated` (recorded, to be raised again
    by :func:`honour`, not a traceback to show) and passes everything else to ``previous``."""

    def hook(unraisable: Any) -> None:
        if not isinstance(unraisable.exc_value, KeyboardInterrupt) or not _pending:
            previous(unraisable)

    return hook


def completed(what: str) -> None:
    """Record that the command's work is complete and in place (``what``: where, in words), so
    that a stop arriving afterwards says so instead of calling it cut short."""
    _completed[:] = [what]


def what_completed() -> str | None:
    """What :func:`completed` recorded during this command, or None."""
    return _completed[0] if _completed else None


def clear() -> None:
    """Forget the stop asked for and what was completed (the command it ended is over)."""
    _pending.clear()
    _completed.clear()
