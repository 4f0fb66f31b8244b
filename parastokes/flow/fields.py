"""A run's flow on a grid: which grid (the user's plane or box, or one around the bodies) and the
velocity of a frame or of a window of frames on it. Shared by ``parastokes flow``, ``parastokes
movie --flow`` and a run's own ``output.flow_every``."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ..core.files import Staging, staged
from .average import window
from .evaluate import velocity
from .grids import Grid, PlaneSpec, bodies_box, grid_for
from .render import draw_plane
from .run import RunFrames

__all__ = ["default_plane", "frames_velocity", "picture_size", "plane_of", "run_grid",
           "save_png"]


def default_plane(run: RunFrames, frames: Sequence[int]) -> PlaneSpec:
    """The x-z plane through the bodies' mean y over ``frames`` (the side view, with the wall)."""
    return PlaneSpec(1, float(np.mean([run.positions(f)[:, 1].mean() for f in frames])))


def run_grid(run: RunFrames, frames: Sequence[int], plane: PlaneSpec | None,
             box: np.ndarray | None, resolution: tuple[int, ...]) -> Grid:
    """The grid of ``plane`` and/or ``box``; without a box, around the bodies of ``frames``
    (:func:`.grids.bodies_box`); with neither, :func:`default_plane`."""
    if box is None:
        points = np.concatenate([run.positions(f) for f in frames])
        box = bodies_box(points, run.wall)
        if plane is None:
            plane = default_plane(run, frames)
        if plane.axis != 2 or not run.wall or plane.value >= 0:  # (else grid_for says why not)
            box[plane.axis] = [min(box[plane.axis, 0], plane.value),
                               max(box[plane.axis, 1], plane.value)]
    return grid_for(box, resolution, plane, run.wall)


def frames_velocity(run: RunFrames, frames: Sequence[int] | np.ndarray,
                    weights: Sequence[float] | np.ndarray,
                    points: np.ndarray, background: bool = True,
                    n_threads: int | None = None) -> np.ndarray:
    """Σ weight × velocity of each frame at ``points`` (one frame with weight 1: its flow)."""
    total = np.zeros((len(points), 3))
    for f, w in zip(frames, weights, strict=True):
        total += w * velocity(run.system, run.state(f), points, float(run.times[f]),
                              background, n_threads)
    return total


def average_frames(run: RunFrames, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray]:
    """The frames of [t0, t1] and their weights (:func:`.average.window`)."""
    return window(run.times, t0, t1)


def plane_of(grid: Grid, values: np.ndarray, y: float) -> tuple[Grid, np.ndarray]:
    """``grid`` itself if it is a plane, else its x-z slice nearest to ``y`` and its values."""
    if grid.plane_axes is not None:
        return grid, values
    k = int(np.clip(round((y - grid.origin[1]) / grid.spacing[1]), 0, grid.shape[1] - 1))
    nx, _, nz = grid.shape
    origin = (grid.origin[0], grid.origin[1] + k * grid.spacing[1], grid.origin[2])
    plane = Grid(origin, grid.spacing, (nx, 1, nz))
    return plane, grid.field(values)[:, k].reshape(-1, 3)


def picture_size(plane: Grid, width: float = 7.0) -> tuple[float, float]:
    """Inches (width, height) of the picture of ``plane`` at true scale: its axes ``width`` less
    the colour bar and labels (1.8 in) wide, as tall as the plane's aspect makes them plus the
    title and labels (1 in); between 2.5 and 9 in tall."""
    i, j = plane.plane_axes or (0, 2)
    extent = [plane.spacing[k] * (plane.shape[k] - 1) for k in (i, j)]
    height = (width - 1.8) * extent[1] / extent[0] + 1.0
    return width, float(np.clip(height, 2.5, 9.0))


def save_png(path: Path, grid: Grid, values: np.ndarray, run: RunFrames, frame: int,
             title: str, size: tuple[float, float] | None = None, dpi: int = 120,
             staging: Staging | None = None) -> Path:
    """The picture of :func:`.render.draw_plane` (a box: its x-z slice through the bodies) with
    the bodies of ``frame`` (``size`` in inches: by default :func:`picture_size`), written to
    ``path`` through ``staging`` (moved into place when it commits), else atomically at once."""
    if staging is None:
        with staged() as own:
            return save_png(path, grid, values, run, frame, title, size, dpi, own)
    plane, field = plane_of(grid, values, float(run.positions(frame)[:, 1].mean()))
    fig = Figure(figsize=size or picture_size(plane), layout="constrained")
    draw_plane(fig, plane, field, title, run.wall, run.data["bodies"], frame)
    return staging.write(path, lambda handle: fig.savefig(handle, format="png", dpi=dpi))
