"""One run of a configuration: the serial fine solution, Parareal (Algorithm 1), or both, with all
outputs (summary.json, trajectory.h5 + .xdmf, figures) in one directory. Used by the CLI.

The directory is owned by the run (:mod:`parastokes.output.rundir`: a lock naming PID and host, no
silent overwrite, results written to ``DIR/.partial/`` and moved into place whole when the run has
completed). Every resume file carries the run's identity (:func:`identity`: the resolved model,
time, fine, coarse and slice settings, the mode and the package version); ``--resume`` with any
difference is refused, naming the keys.

Parareal reports every iteration through ``parareal.run``'s ``on_iteration`` hook: the final
positions X^k at T_N of every iteration are saved (so η^k and η̃^k of eq. 34 can be recomputed from
the saved file) and reported live; ``--resume`` after an interruption continues from Parareal's
checkpoint. Files in the output directory while a run is in progress:

- ``checkpoint.npz``: Parareal's checkpoint (removed at the end when ``parareal.checkpoint`` is
  false);
- ``reference.npz``: the serial fine solution at T_0..T_n and its wall time, written after every
  slice n (``--resume`` continues the serial run after the last saved slice, bit for bit);
- ``history.npz``: X^k at T_N and the elapsed wall time after every iteration;
- ``blowup.npz``: after a numerical blow-up, the last good state, its time and which solver failed.
"""

from __future__ import annotations

import errno
import itertools
import logging
import math
import os
import platform
import time
from pathlib import Path
from typing import Any, Protocol

try:
    import resource
except ImportError:  # (not on Windows)
    resource = None  # type: ignore[assignment]

import numpy as np

from .. import __version__, integrate, parareal
from ..config import Config, ConfigError, Resolved, Setup, preflight, resolved_dict
from ..config.checks import estimated_fine_seconds
from ..core import files
from ..core.contracts import StepFailure, System
from ..core.files import CorruptFileError, write_text
from ..integrate import BlowUpError
from ..output import rundir
from ..output import trajectory as io
from ..parallel import SerialExecutor, run_labelled
from ..parareal import checkpoint as ckpt
from ..parareal.speedup import schedule_speedups
from . import session

__all__ = [
    "BLOWUP",
    "CHECKPOINT",
    "HISTORY",
    "REFERENCE",
    "Reporter",
    "ReporterLike",
    "execute",
    "fine_identity",
    "identity",
    "speedup_table",
]

logger = logging.getLogger(__name__)

CHECKPOINT = "checkpoint.npz"
REFERENCE = "reference.npz"
HISTORY = "history.npz"
BLOWUP = "blowup.npz"
SUMMARY = "summary.json"
TRAJECTORY = "trajectory.h5"


class ReporterLike(Protocol):
    """What :func:`execute` reports to: a :class:`Reporter`, or any object with its methods (the
    CLI's console)."""

    def note(self, text: str) -> None: ...

    def start(self, what: str, total: int) -> None: ...

    def expect(self, seconds: float) -> None: ...

    def advance(self) -> None: ...

    def finish(self) -> None: ...

    def iteration(self, k: int, increment: float, error: float | None, elapsed: float) -> None: ...


class Reporter:
    """Receives progress from :func:`execute`; this base class stays silent (see the CLI's)."""

    def note(self, text: str) -> None:
        """A line of information."""

    def start(self, what: str, total: int) -> None:
        """A phase of ``total`` steps begins: ``"serial"`` slices or ``"parareal"`` iterations
        (those still to do: a resumed run counts only what is left)."""

    def expect(self, seconds: float) -> None:
        """An estimate of the wall time of one step of the current phase (for an ETA)."""

    def advance(self) -> None:
        """One step of the current phase is done."""

    def finish(self) -> None:
        """The current phase is over."""

    def iteration(self, k: int, increment: float, error: float | None, elapsed: float) -> None:
        """Iteration k of Parareal finished: η̃^k, η^k (None without reference), wall time so
        far."""


def _flatten(prefix: str, value: Any, out: dict[str, Any]) -> None:
    if isinstance(value, dict):
        for key, item in value.items():
            _flatten(f"{prefix}.{key}" if prefix else key, item, out)
    else:
        out[prefix] = value


def identity(cfg: Config) -> dict[str, Any]:
    """What determines the iterates, by key path: the model, time, fine and coarse sections,
    ``parareal.n_slices``, ``run.mode`` and the package version (``version``).

    Keys that only say when to stop or where to run (``parareal.tol``, ``max_iterations``,
    ``execution``, ``output``) are left out: ``--resume`` may change them (e.g. to run more
    iterations).
    """
    return _identity(cfg.model_dump(mode="json"), __version__)


def _identity(dumped: dict[str, Any], version: str) -> dict[str, Any]:
    """:func:`identity` of a configuration's ``model_dump(mode="json")`` (as a run's summary
    stores it) and the package ``version``."""
    sections = {key: dumped[key] for key in ("model", "time", "fine", "coarse")}
    sections["parareal"] = {"n_slices": dumped["parareal"]["n_slices"]}
    sections["run"] = {"mode": dumped["run"]["mode"]}
    sections["coarse"] = {k: v for k, v in sections["coarse"].items()
                          if k != "max_weight_sum"}  # a safety bound, not a setting of the solver
    flat: dict[str, Any] = {}
    _flatten("", sections, flat)
    return {**flat, "version": version}


def fine_identity(cfg: Config) -> dict[str, Any]:
    """What determines the serial fine solution (the reference file): :func:`identity` without the
    coarse solver and the run mode, so runs that differ only in their coarse solver can share one
    reference (``reference.npz`` copied from one run directory into another is accepted)."""
    fine = ("model.", "time.", "fine.", "parareal.n_slices", "version")
    coarse = "model.coarse_bodies"  # a scene's choice for G's grid (Scene.coarse_bodies)
    return {k: v for k, v in identity(cfg).items() if k.startswith(fine) and k != coarse}


def _same_run(path: Path, saved: Any, now: dict[str, Any]) -> None:
    """Refuse to resume from ``path`` (written with identity ``saved``) unless it matches ``now``:
    a :class:`ConfigError` names every differing key."""
    if not isinstance(saved, dict):
        raise CorruptFileError(
            path,
            "written by another version of parastokes (no run identity)",
            "resume with that version, or pass --overwrite to start afresh",
        )
    found = ckpt.differences({k: v for k, v in saved.items() if k != ckpt.PROBLEM}, now)
    if found:
        hint = (
            "continues only the same configuration: undo the change, pass --overwrite to "
            "discard the run in that directory, or choose another --out"
        )
        issues = [(key, f"{new!r} now, {old!r} in the run to resume") for key, old, new in found]
        raise ConfigError([*issues, ("--resume", hint)], f"{path} (the run to resume)")


def _check_resumable(out: Path, cfg: Config, resume: bool) -> None:
    """Before any work: every resume file in ``out`` is readable and of this run (the reference:
    of its fine problem, :func:`fine_identity`; the others: of the whole run, :func:`identity`),
    and with ``resume`` the finished run's ``summary.json`` too (its results are replaced: by
    this run's only if it is the same run, even when its resume files are gone)."""
    if resume and (out / SUMMARY).exists():
        summary = io.read_summary(out / SUMMARY)
        try:
            saved = _identity(summary["config"], summary["versions"]["parastokes"])
        except (KeyError, TypeError) as error:
            raise CorruptFileError(out / SUMMARY, f"not a run's summary (no {error})",
                                   "pass --overwrite to replace that run") from None
        _same_run(out / SUMMARY, saved, identity(cfg))
    for name, key in ((REFERENCE, fine_identity(cfg)), (HISTORY, identity(cfg)),
                      (CHECKPOINT, identity(cfg))):
        path = out / name
        if path.exists():
            meta = io.load_arrays(path)[0]
            _same_run(path, meta.get("key"), key)
            if name == CHECKPOINT:
                _stops_before(path, meta, cfg)


def _stops_before(path: Path, meta: dict[str, Any], cfg: Config) -> None:
    """Refuse to resume from the checkpoint ``path`` (its ``meta``) when the stopping rule of
    ``cfg`` would have stopped before the iteration it holds: a lower ``max_iterations`` or a
    looser ``tol`` met at an earlier iteration. Only the last iterate is kept, so the run cannot
    go back to that iteration (finished or interrupted alike); a ConfigError says what to do."""
    try:
        done = int(meta["iteration"])
        increments = [float(value) for value in meta["increments"]]
    except (KeyError, TypeError, ValueError):
        return  # (read again, and named if damaged, when Parareal loads it)
    p = cfg.parareal
    met = next((k for k, value in enumerate(increments, 1) if value < p.tol), None)
    issues = []
    if p.max_iterations is not None and done > p.max_iterations:
        issues.append(("parareal.max_iterations",
                       f"{p.max_iterations} now, but the run to resume has done {done} iterations"))
    if met is not None and met < done:
        issues.append(("parareal.tol", f"{p.tol:g} now: met after iteration {met} (η̃ = "
                                       f"{increments[met - 1]:.3g}), but the run to resume has "
                                       f"done {done} iterations"))
    if issues:
        issues.append(("--resume", f"{path} keeps only the iterate of iteration {done}, so the run "
                                   f"cannot stop earlier: keep parareal.max_iterations >= {done} "
                                   "and a tol not met before it (that run's result is then "
                                   "reported as it is), or pass --overwrite to run it again with "
                                   "the new rule"))
        raise ConfigError(issues, f"{path} (the run to resume)")


def _blow_up_note(out: Path, error: BlowUpError, where: str, fix: str, step: float) -> str:
    """Save the last good state of a blow-up to ``out/BLOWUP`` (with the step of the solver that
    failed, ``step``, for :func:`_same_time`); the note that says so."""
    io.save_arrays(
        out / BLOWUP,
        {"where": where, "t": error.t, "step": error.step, "monitor": error.monitor, "dt": step},
        last_state=error.last_state,
    )
    taken = "" if where.startswith("the correction") else f" (step {error.step} of that solve)"
    return (
        f"{where} blew up at t = {error.t:.10g}{taken}; the last good state is in "
        f"{out / BLOWUP}; {fix}"
    )


def _previous_blow_up(out: Path) -> dict[str, Any] | None:
    """The record of the blow-up of an earlier run in ``out`` (kept through ``--overwrite``
    until a run completes), or None."""
    try:
        meta, _ = io.load_arrays(out / BLOWUP)
    except (OSError, ValueError):
        return None
    return meta


def _solver_step(cfg: Config, resolved: Resolved, label: str) -> float:
    """The step of the solver a blow-up of the solve ``label`` happened in."""
    fine = "fine solve" in label or label == "serial"
    return float(resolved.fine_dt if fine else resolved.coarse_dt)


def _height_keys(cfg: Config) -> str:
    """The keys that say how far the bodies start from the wall, by kind."""
    model = cfg.model
    if model.kind == "scene":
        return "the bodies' height, position or center ([[bodies]])"
    for key in ("height", "position", "center"):
        if key in type(model).model_fields:
            return f"model.{key}" + (" (its z)" if key != "height" else "")
    return "the body's initial position"


def _smaller_step_passes(setup: Setup, error: BlowUpError, step: float) -> bool:
    """Whether the fine scheme with a step 10 times smaller than ``step`` carries the last good
    state of ``error`` through the time of two such steps without a blow-up: then the step, not
    the model, drove the body into the wall (a probe of 20 small steps)."""
    system, x = setup.system, error.last_state
    if np.shape(x) != np.shape(system.initial_state()):
        return False  # (a coarser grid's state)
    start = error.t - step
    try:
        integrate.run(system, x, start, start + 2 * step, setup.config.fine.scheme, step / 10)
    except (BlowUpError, StepFailure, ValueError, FloatingPointError):
        return False
    return True


def _near_wall(setup: Setup, state: np.ndarray) -> str | None:
    """Why a blow-up at ``state`` is the body reaching the wall z = 0 (its lowest point closer to
    the wall than the blob size ε, where the regularised kernels stop resolving the gap), else
    None."""
    r = setup.resolved
    scale = r.epsilon if math.isfinite(r.epsilon) else r.grid_spacing
    if not getattr(setup.system, "wall", False) or not math.isfinite(scale):
        return None
    try:
        lowest = float(np.min(np.asarray(setup.system.positions(state))[:, 2]))
    except (ValueError, IndexError):
        return None
    if not lowest < scale:
        return None
    return (
        f"a body is at the wall: its lowest point is {lowest:.3g} above z = 0, closer than the "
        f"blob size ε = {scale:.3g}, where the regularised flow no longer keeps it off; it gets "
        "there at this time whatever the step (a step 10 times smaller meets the wall too), so "
        f"a smaller step does not help: start it farther from the wall "
        f"({_height_keys(setup.config)}), end the run before (time.t1), or change the forces "
        "that drive it there"
    )


def _same_time(previous: dict[str, Any] | None, error: BlowUpError, where: str, step: float,
               span: float) -> str | None:
    """A note when the earlier run in the directory blew up in the same solver at (about) the
    same time with another step: the time does not move with the step, so the step is not the
    cause."""
    if not previous or previous.get("where") != where:
        return None
    try:
        t_before, step_before = float(previous["t"]), float(previous["dt"])
    except (KeyError, TypeError, ValueError):
        return None
    changed = max(step, step_before) / min(step, step_before) >= 1.2
    if not (changed and abs(error.t - t_before) <= 0.05 * span):
        return None
    return (
        f"the run before blew up there too, at t = {t_before:.6g} with a step of "
        f"{step_before:.3g} (now t = {error.t:.6g} with {step:.3g}): the time does not move with "
        "the step, so the step is not the cause; look at the model (a body reaching the wall, "
        "forces too strong for it)"
    )


def _advice(setup: Setup, label: str, error: BlowUpError, where: str,
            previous: dict[str, Any] | None) -> str:
    """What to change after a blow-up of the solve ``label`` (:func:`_fix`), or why the step is
    not the cause (:func:`_near_wall`, :func:`_same_time`)."""
    cfg = setup.config
    span = cfg.time.t1 - cfg.time.t0
    step = _solver_step(cfg, setup.resolved, label)
    if " returned " in error.reason:  # a body's own method at the (finite) last good state
        return ("the body's own function named above gives non-finite values, so a smaller step "
                "does not help: fix that function (or the values it is given)")
    wall = _near_wall(setup, error.last_state)
    solve = "solve" in label or label == "serial"  # (not a correction or combination)
    if wall is not None and solve and _smaller_step_passes(setup, error, step):
        wall = None  # the step drove it there: a smaller one is the fix
    found = [note for note in (wall, _same_time(previous, error, where, step, span)) if note]
    return "; ".join(found) if found else _fix(cfg, label, error.reason)


def _fix(cfg: Config, label: str, reason: str = "") -> str:
    """What to change after a blow-up of the solve named ``label`` (``reason``: the error's)."""
    fine = "fine solve" in label or label == "serial"
    if "step size" in reason:  # adaptive steps shrank to nothing
        return ("loosen fine.rtol/fine.atol, or use fixed steps (no rtol) to see where the "
                "body fails")
    if "linear solve failed" in reason:
        which = "fine.dt" if fine else "the coarse step"
        return (f"reduce {which}, or use the scheme ros2 (a direct solve on the approximate "
                "Jacobian, no GMRES iterations to fail)")
    if fine:
        return f"reduce fine.dt (now {cfg.fine.dt:g}) or use a more stable fine.scheme"
    if cfg.coarse.kind == "hodmd":
        return ("reduce the steps of the coarse solvers (coarse.g1 and coarse.g2: their dt or "
                "dt_ratio), or use a more stable scheme for them")
    return (
        "reduce the coarse step (coarse.dt_ratio or coarse.dt), or choose Lagrange nodes at which "
        f"the coarse scheme ({getattr(cfg.coarse, 'scheme', cfg.coarse.kind)}) is stable at that "
        "step"
    )


def _blow_up(error: BaseException) -> tuple[BlowUpError, str] | None:
    """The BlowUpError inside ``error`` (a TaskError's ``original`` or a cause) and the label of
    the task that raised it."""
    label = ""
    seen: set[int] = set()
    item: BaseException | None = error
    while item is not None and id(item) not in seen:
        seen.add(id(item))
        if isinstance(item, BlowUpError):
            return item, label
        label = getattr(item, "label", label)
        item = getattr(item, "original", None) or item.__cause__
    return None


def _frame_indices(n_slices: int, every: int) -> list[int]:
    """Slice boundaries written as frames: every ``every``-th, and always the last."""
    return sorted(set(range(0, n_slices + 1, every)) | {n_slices})


def _inner_frames(
    fine: Any, t_start: float, t_end: float, x: np.ndarray, parts: int
) -> np.ndarray:
    """The states at the ``parts - 1`` equally spaced times inside ``[t_start, t_end]``, by fine
    solves chained from ``x`` (the frames inside a slice; equal to the run's states up to
    round-off, since every solve projects its ends)."""
    ends = np.linspace(t_start, t_end, parts + 1)
    states = []
    for a, b in itertools.pairwise(ends[:-1]):
        x = fine(a, b, x)
        states.append(x)
    return np.asarray(states)


def _frame_plan(setup: Setup) -> tuple[list[int], int]:
    """The slice boundaries written as frames, and ``parts``: each slice's frames inside it plus
    one (1: none inside), as ``output.every`` asks."""
    every, steps = setup.config.output.every, setup.resolved.fine_steps
    frames = _frame_indices(setup.config.parareal.n_slices, max(1, (every or steps) // steps))
    return frames, steps // every if every is not None and every < steps else 1


def _check_room(setup: Setup, writer: io.TrajectoryWriter) -> None:
    """Refuse, before any work, a trajectory whose frames alone exceed the file-size limit
    (``ulimit -f``) or the free space where it is written: otherwise the run would fail at its
    end, when it writes them (a FileWriteError then)."""
    frames, parts = _frame_plan(setup)
    runs = 2 if setup.config.run.mode == "both" else 1
    count = runs * (len(frames) + (parts - 1) * setup.config.parareal.n_slices)
    columns = sum(body.rows * (3 + sum(c.stop - c.start for c in body.vectors.values()))
                  for body in writer.layout)
    # its header as written, and the frames' data: a lower bound on the file's size
    needed = writer.path.stat().st_size + 8.0 * count * columns
    room: list[tuple[int, str, float]] = []
    if resource is not None:
        limit = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
        if limit != resource.RLIM_INFINITY:
            room.append((errno.EFBIG, f"the file size limit is {limit / 1e6:.3g} MB", limit))
    try:
        found = os.statvfs(writer.path.parent)
    except (OSError, AttributeError):  # (a file system, or a system, that does not say)
        found = None
    if found is not None:
        free = float(found.f_bavail * found.f_frsize)
        room.append((errno.ENOSPC, f"{free / 1e6:.3g} MB are free on its file system", free))
    for number, what, size in room:
        if needed > size:
            reason = f"its {count} frames need at least {needed / 1e6:.3g} MB, but {what}"
            raise files.FileWriteError(writer.path, OSError(number, reason))


def _append_frames(
    writer: io.TrajectoryWriter,
    run: str,
    running: session.Session,
    times: np.ndarray,
    states: np.ndarray,
) -> None:
    """Write the frames of ``states`` (at the slice boundaries ``times``) as ``output.every``
    asks: every m-th boundary, or every boundary and the frames inside the slices."""
    setup = running.setup
    n_slices = len(times) - 1
    frames, parts = _frame_plan(setup)
    inner: dict[int, np.ndarray] = {}
    if parts > 1:
        slices = range(1, n_slices + 1)
        values = run_labelled(
            running.executor or SerialExecutor(),
            _inner_frames,
            [(setup.fine, times[n - 1], times[n], states[n - 1], parts) for n in slices],
            [f"frames inside slice {n} ({run})" for n in slices],
        )
        inner = dict(zip(slices, values, strict=True))
    for n in range(n_slices + 1):
        if n in frames:
            writer.append(run, times[n], states[n])
        if n + 1 in inner:
            inside = np.linspace(times[n], times[n + 1], parts + 1)[1:-1]
            for t, state in zip(inside, inner[n + 1], strict=True):
                writer.append(run, t, state)


def _slice_seconds(setup: Setup) -> float:
    """A rough estimate of one fine solve over a slice (for the progress bars' ETA)."""
    r = setup.resolved
    return estimated_fine_seconds(setup.config.fine.scheme, r.fine_steps, r.n_points)


# ---- the serial fine run ---------------------------------------------------------------------
def _serial(
    setup: Setup, x0: np.ndarray, times: np.ndarray, out: Path, key: dict, reporter: ReporterLike,
    previous: dict[str, Any] | None = None,
) -> tuple[np.ndarray, float]:
    """The serial fine solution F(T_n, T_0, x0) at every T_n (as ``parareal.serial_solution``) and
    its wall time. Saved to ``out/REFERENCE`` after every slice, and continued from there when
    that file holds the same fine problem (``key``, :func:`fine_identity`), so an interrupted
    serial run loses at most a slice and a finished one can serve other runs of that problem."""
    path = out / REFERENCE
    n_slices = len(times) - 1
    states = np.full((n_slices + 1, *x0.shape), np.nan)
    states[0] = x0
    done, wall = 0, 0.0
    if path.exists():
        meta, arrays = io.load_arrays(path, required=("states",))
        try:
            done, wall = int(meta["done"]), float(meta["wall_time"])
            states[: done + 1] = arrays["states"][: done + 1]
        except (KeyError, TypeError, ValueError) as error:
            raise CorruptFileError(path, f"an incomplete serial run ({error!r})") from None
        if done == n_slices:
            reporter.note(f"serial fine solution reloaded from {path.name}")
            return states, wall
        reporter.note(f"serial fine run resumed after slice {done} of {n_slices}")
    reporter.start("serial", n_slices - done)
    reporter.expect(_slice_seconds(setup))
    accepted = rejected = 0
    for n in range(done + 1, n_slices + 1):
        start = time.perf_counter()
        try:
            result = setup.fine.run(times[n - 1], times[n], states[n - 1])
            states[n] = result.state
            accepted, rejected = accepted + result.n_steps, rejected + result.n_rejected
        except BlowUpError as error:
            cfg = setup.config
            where = f"the fine solver F ({cfg.fine.scheme}) in slice {n} of the serial fine run"
            fix = _advice(setup, "serial", error, where, previous)
            error.add_note(_blow_up_note(out, error, where, fix, cfg.fine.dt))
            raise
        wall += time.perf_counter() - start
        io.save_arrays(path, {"key": key, "done": n, "wall_time": wall}, states=states)
        reporter.advance()
    reporter.finish()
    if setup.config.fine.rtol is not None:
        reporter.note(f"serial fine run: adaptive steps ({setup.config.fine.scheme}, rtol "
                      f"{setup.config.fine.rtol:g}): {accepted} accepted, {rejected} rejected")
    return states, wall


# ---- Parareal --------------------------------------------------------------------------------
def _parareal(
    running: session.Session,
    x0: np.ndarray,
    times: np.ndarray,
    reference: np.ndarray | None,
    out: Path,
    key: dict,
    reporter: ReporterLike,
    previous: dict[str, Any] | None = None,
) -> tuple[parareal.PararealResult, io.HistoryRecord]:
    """Parareal with the history of an interrupted run in ``out`` (if any) carried on.

    After every iteration (``parareal.run``'s ``on_iteration``) the final positions X^k at T_N and
    the elapsed time are appended to ``history.npz`` and reported; the checkpoint in ``out`` lets
    an interrupted run resume where it stopped.
    """
    setup, executor = running.setup, running.executor
    cfg, system = setup.config, setup.system
    history_path = out / HISTORY
    finals: list[np.ndarray] = []
    elapsed: list[float] = []
    checkpoint = out / CHECKPOINT
    if history_path.exists():
        _, arrays = io.load_arrays(history_path, required=("final_positions", "elapsed"))
        finals, elapsed = list(arrays["final_positions"]), list(arrays["elapsed"])

    def record(report: parareal.IterationReport) -> None:
        k = report.iteration
        del finals[k - 1 :], elapsed[k - 1 :]
        missing = k - 1 - len(finals)  # > 0 only if an interrupt fell between checkpoint and here
        finals.extend([np.full_like(system.positions(x0), np.nan)] * missing)
        elapsed.extend([np.nan] * missing)
        finals.append(system.positions(report.final_state))
        elapsed.append(report.elapsed)
        io.save_arrays(
            history_path,
            {"key": key},
            final_positions=np.asarray(finals),
            elapsed=np.asarray(elapsed),
        )
        reporter.iteration(report.iteration, report.increment, report.error, report.elapsed)
        reporter.advance()

    p = cfg.parareal
    reporter.start("parareal", max(p.max_iterations - len(finals), 0))  # (resumed: what is left)
    workers = getattr(executor, "workers", 1)
    reporter.expect(_slice_seconds(setup) * -(-p.n_slices // workers))  # one parallel sweep
    try:
        result = parareal.run(
            setup.fine,
            setup.coarse,
            x0,
            times[0],
            times[-1],
            p.n_slices,
            stopping=parareal.Stopping(tol=p.tol, max_iterations=p.max_iterations),
            checkpoint=parareal.Checkpoint(checkpoint, identity=key),
            reporting=parareal.Reporting(on_iteration=record),
            executor=executor,
            reference=reference,
            project=system.project,
            positions=system.positions,
            allow_oversubscribe=cfg.execution.allow_oversubscribe
            or cfg.execution.executor == "serial",
            schedule=p.schedule,
        )
    except Exception as error:
        found = _blow_up(error)
        if found is not None:
            blow, label = found
            where = f"the {label or 'solve'} (Parareal)"
            fix = _advice(setup, label, blow, where, previous)
            step = _solver_step(cfg, setup.resolved, label)
            error.add_note(_blow_up_note(out, blow, where, fix, step))
        raise
    reporter.finish()
    if len(elapsed) >= result.iterations > 0:  # the last one as the report's total (same speedup)
        elapsed[result.iterations - 1] = result.timings.total
    history = io.HistoryRecord(
        increments=result.increments,
        errors=result.errors,
        final_positions=finals[: result.iterations],
        elapsed=elapsed[: result.iterations],
        timings=result.timings.to_dict(),
    )
    return result, history


# ---- summary ---------------------------------------------------------------------------------
def _speedups(
    result: parareal.PararealResult, elapsed: list[float], serial_time: float | None
) -> dict[str, Any]:
    """Eq. 14 measured and theoretical and eq. 15, for the run and after each iteration k."""
    speedups = result.speedup(serial_time)
    values: dict[str, Any] = dict(speedups)
    n = result.n_slices
    g, f = speedups["gamma_G"], speedups["gamma_F"]
    ks = list(range(1, result.iterations + 1))
    models = [schedule_speedups(speedups["schedule"], g, f, k, n) for k in ks]
    values["by_iteration"] = {
        "iterations": ks,
        "measured": [speedups["serial_time"] / t for t in elapsed],
        "theoretical": [theoretical for theoretical, _ in models],
        "bound": [bound for _, bound in models],
    }
    values["n_slices"] = n
    return values


def _monitor(system: System, states: np.ndarray) -> dict[str, float]:
    """The stability monitor (rod length / vesicle area change) over the slice boundaries."""
    values = [system.monitor(state) for state in states]
    return {"max": float(max(values)), "final": float(values[-1]), "limit": system.monitor_limit}


def _writer(cfg: Config, setup: Setup, conf: dict[str, Any], out: Path) -> io.TrajectoryWriter:
    """The trajectory writer of the layout that the body's kind gives (registry)."""
    layout = cfg.model.layout(setup.system, cfg.output.frames, cfg.output.tracked_points)
    return io.TrajectoryWriter(out / TRAJECTORY, layout, config=conf)


def execute(
    cfg: Config,
    resolved: Resolved,
    out: str | Path,
    *,
    resume: bool = False,
    overwrite: bool = False,
    reporter: ReporterLike | None = None,
    files: dict[str, str] | None = None,
) -> dict[str, Any]:
    """Run ``cfg`` into the directory ``out``; returns the summary (also written to summary.json).

    The directory is claimed first (:func:`parastokes.output.rundir.claim`), before any work: a
    file, an unwritable path, a directory in use by another run, or one holding a finished,
    interrupted or foreign run (unless ``resume`` or ``overwrite``) raises a ValueError that says
    what to do. With ``resume`` the serial solution and the Parareal checkpoint found there are
    continued; a run of another configuration is refused (:class:`ConfigError` naming the keys).
    ``files`` (name -> text, the demo's ``config.toml``) are written into it once that check has
    passed. Results go to the directory whole once complete; figures are drawn last
    (``output.figures``). Raises ``integrate.BlowUpError`` on a numerical blow-up, after saving the
    last good state. Before all of that (:func:`parastokes.output.rundir.check_path`, then
    :func:`parastokes.config.preflight`, as ``parastokes check``): the
    configuration is built and a user's body called once at its initial state; a body that breaks
    the System contract raises :class:`~parastokes.bodies.contract.BodyError` naming the method,
    before the directory is claimed or a worker started.
    """
    reporter = reporter or Reporter()
    rundir.check_path(out)  # a bad --out before any work, and the body before the claim
    setup = preflight(cfg, resolved)
    with rundir.claim(out, resume=resume, overwrite=overwrite) as directory:
        found = directory.entries()
        if resume and not found["state"] and not found["results"]:
            reporter.note(f"--resume: {out} holds no run to continue; starting afresh")
        return _execute(setup, directory, reporter, files or {}, resume)


def _kernels_cached() -> bool:
    """Whether numba's cache holds compiled kernels of this package (else the first run compiles
    them, which takes up to a minute)."""
    root = os.environ.get("NUMBA_CACHE_DIR") or Path(__file__).parent
    return next(Path(root).rglob("*.nbi"), None) is not None


def _execute(
    setup: Setup, directory: rundir.RunDirectory, reporter: ReporterLike, files: dict[str, str],
    resume: bool = False,
) -> dict[str, Any]:
    from ..output import plots

    cfg, resolved = setup.config, setup.resolved
    out, staging = directory.path, directory.staging
    conf = resolved_dict(cfg, resolved)
    key = identity(cfg)
    _check_resumable(out, cfg, resume)
    previous = _previous_blow_up(out)  # (an earlier run's, to compare a new blow-up with)
    for name, text in files.items():
        write_text(out / name, text)
    mode = cfg.run.mode
    start = time.perf_counter()
    if not _kernels_cached():
        reporter.note("compiling the numerical kernels (first run only; up to a minute) ...")
    with session.start(setup) as running:
        system = setup.system
        x0 = system.initial_state()
        times = parareal.time_points(cfg.time.t0, cfg.time.t1, cfg.parareal.n_slices)
        writer = _writer(cfg, setup, conf, staging) if cfg.output.trajectory else None
        try:
            if writer is not None:
                _check_room(setup, writer)
            reference = serial_time = result = record = None
            if mode in ("serial", "both"):
                reference, serial_time = _serial(
                    setup, x0, times, out, fine_identity(cfg), reporter, previous
                )
                if writer is not None:
                    _append_frames(writer, "serial", running, times, reference)
            if mode in ("parareal", "both"):
                result, record = _parareal(
                    running, x0, times, reference, out, key, reporter, previous
                )
                if writer is not None:
                    _append_frames(writer, "parareal", running, times, result.states)
                    writer.write_history(record)
        except BaseException:
            running.abort()
            raise
        finally:
            if writer is not None:
                writer.close()
        final_states = result.states if result is not None else reference
        assert final_states is not None  # run.mode is serial, parareal or both
        summary = {
            "title": cfg.title,
            "mode": mode,
            "config": conf,
            "iterations": 0 if result is None else result.iterations,
            "stop_reason": None if result is None else result.stop_reason,
            "converged": None if result is None else result.converged,
            "increments": [] if result is None else result.increments,
            "errors": None if result is None else result.errors,
            "timings": {
                "serial_fine": serial_time,
                **({} if result is None else result.timings.to_dict()),
                "elapsed_by_iteration": [] if record is None else record.elapsed,
            },
            "speedup": None
            if result is None or record is None  # (both or neither)
            else _speedups(result, list(record.elapsed), serial_time),
            "workers": None if running.executor is None else running.executor.workers,
            "monitor": _monitor(system, final_states),
            "final_time": float(times[-1]),
            "final_positions": system.positions(final_states[-1]),
            "warnings": resolved.warnings,
            "versions": {
                "parastokes": __version__,
                "numpy": np.__version__,
                "python": platform.python_version(),
            },
        }
    summary["wall_time"] = time.perf_counter() - start
    io.write_summary(staging / SUMMARY, summary)
    if writer is not None:
        io.write_xdmf(staging / TRAJECTORY)
        if cfg.output.flow_every is not None:
            from ..flow.command import write_run_flow

            write_run_flow(staging, cfg.output.flow_every, cfg.output.flow_plane,
                           cfg.output.flow_resolution)
    if cfg.output.figures:
        written = plots.draw_run(staging, formats=cfg.output.formats)
        reporter.note(f"figures: {', '.join(sorted({p.stem for p in written}))}")
    directory.commit()  # the new results replace the old ones whole
    (out / BLOWUP).unlink(missing_ok=True)
    if result is not None and not cfg.parareal.checkpoint:
        (out / CHECKPOINT).unlink(missing_ok=True)
    return summary




def speedup_table(summary: dict[str, Any]) -> str:
    """The speedup report of a summary (eqs. 14-15), as printed after a run."""
    s = summary["speedup"]
    if s is None:
        return "speedup: no Parareal run"
    source = "estimated as N_c γ_F" if s["serial_time_estimated"] else "measured serial fine run"
    if s.get("schedule") == "pipelined":
        model, limit = "pipelined schedule, simulated, N_c workers", "its critical path"
    else:
        model, limit = "eq. 14 without overhead", "eq. 15"
    lines = [
        f"speedup after K = {summary['iterations']} iterations, N_c = {s['n_slices']} slices, "
        f"{summary['workers']} workers:",
        f"  measured     {s['measured']:8.3f}   (Υ_F = {s['serial_time']:.3f} s, {source}; "
        f"Parareal {summary['timings']['total']:.3f} s)",
        f"  theoretical  {s['theoretical']:8.3f}   ({model}; γ_G/γ_F = {s['gamma_ratio']:.4f})",
        f"  bound        {s['bound']:8.3f}   ({limit})",
    ]
    return "\n".join(lines)
