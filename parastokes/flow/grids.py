"""Where the flow is evaluated: regular grids of points (a plane or a box) and how users name them.

A :class:`Grid` is ``shape = (nx, ny, nz)`` nodes from ``origin`` with ``spacing``; its points are
ordered with x fastest and z slowest, so a field of the grid reshapes to ``(nz, ny, nx, 3)`` (the
order of the XDMF structured grids, :mod:`.xdmf`). A plane is a grid with one node across it.

From the command line: ``--plane z=5`` (or ``x=``, ``y=``), ``--box x0 x1 y0 y1 z0 z1``, and
``--resolution N`` (N nodes along the longest side, square cells) or ``NxM`` (NxMxK for a box),
at most :data:`MAX_RESOLUTION` along each; a coordinate beyond :data:`MAX_COORDINATE` is refused
(the kernels' powers of the distance would overflow to NaN). Without a box the extent is that of
the bodies plus a margin (and down to the wall).
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..config.schema import MAX_FLOW_COORDINATE as MAX_COORDINATE
from ..config.schema import MAX_FLOW_RESOLUTION as MAX_RESOLUTION

__all__ = ["MAX_COORDINATE", "MAX_RESOLUTION", "Grid", "PlaneSpec", "bodies_box", "grid_for",
           "parse_box", "parse_plane", "parse_resolution"]

AXES = "xyz"


@dataclass(frozen=True)
class Grid:
    """``shape`` = (nx, ny, nz) nodes at ``origin + index * spacing``."""

    origin: tuple[float, float, float]
    spacing: tuple[float, float, float]
    shape: tuple[int, int, int]

    @classmethod
    def of(cls, origin: Sequence[float], spacing: Sequence[float], shape: Sequence[int]) -> Grid:
        """The grid of three values each (any sequences of numbers)."""
        (x0, y0, z0), (dx, dy, dz), (nx, ny, nz) = origin, spacing, shape
        return cls((float(x0), float(y0), float(z0)), (float(dx), float(dy), float(dz)),
                   (int(nx), int(ny), int(nz)))

    def axes(self) -> list[np.ndarray]:
        """The node coordinates along x, y and z."""
        return [self.origin[i] + self.spacing[i] * np.arange(self.shape[i]) for i in range(3)]

    def points(self) -> np.ndarray:
        """All nodes, (nx ny nz, 3), x fastest."""
        x, y, z = self.axes()
        zz, yy, xx = np.meshgrid(z, y, x, indexing="ij")
        return np.stack([xx.ravel(), yy.ravel(), zz.ravel()], axis=1)

    def field(self, values: np.ndarray) -> np.ndarray:
        """Values at :meth:`points` as (nz, ny, nx, ...)."""
        nx, ny, nz = self.shape
        return np.asarray(values).reshape(nz, ny, nx, *np.shape(values)[1:])

    @property
    def plane_axes(self) -> tuple[int, int] | None:
        """The two axes a plane spans (first, second), or None for a box."""
        flat = [i for i in range(3) if self.shape[i] == 1]
        if len(flat) != 1:
            return None
        i, j = (k for k in range(3) if k != flat[0])
        return i, j


@dataclass(frozen=True)
class PlaneSpec:
    """``axis`` (0, 1, 2) held at ``value``: ``--plane z=5``."""

    axis: int
    value: float


def parse_plane(text: str) -> PlaneSpec:
    """``"z=5"`` -> PlaneSpec(2, 5.0); ValueError saying the form otherwise."""
    match = re.fullmatch(r"\s*([xyzXYZ])\s*=\s*(\S+)\s*", text)
    try:
        value = float(match.group(2)) if match else math.nan
    except ValueError:
        value = math.nan
    if match is None or not math.isfinite(value):
        raise ValueError(f"--plane {text!r}: give AXIS=VALUE, e.g. --plane z=5 or --plane y=0")
    if abs(value) > MAX_COORDINATE:
        raise ValueError(f"--plane {text!r}: beyond ±{MAX_COORDINATE:g} μm, where the flow cannot "
                         "be computed; give a plane near the bodies")
    return PlaneSpec(AXES.index(match.group(1).lower()), value)


def parse_box(values: list[float]) -> np.ndarray:
    """``[x0, x1, y0, y1, z0, z1]`` -> (3, 2) bounds; ValueError unless every x0 < x1."""
    box = np.asarray(values, dtype=float)
    if box.shape != (6,) or not np.all(np.isfinite(box)):
        raise ValueError(f"--box: give six numbers x0 x1 y0 y1 z0 z1, got {values}")
    if np.abs(box).max() > MAX_COORDINATE:
        raise ValueError(f"--box: {np.abs(box).max():g} is beyond ±{MAX_COORDINATE:g} μm, where "
                         "the flow cannot be computed; give a box near the bodies")
    box = box.reshape(3, 2)
    bad = [AXES[i] for i in range(3) if not box[i, 0] < box[i, 1]]
    if bad:
        raise ValueError(f"--box: need {bad[0]}0 < {bad[0]}1, got {box[AXES.index(bad[0])]}")
    return box


def parse_resolution(text: str | int) -> tuple[int, ...]:
    """``"64"`` -> (64,), ``"64x32"`` -> (64, 32); at least 2 nodes along each."""
    parts = str(text).lower().split("x")
    try:
        counts = tuple(int(p) for p in parts)
    except ValueError:
        counts = ()
    if not counts or len(counts) > 3 or not 2 <= min(counts) <= max(counts) <= MAX_RESOLUTION:
        raise ValueError(f"--resolution {text!r}: give N or NxM (NxMxK for a box), each from 2 "
                         f"to {MAX_RESOLUTION}, e.g. --resolution 128 or 128x64")
    return counts


def bodies_box(points: np.ndarray, wall: bool, margin: float = 0.5) -> np.ndarray:
    """(3, 2) bounds around ``points`` plus ``margin`` times their largest extent on every side
    (at least 1); with ``wall`` the lower z bound is the wall z = 0."""
    low, high = points.min(axis=0), points.max(axis=0)
    pad = max(margin * float(np.max(high - low)), 1.0)
    box = np.stack([low - pad, high + pad], axis=1)
    if wall:
        box[2, 0] = 0.0
    return box


def _counts(extent: np.ndarray, resolution: tuple[int, ...]) -> list[int]:
    """Nodes along each extent: ``resolution`` per axis, or one N along the longest, the others in
    proportion (square cells), at least 2."""
    if len(resolution) == len(extent):
        return list(resolution)
    if len(resolution) != 1:
        raise ValueError(f"--resolution: give one count or {len(extent)} (one per axis), got "
                         f"{'x'.join(map(str, resolution))}")
    longest = float(np.max(extent))
    return [max(2, round((resolution[0] - 1) * e / longest) + 1) for e in extent]


def grid_for(box: np.ndarray, resolution: tuple[int, ...], plane: PlaneSpec | None = None,
             wall: bool = False) -> Grid:
    """The grid over ``box`` (3, 2) with ``resolution``; with ``plane``, the plane's slice of it.

    ValueError for a plane below the wall (no fluid there) or outside the box.
    """
    box = np.asarray(box, dtype=float)
    if plane is not None:
        name = f"{AXES[plane.axis]}={plane.value:g}"
        if wall and plane.axis == 2 and plane.value < 0:
            raise ValueError(f"--plane {name} is below the wall z = 0 (no fluid there); choose "
                             "z >= 0")
        low, high = box[plane.axis]
        if not low <= plane.value <= high:
            raise ValueError(f"--plane {name} lies outside the box {AXES[plane.axis]} in "
                             f"[{low:g}, {high:g}]; move the plane or widen --box")
        spans = [i for i in range(3) if i != plane.axis]
    else:
        if wall and box[2, 0] < 0:
            raise ValueError(f"--box: z0 = {box[2, 0]:g} is below the wall z = 0 (no fluid "
                             "there); choose z0 >= 0")
        spans = [0, 1, 2]
    counts = _counts(box[spans, 1] - box[spans, 0], resolution)
    shape, origin, spacing = [1, 1, 1], list(box[:, 0]), [0.0, 0.0, 0.0]
    for axis, n in zip(spans, counts, strict=True):
        shape[axis] = n
        spacing[axis] = float(box[axis, 1] - box[axis, 0]) / (n - 1)
    if plane is not None:
        origin[plane.axis] = plane.value
        spacing[plane.axis] = float(np.mean([spacing[i] for i in spans]))
    return Grid.of(origin, spacing, shape)
