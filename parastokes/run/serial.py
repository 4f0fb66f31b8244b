"""The serial fine run: F over every slice, saved after each so that an interrupted run
resumes bit for bit and a finished one serves other runs of the same fine problem."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from ..config import Setup
from ..config.checks import estimated_fine_seconds
from ..core import signals
from ..core.files import CorruptFileError
from ..integrate import BlowUpError
from ..output import trajectory as io
from .advice import advice, blow_up_note
from .layout import REFERENCE
from .report import ReporterLike


def slice_seconds(setup: Setup) -> float:
    """A rough estimate of one fine solve over a slice (for the progress bars' ETA)."""
    r = setup.resolved
    return estimated_fine_seconds(setup.config.fine.scheme, r.fine_steps, r.n_points)


def serial_run(
    setup: Setup, x0: np.ndarray, times: np.ndarray, out: Path, key: dict, reporter: ReporterLike,
    previous: dict[str, Any] | None = None, state: Path | None = None,
) -> tuple[np.ndarray, float]:
    """The serial fine solution F(T_n, T_0, x0) at every T_n (as ``parareal.serial_solution``) and
    its wall time. Saved to ``state/REFERENCE`` (``state``: ``out`` by default) after every
    slice, and continued from there when that file holds the same fine problem (``key``,
    :func:`fine_identity`), so an interrupted serial run loses at most a slice and a finished one
    can serve other runs of that problem. A blow-up's last good state is saved in ``out``."""
    path = (out if state is None else state) / REFERENCE
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
    reporter.expect(slice_seconds(setup))
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
            fix = advice(setup, "serial", error, where, previous)
            error.add_note(blow_up_note(out, error, where, fix, cfg.fine.dt))
            raise
        wall += time.perf_counter() - start
        io.save_arrays(path, {"key": key, "done": n, "wall_time": wall}, states=states)
        reporter.advance()
        signals.honour()
    reporter.finish()
    if setup.config.fine.rtol is not None:
        reporter.note(f"serial fine run: adaptive steps ({setup.config.fine.scheme}, rtol "
                      f"{setup.config.fine.rtol:g}): {accepted} accepted, {rejected} rejected")
    return states, wall
