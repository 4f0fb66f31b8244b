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
) -> tuple[np.ndarray, float, dict[str, Any] | None]:
    """The serial fine solution F(T_n, T_0, x0) at every T_n (as ``parareal.serial_solution``),
    its wall time and, for adaptive steps, what :func:`adaptive_summary` says of the slices run
    now (None for fixed steps or a reloaded run). Saved to ``state/REFERENCE`` (``state``:
    ``out`` by default) after every slice, and continued from there when that file holds the
    same fine problem (``key``, :func:`fine_identity`), so an interrupted serial run loses at
    most a slice and a finished one can serve other runs of that problem. A blow-up's last good
    state is saved in ``out``."""
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
            return states, wall, None
        reporter.note(f"serial fine run resumed after slice {done} of {n_slices}")
    reporter.start("serial", n_slices - done)
    reporter.expect(slice_seconds(setup))
    results = []
    for n in range(done + 1, n_slices + 1):
        start = time.perf_counter()
        try:
            result = setup.fine.run(times[n - 1], times[n], states[n - 1])
            states[n] = result.state
            results.append(result)
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
    steps = adaptive_summary(results) if setup.config.fine.rtol is not None else None
    if steps is not None:
        reporter.note(f"serial fine run: adaptive steps ({setup.config.fine.scheme}, rtol "
                      f"{setup.config.fine.rtol:g}): {steps['accepted']} accepted, "
                      f"{steps['rejected']} rejected, {len(steps['switches'])} scheme switches")
    return states, wall, steps


def adaptive_summary(results: list[Any]) -> dict[str, Any]:
    """The steps of adaptive fine solves (their :class:`parastokes.integrate.RunResult`), for
    ``summary.json``: accepted, rejected, per scheme (``scheme="auto"`` runs several) and the
    switches of ``auto`` ``{t, scheme, reason}`` in time order."""
    by_scheme: dict[str, list[int]] = {}
    for result in results:
        for name, accepted, rejected in result.by_scheme:
            counts = by_scheme.setdefault(name, [0, 0])
            counts[0] += accepted
            counts[1] += rejected
    return {
        "accepted": sum(r.n_steps for r in results),
        "rejected": sum(r.n_rejected for r in results),
        "by_scheme": {name: {"accepted": a, "rejected": r} for name, (a, r) in by_scheme.items()},
        "switches": [{"t": t, "scheme": name, "reason": why}
                     for r in results for t, name, why in r.switches],
    }
