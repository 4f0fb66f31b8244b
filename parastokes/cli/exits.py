"""How a command ends: the documented exit statuses (:class:`ExitCode`), the error behind a
failure, SIGTERM and SIGHUP handled like Ctrl-C, and the message printed for each
(with what was saved and what to change)."""

from __future__ import annotations

import enum
import logging
import os
import signal
import sys
import threading
from collections.abc import Callable
from concurrent.futures.process import BrokenProcessPool
from typing import TYPE_CHECKING, Any, TypeAlias

from ..core.signals import Terminated, interrupt, terminate, what_completed
from .console import Console
from .launch import is_manager, mpi_processes

if TYPE_CHECKING:
    from types import FrameType

    #: A signal handler as ``signal.signal`` takes and returns it.
    _Handler: TypeAlias = Callable[[int, FrameType | None], Any] | int | signal.Handlers | None


logger = logging.getLogger("parastokes")


_TERMINATING = (signal.SIGTERM, signal.SIGHUP)


PIPE_CLOSED = 128 + 13


WRITERS = ("flow", "movie", "tune", "plot")


SMALLER = {
    "flow": "use a smaller --resolution or --dpi (a plane rather than a box)",
    "movie": "use a smaller --size or --resolution, or fewer --frames",
    "plot": "plot fewer runs at once",
    "predict": "give smaller files (--serial, --measured's summary.json)",
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


def body_error(error: BaseException) -> BaseException | None:
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
    from ..run.execution import MonitorError

    causes = list(_causes(error))
    for cause in causes:
        if isinstance(cause, Terminated):
            return ExitCode(128 + cause.signum)
    if any(isinstance(e, KeyboardInterrupt) for e in causes):
        return ExitCode.INTERRUPTED
    if any(isinstance(e, BlowUpError | MonitorError) for e in causes):
        return ExitCode.BLOWUP
    if isinstance(error, ConfigError) or body_error(error) is not None:
        return ExitCode.CONFIG
    if any(isinstance(e, MemoryError) or is_resource_error(e) for e in causes):
        return ExitCode.CONFIG  # out of memory, a full disk, too many open files: the machine's
    if any(isinstance(e, TaskError | BrokenProcessPool) for e in causes):
        return ExitCode.PARALLEL
    if isinstance(error, ValueError | OSError | ImportError):
        return ExitCode.CONFIG  # bad input, or a file or directory that cannot be used
    return ExitCode.UNEXPECTED


def catch_termination() -> dict[int, _Handler]:
    """Handle SIGTERM and SIGHUP like Ctrl-C, and record each and Ctrl-C for
    :func:`~parastokes.core.signals.honour` (main thread only); returns the previous handlers."""
    if threading.current_thread() is not threading.main_thread():
        return {}
    handlers: dict[int, _Handler] = {
        signum: signal.signal(signum, terminate) for signum in _TERMINATING
    }
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:  # (recorded as well)
        handlers[signal.SIGINT] = signal.signal(signal.SIGINT, interrupt)
    if hasattr(signal, "SIGXFSZ"):  # past a file-size limit a write fails (EFBIG), not the process
        handlers[signal.SIGXFSZ] = signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    return handlers


def reader_gone(error: BaseException) -> bool:
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
            smaller = SMALLER.get(command, "use fewer points, slices or workers")
            return f"cause: out of memory (MemoryError): {smaller}, or a machine with more memory"
        if is_resource_error(cause) and isinstance(cause, OSError):
            text = describe_os_error(cause)
            return None if text in str(error) else f"cause: {text}"
    return None


def report(error: BaseException, console: Console, command: str = "run") -> ExitCode:
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
        done = what_completed()
        if done is not None:
            lines = [f"{what} after the command had completed: {done}"]
        elif resumable:
            lines = [f"{what}: the workers are stopped and the checkpoint is consistent; rerun "
                     "with --resume to continue"]
        else:
            kept = ("; the files it was writing are dropped, the previous ones kept"
                    if command in WRITERS else "")
            lines = [f"{what}; no run was in progress, so there is nothing to resume{kept}"]
    elif code is ExitCode.UNEXPECTED:
        logger.exception("unexpected error")
        return code
    else:
        limit = _machine_limit(error, command)
        message = str(body_error(error) or error)
        if not message:  # (a MemoryError says nothing itself: its cause is the message)
            message, limit = (limit or type(error).__name__).removeprefix("cause: "), None
        lines = [f"error: {message}", *notes, *([limit] if limit else [])]
        if code is ExitCode.PARALLEL and resumable:
            lines.append("rerun with --resume to continue from the last iteration")
    print("\n".join(lines), file=sys.stderr)
    return code
