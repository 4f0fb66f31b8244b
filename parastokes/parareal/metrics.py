"""The error measures of eq. 34: true relative error eta^k and relative increment eta~^k."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

__all__ = ["Positions", "as_points", "relative_change"]

Positions = Callable[[np.ndarray], np.ndarray]


def as_points(values: np.ndarray) -> np.ndarray:
    """View an array as points, one per row (a 1-D array is a single point)."""
    values = np.asarray(values, dtype=float)
    return values.reshape(1, -1) if values.ndim <= 1 else values.reshape(values.shape[0], -1)


def relative_change(
    state: np.ndarray, base: np.ndarray, positions: Positions | None = None
) -> float:
    """max_i ||x_i - y_i||_2 / ||y_i||_2 over the points x_i of ``state``, y_i of ``base`` (eq. 34).

    The points are the rows of ``positions(state)`` (default: of the whole state; a 1-D state is one
    point). ``relative_change(X^k, X_F)`` is eta^k and ``relative_change(X^{k-1}, X^k)`` is eta~^k:
    the denominator is the second argument. A point with ||y_i|| = 0 counts 0 if it did not move and
    infinity otherwise.
    """
    if positions is not None:
        state, base = positions(state), positions(base)
    x, y = as_points(state), as_points(base)
    diff = np.linalg.norm(x - y, axis=1)
    norm = np.linalg.norm(y, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(norm > 0.0, diff / norm, np.where(diff > 0.0, np.inf, 0.0))
    return float(ratio.max())
