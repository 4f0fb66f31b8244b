"""Lock files: one process at a time owns a name (a run directory, an output file).

:func:`acquire` creates the lock file with ``O_CREAT | O_EXCL`` (atomic on local and network file
systems alike, unlike HDF5's file locking) and writes the owner's PID, host, process start time,
wall-clock time and command line into it. A lock held by a live process raises :class:`Held`
with that record (the caller's message names the holder: :func:`holder`). A lock whose process is
gone (same host, PID dead or reused) is stale and is taken over; a lock from another host is never
guessed about.
"""

from __future__ import annotations

import json
import os
import socket
import sys
import time
from pathlib import Path

__all__ = ["Held", "acquire", "holder", "owner", "process_alive", "release", "stale"]

# Seconds after which a lock take-over that was itself interrupted is ignored.
BREAK_TIMEOUT = 10.0


class Held(OSError):
    """The lock ``path`` is held by a live process; ``record`` is its lock record."""

    def __init__(self, path: Path, record: dict) -> None:
        super().__init__(f"{path} is held by {holder(record)}")
        self.path, self.record = path, record


def process_start(pid: int) -> str | None:
    """The start time of process ``pid`` in clock ticks since boot (Linux), else None."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return text.rsplit(")", 1)[1].split()[19]


def process_alive(pid: int, started: str | None = None) -> bool:
    """Whether process ``pid`` of this host runs (not a zombie) and, given ``started`` (its start
    time from /proc), is the one that started then (not a later process reusing the PID)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return True  # no /proc: trust kill()
    return state != "Z" and (started is None or process_start(pid) == started)


def holder(record: dict) -> str:
    """The holder of a lock in words: its command (``parastokes movie``, ``parastokes run``, ...),
    PID, host and start time."""
    words = str(record.get("command") or "").split()
    program = Path(words[0]).name if words else ""
    ours = program == "parastokes" or (program == "__main__.py" and "parastokes" in words[0])
    what = f"`parastokes {words[1]}`" if ours and len(words) > 1 else "another parastokes process"
    return (f"{what} (PID {record.get('pid')} on host {record.get('host')}, started "
            f"{record.get('time', '?')})")


def owner(path: Path) -> dict | None:
    """The lock record in ``path``; None if it is gone or unreadable (a lock being written)."""
    from .files import read_record  # (files imports this module)

    try:
        record = json.loads(read_record(path))
    except (OSError, ValueError):
        return None
    return record if isinstance(record, dict) else None


def age(path: Path) -> float:
    """Seconds since ``path`` was last written (0 if it is gone)."""
    try:
        return time.time() - path.stat().st_mtime
    except OSError:
        return 0.0


def stale(record: dict) -> bool:
    """Whether the lock ``record`` is of a process of this host that is gone."""
    if record.get("host") != socket.gethostname() or not isinstance(record.get("pid"), int):
        return False
    return not process_alive(record["pid"], record.get("started"))


def _take_over(path: Path, record: dict | None) -> None:
    """Remove the stale lock ``path`` (``record``: its record, None for an unreadable one)
    unless another process is doing so or has replaced it."""
    breaker = path.with_name(path.name + ".break")
    try:
        fd = os.open(breaker, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
    except FileExistsError:
        if time.time() - breaker.stat().st_mtime > BREAK_TIMEOUT:
            breaker.unlink(missing_ok=True)
        time.sleep(0.05)
        return
    os.close(fd)
    try:
        if owner(path) == record:  # still the same stale lock
            path.unlink(missing_ok=True)
    finally:
        breaker.unlink(missing_ok=True)


def acquire(path: str | os.PathLike) -> dict:
    """Create the lock file ``path`` for this process (taking over a stale one); returns its
    record. :class:`Held` when a live process (or one of another host) holds it; another
    ``OSError`` when it cannot be created."""
    path = Path(path)
    pid = os.getpid()
    record = {
        "pid": pid,
        "host": socket.gethostname(),
        "started": process_start(pid),
        "time": time.strftime("%Y-%m-%d %H:%M:%S"),
        "command": " ".join(sys.argv),
    }
    deadline = time.monotonic() + 2 * BREAK_TIMEOUT
    while True:
        try:
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        except FileExistsError:
            found = owner(path)
            if (found is not None and not stale(found)) or time.monotonic() > deadline:
                raise Held(path, found or {}) from None
            if found is not None:
                _take_over(path, found)
            elif age(path) > BREAK_TIMEOUT:  # a record never written: its writer was killed
                _take_over(path, None)
            else:
                time.sleep(0.05)  # being written: read it again
            continue
        with os.fdopen(fd, "w", encoding="utf-8") as handle:
            json.dump(record, handle)
        return record


def release(path: str | os.PathLike, record: dict) -> None:
    """Remove the lock file ``path`` if it still holds ``record`` (this holder's)."""
    path = Path(path)
    if owner(path) == record:
        path.unlink(missing_ok=True)
