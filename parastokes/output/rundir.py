"""Ownership of a run's output directory: one run at a time, nothing overwritten unasked, results
replaced whole.

- **Lock.** :func:`claim` creates ``DIR/.parastokes.lock`` with ``O_CREAT | O_EXCL`` (atomic on
  local and network file systems alike, unlike HDF5's file locking) and writes the owner's PID,
  host and start time into it. A second run on the same directory is refused with a message naming
  that PID and host. A lock whose process is gone (same host, PID dead or reused) is stale and is
  taken over; a lock from another host is never guessed about: the message says which file to
  remove once that run is known to be over.
- **No silent overwrite.** Without ``overwrite``, a directory holding a finished run
  (``summary.json``), an interrupted one (its resume state) or files that are not a run's is
  refused before anything is computed; ``resume`` continues an interrupted or finished run.
- **Whole results.** A run writes its results (trajectory, summary, figures, the demo's
  ``config.toml``) into ``DIR/.partial/`` and :meth:`RunDirectory.commit` moves them in only when
  all are complete, then removes the previous run's results that the new one does not have (stale
  figures). The resume state (``checkpoint.npz``, ``checkpoint.solves/``, ``reference.npz``,
  ``history.npz``) is written each file atomically: in place, or, for an ``--overwrite`` of a
  directory that holds a run, into ``DIR/.next/``, so that the old run stays whole and resumable
  until the new one commits (a new run refused by a check, interrupted, or blown up leaves it as
  it was; its own ``.next/`` is dropped). The commit is journalled (``.partial/COMMIT``, with the
  names of the new resume state): a commit cut short is completed by the next claim, so the
  directory holds either the old run whole or the new one whole. The partial results of a run
  that stops early are dropped (the next run writes them anew).

The commands that write beside or from a run (``flow``, ``movie``, ``tune``, ``plot``) claim their
files through the same rules (:func:`claim_files`): checked before any work (a directory, an
unwritable place, an existing file without ``--overwrite``); never one of a run's own files
(:func:`is_run_file`); the lock of a run directory they write into held while they work, and one
they read from refused while a run holds it; every file written to a temporary name and moved into
place whole (:class:`parastokes.core.files.Staging`), so that an interrupt, a full disk or a failing
writer leaves the previous file intact and no partial one.
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Collection, Iterator, Sequence
from contextlib import ExitStack, contextmanager
from pathlib import Path

from ..core import locks, signals
from ..core.files import (
    CorruptFileError,
    Staging,
    hold_names,
    read_record,
    recover_sets,
    staged,
    temporary_owner,
    write_text,
)

__all__ = [
    "DirectoryInUse", "RunDirectory", "RunDirectoryError", "check_files", "check_free", "claim",
    "claim_files", "is_run_directory", "is_run_file", "locked",
]

LOCK = ".parastokes.lock"
STAGING = ".partial"
NEXT = ".next"
MANIFEST = ".parastokes-results.json"
_COMMIT = "COMMIT"

#: The resume state of a run (written in place, atomically), and its last good state on blow-up.
STATE_FILES = (
    "checkpoint.npz", "checkpoint.solves", "reference.npz", "history.npz", "blowup.npz"
)
#: The results of a finished run.
RESULT_FILES = ("summary.json", "trajectory.h5", "trajectory.xdmf")
#: Inputs kept beside the results (the demo's configuration).
INPUT_FILES = ("config.toml",)
#: Figures of runs written before the results were listed in MANIFEST.
_OLD_FIGURES = tuple(
    f"{stem}.{fmt}"
    for stem in ("error_decay", "speedup_vs_error", "speedup_by_iteration", "structure")
    for fmt in ("png", "pdf")
)
#: The figures a run draws itself (``output.figures``; ``parastokes plot RUN`` draws them again),
#: by stem (``structure_<kind>`` too), and its own flow output (``output.flow_every``).
RUN_FIGURES = ("error_decay", "speedup_vs_error", "speedup_by_iteration", "gantt", "structure")
RUN_FLOW = ("flow.h5", "flow.xdmf", "flow.png")
#: The files that keep a run directory's books.
_BOOKS = (LOCK, LOCK + ".break", STAGING, NEXT, MANIFEST)


class RunDirectoryError(ValueError):
    """The output directory cannot be used (a file, unwritable, or holding a run not to touch)."""


class DirectoryInUse(RunDirectoryError):
    """Another run holds the directory's lock; ``owner`` is its lock record (pid, host, ...)."""

    def __init__(self, out: Path, owner: dict) -> None:
        self.owner = owner
        super().__init__(
            f"{out} is in use by {locks.holder(owner)}; wait for it to finish or choose "
            f"another --out. If that command is over (e.g. its node was lost), remove "
            f"{out / LOCK}"
        )


def _lock(out: Path) -> dict:
    """Create ``out/LOCK`` for this process (taking over a stale one); returns its record."""
    try:
        return locks.acquire(out / LOCK)
    except locks.Held as held:
        raise DirectoryInUse(out, held.record) from None


class RunDirectory:
    """A claimed output directory: ``path``, ``staging`` where the new results are written and
    ``state`` where the new resume state is."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.staging = path / STAGING
        #: Where the run writes its resume state: the directory itself, or ``NEXT`` in it for an
        #: ``--overwrite`` whose old run stays whole until the commit (:meth:`start`).
        self.state = path

    def _previous_results(self) -> set[str]:
        try:
            names = json.loads(read_record(self.path / MANIFEST))["files"]
            return {str(n) for n in names}
        except (OSError, ValueError, KeyError, TypeError):
            return set(RESULT_FILES) | set(_OLD_FIGURES)

    def entries(self) -> dict[str, list[str]]:
        """The directory's entries by role: ``results``, ``state``, ``foreign``."""
        names = {p.name for p in self.path.iterdir()} - set(_BOOKS)
        names = {n for n in names if not n.endswith(".tmp")}
        results = self._previous_results() | set(RESULT_FILES)
        known = results | set(STATE_FILES) | set(INPUT_FILES)
        return {
            "results": sorted(names & results),
            "state": sorted(names & set(STATE_FILES)),
            "foreign": sorted(names - known),
        }

    def check(self, *, resume: bool, overwrite: bool) -> None:
        """Refuse, before any work, a directory whose contents this run must not replace."""
        found = self.entries()
        finished = "summary.json" in found["results"]
        ours = finished or bool(found["state"])
        where = self.path
        if found["foreign"] and not overwrite and not (resume and ours):
            shown = ", ".join(found["foreign"][:5]) + (", ..." if len(found["foreign"]) > 5 else "")
            raise RunDirectoryError(
                f"{where} holds files that are not a parastokes run's ({shown}); choose a new or "
                "empty --out, or pass --overwrite to write this run's files beside them"
            )
        if resume or overwrite:
            return
        if finished:
            raise RunDirectoryError(
                f"{where} holds a finished run (summary.json); pass --overwrite to replace its "
                "results (they stay until the new run has completed), --resume to continue it, or "
                "choose another --out"
            )
        if found["state"]:
            raise RunDirectoryError(
                f"{where} holds an interrupted run ({', '.join(found['state'])}); pass --resume "
                "to continue it, or --overwrite to discard it and start afresh"
            )

    def recover(self) -> None:
        """Complete a commit that was cut short (by a kill or a power cut); drop the resume state
        of an ``--overwrite`` run that did not reach its commit (the run it was to replace stays
        whole, resumable)."""
        if (self.staging / _COMMIT).exists():
            self._roll_forward()
        shutil.rmtree(self.path / NEXT, ignore_errors=True)

    def start(self, *, replace: bool) -> None:
        """Make an empty staging directory for the new results (dropping an unfinished run's);
        with ``replace`` (``--overwrite`` of a directory holding a run), an empty ``NEXT`` for
        the new run's resume state too (:attr:`state`), so that the old run's stays until the
        commit."""
        shutil.rmtree(self.staging, ignore_errors=True)
        self.staging.mkdir()
        found = self.entries()
        if replace and (found["state"] or found["results"]):
            self.state = self.path / NEXT
            shutil.rmtree(self.state, ignore_errors=True)
            self.state.mkdir()

    def add_results(self, names: Sequence[str]) -> None:
        """List files written beside the results (``parastokes plot DIR``'s figures) among them,
        so that the next ``--overwrite`` replaces them with the rest (hold :func:`locked`)."""
        _write_names(self.path / MANIFEST, sorted(self._previous_results() | set(names)))

    def commit(self) -> list[str]:
        """Move every file of the staging directory into place, and the new resume state from
        :attr:`state` when it is not the directory itself (replacing the old run's, which is
        removed where the new run has none); remove the previous results that the new ones do
        not replace; returns the names of the new results. Journalled in ``STAGING/COMMIT``
        first, so a commit cut short is completed by the next claim (:meth:`recover`). Nothing
        moves after a stop was asked for (:func:`parastokes.core.signals.honour`)."""
        signals.honour()
        names = sorted(p.name for p in self.staging.iterdir() if not p.name.endswith(".tmp"))
        state = (None if self.state == self.path else
                 sorted(p.name for p in self.state.iterdir() if p.name in STATE_FILES))
        _write_names(self.staging / _COMMIT, names, state)
        self._roll_forward()
        signals.completed(f"the run's results are complete in {self.path} "
                          f"({', '.join(n for n in names if n != 'config.toml')})")
        return names

    def _roll_forward(self) -> None:
        record = self.staging / _COMMIT
        try:
            data = json.loads(read_record(record))
            names, state = list(data["files"]), data.get("state")
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as error:
            raise CorruptFileError(
                record, f"the record of an interrupted commit cannot be read ({error})",
                f"move the files of {self.staging} into {self.path} by hand, or remove "
                f"{self.staging} to keep the previous results",
            ) from None
        if state is not None:  # an --overwrite: the new resume state replaces the old one
            for name in STATE_FILES:
                new, old = self.path / NEXT / name, self.path / name
                if new.exists() or name not in state:  # (moved already: in state, new gone)
                    _remove(old)
                if new.exists():
                    os.replace(new, old)
        for name in names:
            if (self.staging / name).exists():
                os.replace(self.staging / name, self.path / name)
        results = [name for name in names if name not in INPUT_FILES]
        for name in self._previous_results() - set(results):
            (self.path / name).unlink(missing_ok=True)
        _write_names(self.path / MANIFEST, results)
        shutil.rmtree(self.path / NEXT, ignore_errors=True)
        shutil.rmtree(self.staging, ignore_errors=True)
        self.state = self.path


def _remove(path: Path) -> None:
    """Remove the file or directory (``checkpoint.solves``) ``path`` if it exists."""
    if path.is_dir():
        shutil.rmtree(path)
    else:
        path.unlink(missing_ok=True)


def _remove_orphans(path: Path, locked: bool = True) -> None:
    """Remove the temporary files (``NAME.<pid>.tmp``, :func:`parastokes.core.files.temporary_name`)
    that a process killed while writing left in ``path``: with its lock held (``locked``), every
    one but this process's (no other process writes there); else those of processes gone from
    this host and untouched for a minute (one of another host sharing the folder still
    writing)."""
    for entry in path.glob("*.tmp"):
        pid = temporary_owner(entry)
        if pid is None or pid == os.getpid() or not entry.is_file():
            continue
        old = locks.age(entry) > 6 * locks.BREAK_TIMEOUT
        if locked or (not locks.process_alive(pid) and old):
            entry.unlink(missing_ok=True)


def _write_names(path: Path, names: Sequence[str], state: Sequence[str] | None = None) -> None:
    """The record ``{"files": names}`` (the manifest, a commit's record, with the names of the
    new resume state, ``state``, for an ``--overwrite``), written atomically."""
    record: dict = {"files": list(names)} | ({} if state is None else {"state": list(state)})
    write_text(path, json.dumps(record))


def check_path(out: str | os.PathLike, shown: str | None = None) -> None:
    """:class:`RunDirectoryError` when ``out`` cannot become a writable directory (a file, under a
    file, in a folder that is not writable), without creating or locking anything: what a run
    checks before any work, ahead of :func:`claim`. ``shown``: how the message names the path
    (default ``--out OUT``)."""
    path = Path(out)
    if path.exists() and not path.is_dir():
        where = f"{shown}: {path}" if shown else f"--out {path}"
        raise RunDirectoryError(f"{where} is a file, not a directory; choose another --out")
    shown = shown or f"--out {path}"
    existing = path if path.exists() else next(p for p in path.absolute().parents if p.exists())
    if not existing.is_dir():
        raise RunDirectoryError(
            f"{shown}: cannot create the directory (Not a directory: {existing}); "
            "choose a path in a directory you can write to"
        )
    if not os.access(existing, os.W_OK | os.X_OK):
        raise RunDirectoryError(f"{shown}: {existing} is not writable; choose another --out")


def _directory(out: Path) -> None:
    """Make ``out`` (and its parents); a path that cannot be a writable directory is an error."""
    check_path(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        reason = error.strerror or str(error)
        raise RunDirectoryError(
            f"--out {out}: cannot create the directory ({reason}: {error.filename or out}); "
            "choose a path in a directory you can write to"
        ) from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise RunDirectoryError(f"--out {out}: the directory is not writable; choose another")


@contextmanager
def locked(out: str | os.PathLike) -> Iterator[RunDirectory]:
    """Hold the lock of the existing run directory ``out`` without running in it (to add
    figures to its results); :class:`DirectoryInUse` while a run holds it. A commit that was cut
    short is completed first, so what is read there is one run's results, never a mixture."""
    path = Path(out)
    if not path.is_dir():
        raise RunDirectoryError(f"{path} is not a directory: give a run's output directory")
    try:
        record = _lock(path)
    except OSError as error:
        raise RunDirectoryError(
            f"{path}: cannot write there ({error.strerror or error})"
        ) from None
    try:
        directory = RunDirectory(path)
        recover_sets(path)  # (a set of flow's or tune's files cut short: its files first)
        _remove_orphans(path)
        directory.recover()  # a commit cut short: its results whole, never a mixture
        yield directory
    finally:
        if locks.owner(path / LOCK) == record:
            (path / LOCK).unlink(missing_ok=True)


@contextmanager
def claim(out: str | os.PathLike, *, resume: bool, overwrite: bool) -> Iterator[RunDirectory]:
    """Own the directory ``out`` for one run (see the module docstring), checked before any work.

    Raises :class:`RunDirectoryError` (a ValueError: the command line exits with status 2) when
    ``out`` is a file, cannot be created or written, is in use by another run
    (:class:`DirectoryInUse`), or holds results this run must not replace.
    """
    if resume and overwrite:
        raise RunDirectoryError("--resume continues a run and --overwrite discards it: give one")
    path = Path(out)
    _directory(path)
    try:
        record = _lock(path)
    except OSError as error:
        raise RunDirectoryError(
            f"--out {path}: cannot write there ({error.strerror or error}); choose another"
        ) from None
    try:
        directory = RunDirectory(path)
        recover_sets(path)  # (a set of flow's or tune's files cut short: its files first)
        _remove_orphans(path)
        directory.recover()
        directory.check(resume=resume, overwrite=overwrite)
        directory.start(replace=overwrite)
        yield directory
    finally:
        if not (path / STAGING / _COMMIT).exists():  # an unfinished run's partial results
            shutil.rmtree(path / STAGING, ignore_errors=True)
            shutil.rmtree(path / NEXT, ignore_errors=True)
        if locks.owner(path / LOCK) == record:
            (path / LOCK).unlink(missing_ok=True)


# ---- the files of the commands that write beside or from a run ---------------------------------
def is_run_directory(path: str | os.PathLike) -> bool:
    """Whether ``path`` is a run's output directory (its lock, results, resume state or books)."""
    path = Path(path)
    markers = (LOCK, MANIFEST, STAGING, *RESULT_FILES, *STATE_FILES)
    return path.is_dir() and any((path / name).exists() for name in markers)


def is_run_file(name: str) -> bool:
    """Whether ``name`` is one of the files a run writes into its own directory: its results
    (with its figures and its own flow output), its resume state, its input and its books."""
    stem, _, suffix = name.rpartition(".")
    figure = suffix in ("png", "pdf") and (stem in RUN_FIGURES or stem.startswith("structure_"))
    own = (*RESULT_FILES, *STATE_FILES, *INPUT_FILES, *RUN_FLOW, *_BOOKS)
    return name in own or figure


def check_free(run: str | os.PathLike) -> None:
    """:class:`DirectoryInUse` when a live process holds the lock of the run directory ``run``
    (a command reads a run's results only when no run is replacing them)."""
    path = Path(run)
    owner = locks.owner(path / LOCK)
    if owner is not None and not locks.stale(owner):
        raise DirectoryInUse(path, owner)


def check_files(paths: Sequence[str | os.PathLike], *, overwrite: bool = True,
                regenerates: Collection[str] = (), option: str = "--out") -> list[Path]:
    """The files ``paths`` a command is to write, checked before any work (nothing is created):
    none a directory, each in a folder that exists or can be made and is writable, none an
    existing file unless ``overwrite``, and none one of a run's own files in its directory
    (:func:`is_run_file`) but the names in ``regenerates`` (``plot RUN`` draws its figures
    again). :class:`RunDirectoryError` (exit 2) names the file and what to change."""
    found = [Path(p) for p in paths]
    for path in found:
        if path.is_dir():
            raise RunDirectoryError(f"{option} {path} is a directory: give a file name, e.g. "
                                    f"{path / 'out'}")
        check_path(path.parent, f"{option} {path}")
        if is_run_directory(path.parent) and is_run_file(path.name) and \
                path.name not in regenerates:
            raise RunDirectoryError(
                f"{option} {path}: {path.name} is a file of the run in {path.parent}, which no "
                f"other command replaces; choose another {option} (a new name, or another "
                "directory)")
    existing = [str(p) for p in found if p.exists()]
    if existing and not overwrite:
        raise RunDirectoryError(f"{option} {found[0]}: {', '.join(existing)} already exist(s); "
                                f"pass --overwrite to replace them, or choose another {option}")
    return found


@contextmanager
def claim_files(paths: Sequence[str | os.PathLike], *, overwrite: bool = True,
                reads: Sequence[str | os.PathLike] = (), regenerates: Collection[str] = (),
                option: str = "--out") -> Iterator[Staging]:
    """Own the files ``paths`` that a command writes (``flow``, ``movie``, ``tune``, ``plot``),
    checked before any work: :func:`check_files`; the lock of every run directory among their
    folders held until the block ends (:class:`DirectoryInUse` if a run holds it), elsewhere the
    lock of each file's name (:func:`parastokes.core.files.hold_names`: a second command writing
    the same name is refused, naming the first), and the run directories ``reads`` (those the
    command reads) refused while a run holds them (:func:`check_free`). Yields the
    :class:`~parastokes.core.files.Staging` to write them through: they are moved into place as
    one set when the block ends normally (journalled: a move cut short is completed at once or by
    the next command writing there; and listed with the results of a run directory they are in,
    so that its next ``--overwrite`` replaces them), and removed when it raises, so the previous
    files stay whole."""
    found = check_files(paths, overwrite=overwrite, regenerates=regenerates, option=option)
    folders = list(dict.fromkeys(path.parent for path in found))
    with ExitStack() as stack:
        runs: dict[Path, RunDirectory] = {}
        for folder in folders:
            if is_run_directory(folder):
                runs[folder] = stack.enter_context(locked(folder))
            else:
                _directory(folder)
                stack.enter_context(hold_names([p for p in found if p.parent == folder]))
                _remove_orphans(folder, locked=False)
        held = {folder.resolve() for folder in runs}
        for read in reads:
            if Path(read).resolve() not in held:
                check_free(read)
        with staged() as staging:
            yield staging
        for folder, directory in runs.items():
            directory.add_results([p.name for p in found if p.parent == folder and p.exists()])
