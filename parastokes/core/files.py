"""Files the package writes and reads back: atomic writes, and reads that name a damaged file.

Every file is written to a temporary name beside its destination (``NAME.<pid>.tmp``,
:func:`temporary_name`), flushed to disk and renamed over it (``os.replace``, atomic on POSIX), so
a reader, or a command that is killed mid-write, sees either the old complete file or the new
complete one (:class:`Staging`: several files of one command, each moved into place once all are
written; :func:`atomic_write`: one file). A writer that names its own file (h5py, a video
encoder) writes to :meth:`Staging.temporary`; a temporary file it left empty or did not create is
a :class:`FileWriteError`, and the old file stays. A file that cannot be read back (truncated, not
written by parastokes, another format) raises :class:`CorruptFileError`, a ``ValueError`` whose
message names the file and what to do (the command line exits with status 2).

A write that fails (a full disk, a file-size limit, too many open files) raises
:class:`FileWriteError`, an ``OSError`` whose message names the file and the cause. HDF5 files are
written through :class:`GuardedFile`, so that such a failure never reaches HDF5 itself: h5py
crashes the interpreter (a segmentation fault) when it closes a file after a failed write.

Every file the package reads (configurations, suspension poses, point clouds, measured serial
runs, summaries, array files, trajectories, flow grids, run records) goes through one reader,
:func:`read_input` (bytes, read with a bounded read) or :func:`open_input` (a handle for a parser
that reads by itself); HDF5 files are checked by :func:`check_input` before h5py opens them by
name. Each refuses, before opening it, what is not a regular file (a device such as /dev/zero,
a named pipe, which would block the open, a directory, a socket) and a file above the size cap of
its kind (:data:`INPUTS`), in one line naming the file and what to give instead
(:class:`InputFileError`, a ``ValueError``: exit status 2). A file that grows while it is read
is still read to at most its cap plus one byte.

A temporary file of another process, left beside a destination by a writer that was killed
(``NAME.<pid>.tmp``), is removed when the same destination is written again, provided its writer
no longer runs on this host and the file is older than this process (:func:`remove_stale`): a
command's folder (``flow --out``, ``tune --out``) does not collect them.
"""

from __future__ import annotations

import errno
import glob
import io
import json
import os
import stat
import time
import zipfile
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager, nullcontext
from pathlib import Path
from typing import IO, Any

import numpy as np

from . import locks, signals

__all__ = [
    "INPUTS", "CorruptFileError", "FileWriteError", "GuardedFile", "InputFileError",
    "OutputInUse", "Staging", "atomic_write", "check_input", "commit_set", "describe_os_error",
    "hold_names", "is_resource_error", "open_input", "read_input", "read_npz", "read_record",
    "recover_sets",
    "remove_stale", "staged", "temporary_name", "write_npz", "write_text",
]

_MIB, _GIB = 1 << 20, 1 << 30
#: Every kind of file the package reads: what it is (as a message names it) and its size cap in
#: bytes, far above what the package writes or a user gives (docs/design.md, "Bounded reads").
INPUTS: dict[str, tuple[str, int]] = {
    "configuration": ("a TOML configuration (a few kilobytes)", _MIB),
    "poses": ("a file of suspension poses, one body per line or a .npy array", 64 * _MIB),
    "points": ("a point cloud of a rigid surface (.npy or text, N rows of x y z)", 64 * _MIB),
    "serial runs": ("a file of measured serial runs (benchmarks/stiff.py's best_serial.json)",
                    16 * _MIB),
    "summary": ("a run's summary.json", 256 * _MIB),
    "measurements": ("a benchmark's JSON file of measurements", 256 * _MIB),
    "record": ("a run directory's record (lock or manifest)", _MIB),
    "arrays": ("a parastokes array file (.npz: checkpoint, history, reference, blow-up)",
               64 * _GIB),
    "trajectory": ("a trajectory (HDF5) written by parastokes", 1 << 40),
    "flow": ("a flow field (HDF5) written by parastokes flow", 1 << 40),
    "movie": ("an MP4 movie written by the encoder (its box headers are read)", 1 << 40),
}
#: The most read at once from a file (a bounded read proceeds in such chunks).
_CHUNK = 16 * _MIB
#: When this process imported this module: a temporary file older than that is no write of its.
_STARTED = time.time()

#: errno values of a full disk or a reached limit, and what each means.
_CAUSES = {
    errno.ENOSPC: "the file system is full: free space there or choose another directory",
    errno.EDQUOT: "the disk quota is exceeded: free space or choose another directory",
    errno.EFBIG: "the file size limit is reached (`ulimit -f`, or the file system's largest "
                 "file): raise the limit or choose another directory",
    errno.EMFILE: "this process has too many open files (`ulimit -n`): raise the limit",
    errno.ENFILE: "the system's table of open files is full: retry when other programs close "
                  "files",
}


class CorruptFileError(ValueError):
    """A file the package reads back is damaged or foreign; ``path`` names it."""

    def __init__(self, path: str | os.PathLike, problem: str, remedy: str = "") -> None:
        self.path = Path(path)
        remedy = remedy or "remove it (a run writes it anew) or point to the right file"
        super().__init__(f"{self.path}: {problem}; {remedy}")


class InputFileError(ValueError):
    """A file the package was given to read cannot be: not a regular file, or larger than the
    cap of its kind (:data:`INPUTS`); ``path`` names it, ``problem`` and ``remedy`` say why and
    what to give instead."""

    def __init__(self, path: str | os.PathLike, problem: str, remedy: str) -> None:
        self.path, self.problem, self.remedy = Path(path), problem, remedy
        super().__init__(f"{self.path}: {problem}; {remedy}")


def _file_type(mode: int) -> str:
    """What a file of ``mode`` is, in words, when it is not a regular file."""
    for test, name in ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a named pipe (FIFO)"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                       (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return name
    return "not a regular file"


def _size(count: int) -> str:
    """``count`` bytes in words (``64 MiB``)."""
    for unit, scale in (("TiB", 1 << 40), ("GiB", _GIB), ("MiB", _MIB), ("KiB", 1 << 10)):
        if count >= scale:
            return f"{count / scale:.3g} {unit}"
    return f"{count} bytes"


def _checked(path: Path, info: os.stat_result, kind: str) -> None:
    """Refuse (:class:`InputFileError`) a file of ``info`` that is not a regular file or is
    larger than the cap of ``kind``."""
    what, limit = INPUTS[kind]
    if not stat.S_ISREG(info.st_mode):
        raise InputFileError(path, f"{_file_type(info.st_mode)}, not a regular file",
                             f"give {what}")
    if info.st_size > limit:
        raise InputFileError(path, f"larger than {_size(limit)} ({_size(info.st_size)}): no "
                                   f"{kind} file is that large", f"give {what}")


def check_input(path: str | os.PathLike, kind: str) -> int:
    """The size of ``path``, a regular file within the cap of ``kind`` (:data:`INPUTS`), checked
    without opening it (for a reader that opens files by name, as h5py does); else
    :class:`InputFileError`. A missing or inaccessible file is the ``OSError`` of ``os.stat``."""
    path = Path(path)
    info = os.stat(path)
    _checked(path, info, kind)
    return info.st_size


@contextmanager
def open_input(path: str | os.PathLike, kind: str) -> Iterator[IO[bytes]]:
    """``path`` open for binary reading, a regular file within the cap of ``kind``: checked
    before it is opened (a named pipe would block the open), opened without waiting and checked
    again (it may have been replaced in between)."""
    path = Path(path)
    check_input(path, kind)
    with os.fdopen(os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0)), "rb") as handle:
        _checked(path, os.fstat(handle.fileno()), kind)
        yield handle


def read_input(path: str | os.PathLike, kind: str) -> bytes:
    """The bytes of ``path``, a regular file within the cap of ``kind`` (:data:`INPUTS`), read in
    chunks, never more than the cap plus one byte (a file growing while it is read is refused
    as too large); a stop asked for (:mod:`.signals`) ends the read between chunks."""
    what, limit = INPUTS[kind]
    chunks: list[bytes] = []
    with open_input(path, kind) as handle:
        left = limit + 1
        while left > 0:
            chunk = handle.read(min(left, _CHUNK))
            signals.honour()
            if not chunk:
                break
            chunks.append(chunk)
            left -= len(chunk)
    if left <= 0:
        raise InputFileError(path, f"larger than {_size(limit)} (it grew while it was read): "
                                   f"no {kind} file is that large", f"give {what}")
    return b"".join(chunks)


def read_record(path: str | os.PathLike) -> bytes:
    """The bytes of one of the package's own records ``path`` (a lock, a manifest, a commit's
    journal), bounded as a ``record`` input (:func:`open_input`) but, unlike
    :func:`read_input`, read whole without honouring a stop asked for: the clean-ups that run
    after an interrupt (releasing a lock, completing a move) read them."""
    what, limit = INPUTS["record"]
    with open_input(path, "record") as handle:
        data = handle.read(limit + 1)
    if len(data) > limit:
        raise InputFileError(path, f"larger than {_size(limit)} (it grew while it was read): "
                                   "no record file is that large", f"give {what}")
    return data


def describe_os_error(error: OSError) -> str:
    """``error``'s cause in words, with what to do for a full disk or a reached limit."""
    reason = error.strerror or str(error)
    cause = _CAUSES.get(error.errno) if error.errno is not None else None
    return f"{reason} ({cause})" if cause else reason


def is_resource_error(error: BaseException) -> bool:
    """Whether ``error`` is a full disk, a reached file-size limit or too many open files."""
    return isinstance(error, OSError) and error.errno in _CAUSES


class FileWriteError(OSError):
    """Writing ``path`` failed; the message names the file and the cause (a full disk, a
    file-size limit, too many open files, ...)."""

    def __init__(self, path: str | os.PathLike, error: OSError, action: str = "write") -> None:
        super().__init__(error.errno, error.strerror, os.fspath(path))
        self.path = Path(path)
        self.message = f"cannot {action} {self.path}: {describe_os_error(error)}"

    def __str__(self) -> str:
        return self.message

    def __reduce__(self):
        return _rebuilt_write_error, (self.path, self.errno, self.strerror, self.message)


def _rebuilt_write_error(path: Path, number: int, reason: str, message: str) -> FileWriteError:
    error = FileWriteError(path, OSError(number, reason))
    error.message = message
    return error


def temporary_name(path: str | os.PathLike, pid: int | None = None) -> Path:
    """The temporary file ``NAME.<pid>.tmp`` beside ``path`` that a new version of it is written
    to (``pid``: of the writing process, this one by default)."""
    path = Path(path)
    return path.with_name(f"{path.name}.{os.getpid() if pid is None else pid}.tmp")


def temporary_owner(path: str | os.PathLike) -> int | None:
    """The PID in the name of a temporary file ``NAME.<pid>.tmp`` (:func:`temporary_name`), or
    None for any other name."""
    name = Path(path).name
    if not name.endswith(".tmp"):
        return None
    pid = name[: -len(".tmp")].rpartition(".")[2]
    return int(pid) if pid.isdigit() else None


def remove_stale(path: str | os.PathLike) -> list[Path]:
    """Remove the temporary files of ``path`` (``NAME.<pid>.tmp``, :func:`temporary_name`) that
    another writer, killed while writing it, left behind: those whose process no longer runs on
    this host and that were last written before this process started (a writer on another host
    sharing the folder is still writing if it wrote since). Returns the files removed."""
    path = Path(path)
    removed = []
    for entry in path.parent.glob(f"{glob.escape(path.name)}.*.tmp"):
        pid = temporary_owner(entry)
        if pid is None or pid == os.getpid():
            continue
        try:
            info = entry.lstat()
            stale = info.st_mtime < _STARTED and not locks.process_alive(pid)
            if stale and stat.S_ISREG(info.st_mode):
                entry.unlink()
                removed.append(entry)
        except OSError:  # (gone meanwhile, or not ours to remove)
            continue
    return removed


def _synced(path: Path) -> None:
    """Flush ``path`` (written by another writer) to disk."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


class Staging:
    """New versions of files, each written to its :func:`temporary_name` and moved into place by
    :meth:`commit` once all of them are complete; :meth:`discard` removes what is left. An
    ``OSError`` on the way is a :class:`FileWriteError` naming the destination, never the
    temporary file."""

    def __init__(self) -> None:
        self._files: dict[Path, Path] = {}
        self._unchecked: set[Path] = set()  # written by another writer: checked at the commit
        self._journal: Path | None = None  # of the set being moved into place

    def temporary(self, path: str | os.PathLike) -> Path:
        """The temporary file to write the new ``path`` to, by a writer that opens its file by
        name (give it the format explicitly: the name ends in ``.tmp``); :meth:`commit` refuses
        it if that writer left it missing or empty."""
        path = Path(path)
        recover_sets(path.parent)  # (a set cut short keeps its temporary files until moved)
        remove_stale(path)
        self._files[path] = temporary_name(path)
        self._unchecked.add(path)
        return self._files[path]

    def write(self, path: str | os.PathLike, write: Callable[[IO[bytes]], Any]) -> Path:
        """Call ``write(handle)`` on the temporary file of ``path``, flushed to disk; ``path``."""
        path = Path(path)
        tmp = self.temporary(path)
        try:
            with open(tmp, "wb") as handle:
                write(handle)
                handle.flush()
                os.fsync(handle.fileno())
        except FileWriteError:
            raise
        except OSError as error:
            raise FileWriteError(path, error) from None
        self._unchecked.discard(path)
        return path

    def commit(self) -> list[Path]:
        """Move every written file into place; returns the destinations. A temporary file that
        is missing or empty (a writer that failed without saying so) is a FileWriteError, and
        then nothing is moved; nor is anything after a stop asked for (:mod:`.signals`). Two
        files or more are moved as one set: their journal (:func:`recover_sets`) is written
        first and removed last, so that a move cut short (a kill, a failed rename) is completed
        by the next command that writes there, never left half old, half new."""
        signals.honour()
        for path in self._unchecked:
            tmp = self._files[path]
            if not (tmp.is_file() and tmp.stat().st_size > 0):
                raise FileWriteError(path, OSError(errno.EIO, "the writer produced no data"))
        for path in self._unchecked:
            try:
                _synced(self._files[path])
            except OSError as error:
                raise FileWriteError(path, error) from None
        if len(self._files) > 1:
            self._journal = _journal(next(iter(self._files)))
            pairs = [[os.fspath(tmp), os.fspath(path)] for path, tmp in self._files.items()]
            write_text(self._journal, json.dumps(pairs))
        for path, tmp in self._files.items():
            try:
                os.replace(tmp, path)
            except OSError as error:
                raise FileWriteError(path, error) from None
        if self._journal is not None:
            self._journal.unlink()
            self._journal = None
        written = list(self._files)
        self._files, self._unchecked = {}, set()
        return written

    def discard(self) -> None:
        """Remove the temporary files not moved into place; those of a set whose moves began
        (an interrupt between two) are moved now instead, and if that fails too, by the next
        command that writes there (:func:`recover_sets`)."""
        if self._journal is not None:
            try:
                _complete(self._journal)
            except (OSError, ValueError):
                pass  # (left to recover_sets)
        else:
            for tmp in self._files.values():
                tmp.unlink(missing_ok=True)
        self._files, self._unchecked, self._journal = {}, set(), None


@contextmanager
def staged() -> Iterator[Staging]:
    """A :class:`Staging` whose files are moved into place when the block ends normally, and
    removed when it raises (an interrupt included): the old files stay whole."""
    staging = Staging()
    try:
        yield staging
        staging.commit()
    finally:
        staging.discard()


def atomic_write(path: str | os.PathLike, write: Callable[[IO[bytes]], Any]) -> None:
    """Call ``write(handle)`` on a temporary file beside ``path``, then rename it to ``path``
    (:class:`Staging` of one file); an ``OSError`` on the way is a :class:`FileWriteError`
    naming ``path``."""
    with staged() as staging:
        staging.write(path, write)


# ---- sets of files committed as one unit, and the lock of each output name ---------------------
def _journal(first: Path, pid: int | None = None) -> Path:
    """The journal ``.NAME.<pid>.commit`` of a set of files moved into place, beside its first
    file ``NAME``: the JSON list of its ``[temporary, destination]`` pairs."""
    return first.with_name(f".{first.name}.{os.getpid() if pid is None else pid}.commit")


def recover_sets(folder: str | os.PathLike) -> list[Path]:
    """Complete the moves of every set of files in ``folder`` whose commit was cut short (its
    journal left by a process that is gone, or by this one outside a commit): every temporary
    file still there is moved into place, so that the set is the new one whole (its temporary
    files were complete before the journal was written). Returns the files moved. A journal of
    a live process (a commit in progress) is left alone."""
    moved: list[Path] = []
    for journal in sorted(Path(folder).glob(".*.commit")):
        pid = journal.name[: -len(".commit")].rpartition(".")[2]
        if not pid.isdigit() or (int(pid) != os.getpid() and locks.process_alive(int(pid))):
            continue
        moved += _complete(journal)
    return moved


def _complete(journal: Path) -> list[Path]:
    """Move every temporary file of the set in ``journal`` still there into place, then remove
    the journal; the files moved."""
    try:
        pairs = [(Path(tmp), Path(path)) for tmp, path in json.loads(read_record(journal))]
    except (OSError, ValueError, TypeError) as error:
        raise CorruptFileError(journal, f"the journal of a cut-short commit cannot be read "
                               f"({error})", "remove it (the files it names stay as they "
                               "are)") from None
    moved = []
    for tmp, path in pairs:
        if tmp.is_file():
            try:
                os.replace(tmp, path)
            except OSError as error:
                raise FileWriteError(path, error, "complete the cut-short move of") from None
            moved.append(path)
    journal.unlink()
    return moved


class OutputInUse(ValueError):
    """Another command is writing an output of the same name; ``record`` is its lock record."""

    def __init__(self, path: Path, lock: Path, record: dict) -> None:
        self.path, self.record = path, record
        super().__init__(
            f"{path} is being written by {locks.holder(record)}; wait for it to finish or choose "
            f"another name. If that command is over (e.g. its node was lost), remove {lock}")


def name_lock(path: str | os.PathLike) -> Path:
    """The lock file ``.NAME.lock`` of the output ``path``."""
    path = Path(path)
    return path.with_name(f".{path.name}.lock")


@contextmanager
def hold_names(paths: Sequence[str | os.PathLike]) -> Iterator[None]:
    """Hold the lock of each output name in ``paths`` (:func:`name_lock`; their folders made)
    while the block runs,
    two commands writing the same name being refused (:class:`OutputInUse`, naming the holder);
    cut-short commits in their folders completed first (:func:`recover_sets`)."""
    held: list[tuple[Path, dict]] = []
    try:
        for path in dict.fromkeys(Path(p) for p in paths):
            lock = name_lock(path)
            try:
                path.parent.mkdir(parents=True, exist_ok=True)
                held.append((lock, locks.acquire(lock)))
            except locks.Held as error:
                raise OutputInUse(path, lock, error.record) from None
            except OSError as error:
                raise FileWriteError(lock, error, "create the lock") from None
        for folder in dict.fromkeys(Path(p).parent for p in paths):
            recover_sets(folder)
        yield
    finally:
        for lock, record in held:
            locks.release(lock, record)


def commit_set(files: Mapping[str | os.PathLike, bytes | Callable[[IO[bytes]], Any]],
               *, lock: bool = True) -> list[Path]:
    """Write the files of ``files`` (path -> its bytes, or a function writing them to a binary
    handle) and move them into place as one unit (:meth:`Staging.commit`): an interruption
    leaves the old set or, once their moves began, the new set after :func:`recover_sets`,
    never a mixture. With ``lock``, under :func:`hold_names` (a command that holds the names for
    longer, through its work, passes ``lock=False``). Returns the destinations."""

    def writer(content: bytes | Callable[[IO[bytes]], Any]) -> Callable[[IO[bytes]], Any]:
        return content if callable(content) else lambda handle: handle.write(content)

    with hold_names(list(files)) if lock else nullcontext():
        with staged() as staging:
            for path, content in files.items():
                staging.write(path, writer(content))
    return [Path(p) for p in files]


class GuardedFile(io.RawIOBase):
    """A new binary file for h5py (``h5py.File(GuardedFile(path), "w")``) that stops writing at
    its first failed write and remembers the error (``failed``) instead of passing it on.

    From then on writes are discarded and reads return zeros, so HDF5 sees every operation
    succeed and can close its file cleanly; the writer checks :attr:`failed` after every
    operation (:meth:`check`) and raises :class:`FileWriteError`. (h5py crashes the interpreter
    when it flushes or closes a file whose write failed.)
    """

    def __init__(self, path: str | os.PathLike) -> None:
        super().__init__()
        self.path = Path(path)
        try:
            self._raw = open(self.path, "w+b", buffering=0)
        except OSError as error:
            raise FileWriteError(self.path, error, "create") from None
        self.failed: OSError | None = None
        self._position = 0

    def readable(self) -> bool:
        return True

    def writable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True

    def _fail(self, error: OSError) -> None:
        if self.failed is None:
            self.failed = error

    def seek(self, offset: int, whence: int = 0) -> int:
        if self.failed is None:
            try:
                self._position = self._raw.seek(offset, whence)
                return self._position
            except OSError as error:
                self._fail(error)
        self._position = offset if whence == 0 else self._position + offset
        return self._position

    def tell(self) -> int:
        return self._position

    def readinto(self, buffer: Any) -> int:
        size = memoryview(buffer).nbytes
        if self.failed is None:
            try:
                count = self._raw.readinto(buffer) or 0
                self._position += count
                return count
            except OSError as error:
                self._fail(error)
        memoryview(buffer).cast("B")[:] = bytes(size)
        self._position += size
        return size

    def write(self, data: Any) -> int:
        size = memoryview(data).nbytes
        if self.failed is None:
            try:
                view, done = memoryview(data).cast("B"), 0
                while done < size:  # a short write is retried: the next one gives the cause
                    written = self._raw.write(view[done:])
                    if not written:
                        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
                    done += written
                self._position += size
                return size
            except OSError as error:
                self._fail(error)
        self._position += size
        return size

    def truncate(self, size: int | None = None) -> int:
        if self.failed is None:
            try:
                return self._raw.truncate(size)
            except OSError as error:
                self._fail(error)
        return self._position if size is None else size

    def flush(self) -> None:
        if self.failed is None and not self._raw.closed:
            try:
                self._raw.flush()
            except OSError as error:
                self._fail(error)

    def check(self) -> None:
        """Raise :class:`FileWriteError` if a write has failed."""
        if self.failed is not None:
            raise FileWriteError(self.path, self.failed)

    def close(self) -> None:
        if not self._raw.closed:
            self._raw.close()
        super().close()


def write_npz(path: str | os.PathLike, meta: Mapping[str, Any], **arrays: np.ndarray) -> None:
    """Write ``arrays`` and the JSON-ready ``meta`` to an ``.npz`` file atomically."""
    text = json.dumps(meta, allow_nan=True)
    # (numpy >= 2.1 stubs read **arrays as possibly its keyword allow_pickle; numpy < 2.1 would
    # store allow_pickle=... as one more array, so it is not passed)
    atomic_write(
        path,
        lambda handle: np.savez(handle, meta=np.array(text), **arrays),  # type: ignore[arg-type]
    )


def write_text(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    data = text.encode()
    atomic_write(path, lambda handle: handle.write(data))


def read_npz(
    path: str | os.PathLike, required: tuple[str, ...] = ()
) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Read a file written by :func:`write_npz`: ``(meta, arrays)``; the arrays ``required`` must
    be there. Raises :class:`CorruptFileError` naming the file when it cannot be read back."""
    try:
        with open_input(path, "arrays") as handle, np.load(handle, allow_pickle=False) as data:
            if not hasattr(data, "files") or "meta" not in data.files:
                raise CorruptFileError(path, "not a parastokes array file (no 'meta' record)")
            meta = json.loads(str(data["meta"]))
            missing = [name for name in required if name not in data.files]
            if not isinstance(meta, dict) or missing:
                raise CorruptFileError(path, f"not a parastokes array file (missing {missing})")
            return meta, {k: data[k] for k in data.files if k != "meta"}
    except (CorruptFileError, InputFileError, FileNotFoundError):
        raise
    except (OSError, EOFError, ValueError, KeyError, zipfile.BadZipFile) as error:
        if isinstance(error, OSError) and is_resource_error(error):  # (the file is not at fault)
            raise FileWriteError(path, error, "read") from None
        # numpy reports a damaged or foreign file as any of these; its advice to load it "with
        # allow_pickle" does not apply (parastokes never writes pickles)
        reason = "not a NumPy array file" if "pickle" in str(error) else str(error)
        raise CorruptFileError(path, f"damaged or not written by parastokes ({reason})") from None
