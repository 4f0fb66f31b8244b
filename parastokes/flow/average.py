"""The mean flow over a window of saved frames (the flow over one beat is what papers show).

``time_average`` integrates the velocity of :func:`.evaluate.velocity` over [t0, t1] by the
trapezoidal rule on the saved frames inside the window, divided by the window they span: for
frames dense against the period, the mean over whole periods (a beat averages the swimmer's
oscillating flow to its steady part).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .evaluate import velocity

__all__ = ["time_average", "window"]


def window(times: np.ndarray, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray]:
    """The frames with t0 <= t <= t1 (to round-off) and their trapezoidal weights (sum 1; one
    frame: weight 1). ValueError naming the saved range when the window holds none."""
    times = np.asarray(times, dtype=float)
    if not t0 <= t1:
        raise ValueError(f"--average {t0:g} {t1:g}: need T0 <= T1")
    tol = 1e-9 * max(1.0, float(np.max(np.abs(times))) if len(times) else 1.0)
    index = np.flatnonzero((times >= t0 - tol) & (times <= t1 + tol))
    if len(index) == 0:
        raise ValueError(f"--average {t0:g} {t1:g}: no saved frame in that window; the frames "
                         f"span t = {times.min():g} .. {times.max():g} ({len(times)} frames)")
    t = times[index]
    if len(index) == 1 or t[-1] == t[0]:
        return index, np.full(len(index), 1.0 / len(index))
    weights = np.zeros(len(index))
    steps = np.diff(t)
    weights[:-1] += 0.5 * steps
    weights[1:] += 0.5 * steps
    return index, weights / (t[-1] - t[0])


def time_average(system: object, states: Sequence[np.ndarray] | np.ndarray, times: np.ndarray,
                 points: np.ndarray, t0: float, t1: float, background: bool = True,
                 n_threads: int | None = None) -> np.ndarray:
    """The mean velocity (M, 3) at ``points`` over the frames ``states`` at ``times`` inside
    [t0, t1] (trapezoidal rule, module text)."""
    index, weights = window(times, t0, t1)
    total = np.zeros((len(points), 3))
    for i, w in zip(index, weights, strict=True):
        total += w * velocity(system, states[i], points, float(times[i]), background, n_threads)
    return total
