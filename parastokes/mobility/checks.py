"""Input checks before a solve: a surface too coarse for its ε, bodies that overlap, a body
below the wall. Each raises ``ValueError`` naming the body and what to change."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.spatial import cKDTree

from ..core.contracts import StepFailure


class ContactError(StepFailure, ValueError):
    """Two bodies' surfaces overlap or touch (``names``): at the start a configuration error
    (a ``ValueError``), inside a step a blow-up (a :class:`StepFailure`: the integrator keeps
    the last good state and names the time)."""

    def __init__(self, message: str, names: tuple[str, str]) -> None:
        super().__init__(message)
        self.names = names

    def __reduce__(self):
        return type(self), (str(self), self.names)

#: Largest nearest-neighbour spacing allowed, in units of the local ε: with wider gaps between
#: blobs the surface leaks (docs/validation.md, "Rigid bodies": the drag error against the
#: spacing/ε ratio). The usual choice, ε = half the spacing (Khatri & Cortez), is a ratio of 2.
#: The one "surface too coarse" rule: a rigid body of a configuration (its largest gap, the
#: largest of these spacings) is held to it too.
MAX_SPACING_OVER_EPS = 4.0


def nearest_spacing(points: np.ndarray) -> np.ndarray:
    """Distance from each point to its nearest other point, (N,)."""
    dist, _ = cKDTree(points).query(points, k=2)
    return dist[:, 1]


def check_surface(points: np.ndarray, epsilon: float | np.ndarray, *, name: str = "body") -> None:
    """Refuse a surface whose points are too far apart for their ε (spacing > 4 ε at some
    point: the blobs no longer cover the surface) or that repeats a point (a singular system)."""
    pts = np.asarray(points, dtype=np.float64)
    eps = np.broadcast_to(np.asarray(epsilon, dtype=np.float64), (len(pts),))
    spacing = nearest_spacing(pts)
    scale = np.max(np.ptp(pts, axis=0))
    if np.min(spacing) <= 1e-12 * scale:
        i = int(np.argmin(spacing))
        raise ValueError(
            f"{name}: point {i} is repeated (two surface points coincide): remove duplicates"
        )
    ratio = spacing / eps
    worst = int(np.argmax(ratio))
    if ratio[worst] > MAX_SPACING_OVER_EPS:
        raise ValueError(
            f"{name}: surface too coarse for its ε: at point {worst} the spacing to the nearest "
            f"point is {spacing[worst]:.4g}, {ratio[worst]:.3g} ε (ε = {eps[worst]:.4g}; at most "
            f"{MAX_SPACING_OVER_EPS:g} ε allowed): use more surface points or a larger ε "
            f"(about half the spacing, {0.5 * np.median(spacing):.4g})"
        )


def check_placements(
    points: Sequence[np.ndarray], spacings: Sequence[float], names: Sequence[str], wall: bool
) -> None:
    """Refuse bodies below (or on) the wall z = 0 and pairs of bodies whose surfaces come closer
    than half the smaller median spacing of the two (overlapping or touching: the discrete
    surfaces can no longer tell them apart)."""
    if wall:
        for pts, spacing, name in zip(points, spacings, names, strict=True):
            low = float(np.min(pts[:, 2]))
            if low <= 0.0:
                raise ValueError(
                    f"{name}: lies on or below the wall z = 0 (lowest point at z = {low:.4g}): "
                    f"raise its center by at least {-low + 0.5 * spacing:.4g}"
                )
    if len(points) < 2:
        return
    pair = _closest_overlap(points, spacings)
    if pair is not None:
        a, b, closest, limit = pair
        raise ContactError(
            f"{names[a]} and {names[b]} overlap or touch: their surfaces come "
            f"{closest:.4g} apart, under half the surface spacing ({limit:.4g}): move them "
            f"apart or refine both surfaces", (names[a], names[b])
        )


def _closest_overlap(
    points: Sequence[np.ndarray], spacings: Sequence[float]
) -> tuple[int, int, float, float] | None:
    """The first pair of bodies (a < b, by a then b) whose points come closer than half the
    smaller of their spacings, with their closest distance and that limit; None if there is
    none. One k-d tree of all points finds the close pairs of points (O(N log N), not a query
    per pair of bodies: a suspension of thousands of bodies is checked at every solve)."""
    body = np.repeat(np.arange(len(points)), [len(p) for p in points])
    half = 0.5 * np.asarray(spacings, dtype=float)
    tree = cKDTree(np.concatenate(points))
    close = tree.query_pairs(float(half.max()), output_type="ndarray")
    if not len(close):
        return None
    a, b = body[close[:, 0]], body[close[:, 1]]
    apart = np.linalg.norm(tree.data[close[:, 0]] - tree.data[close[:, 1]], axis=1)
    limit = np.minimum(half[a], half[b])
    hit = (a != b) & (apart < limit)
    if not hit.any():
        return None
    lo, hi = np.minimum(a, b)[hit], np.maximum(a, b)[hit]
    first = np.lexsort((hi, lo))[0]
    same = (lo == lo[first]) & (hi == hi[first])
    return int(lo[first]), int(hi[first]), float(apart[hit][same].min()), float(limit[hit][first])
