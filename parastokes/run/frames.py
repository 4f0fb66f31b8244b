"""The frames of a run's trajectory: which slice boundaries and how many frames inside each
slice (``output.every``), the room they need, and their writing."""

from __future__ import annotations

import errno
import itertools
import os
from pathlib import Path
from typing import Any

try:
    import resource
except ImportError:  # (not on Windows)
    resource = None  # type: ignore[assignment]
import numpy as np

from ..config import Config, Setup
from ..core import files, signals
from ..output import trajectory as io
from ..parallel import SerialExecutor, run_labelled
from . import session
from .layout import TRAJECTORY


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


def check_room(setup: Setup, writer: io.TrajectoryWriter) -> None:
    """Refuse, before any work, a trajectory whose frames alone exceed the file-size limit
    (``ulimit -f``) or the free space where it is written: otherwise the run would fail at its
    end, when it writes them (a FileWriteError then)."""
    frames, parts = _frame_plan(setup)
    runs = 2 if setup.config.run.mode == "both" else 1
    count = runs * (len(frames) + (parts - 1) * setup.config.parareal.n_slices)
    columns = sum(body.rows * (3 + sum(c.stop - c.start for c in body.vectors.values())
                               + sum(c.stop - c.start for c in body.rate_vectors.values()))
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


def append_frames(
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
        signals.honour()
        if n in frames:
            writer.append(run, times[n], states[n])
        if n + 1 in inner:
            inside = np.linspace(times[n], times[n + 1], parts + 1)[1:-1]
            for t, state in zip(inside, inner[n + 1], strict=True):
                writer.append(run, t, state)


def trajectory_writer(
    cfg: Config, setup: Setup, conf: dict[str, Any], out: Path
) -> io.TrajectoryWriter:
    """The trajectory writer of the layout that the body's kind gives (registry); the node
    vectors of a body's motion (a rigid body's U and Ω) from the system's rates at each frame."""
    layout = cfg.model.layout(setup.system, cfg.output.frames, cfg.output.tracked_points)
    return io.TrajectoryWriter(out / TRAJECTORY, layout, config=conf, rates=setup.system.rates)
