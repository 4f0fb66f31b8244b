"""Movies of a run: its bodies frame by frame, optionally over the flow of each frame.

MP4 through imageio with imageio-ffmpeg (whose wheel ships an ffmpeg binary: the ``movie`` extra);
a GIF through Pillow when the name ends in ``.gif`` or MP4 cannot be written (no imageio-ffmpeg).
Without the flow, each picture shows the bodies in the planes the figures use (x-y above, x-z,
the distance to the wall, below), on fixed axes that hold every frame; with the flow, the x-z plane
(or the given one) with the speed, the streamlines and the bodies (:mod:`.render`), the speed's
colour scale fixed over the movie (all frames' flows are computed first).
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from .render import draw_bodies, draw_plane, speed_limits
from .run import RunFrames

__all__ = ["choose_frames", "movie_writer", "render_frame", "write_movie"]


def choose_frames(n_saved: int, count: int | None) -> list[int]:
    """At most ``count`` frames spread evenly over the ``n_saved`` saved ones (all by default),
    the first and the last included."""
    if count is not None and count < 1:
        raise ValueError(f"--frames {count}: need at least 1 frame")
    if count is None or count >= n_saved:
        return list(range(n_saved))
    return sorted(set(np.linspace(0, n_saved - 1, count).round().astype(int).tolist()))


def render_frame(fig: Figure) -> np.ndarray:
    """The RGB pixels (H, W, 3) of ``fig``."""
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()


def _bodies_limits(run: RunFrames) -> np.ndarray:
    """(3, 2) bounds of every body over all frames, padded by 5 %."""
    points = np.concatenate([np.asarray(b["positions"]).reshape(-1, 3)
                             for b in run.data["bodies"].values()])
    low, high = points.min(axis=0), points.max(axis=0)
    pad = 0.05 * np.maximum(high - low, 1e-9 + 0.05 * float(np.max(high - low)))
    return np.stack([low - pad, high + pad], axis=1)


def draw_bodies_frame(fig: Figure, run: RunFrames, frame: int, limits: np.ndarray) -> None:
    """The bodies of ``frame`` in the x-y and x-z planes on the fixed ``limits``."""
    axes = fig.subplots(2, 1, sharex=True)
    for ax, (i, j) in zip(axes, ((0, 1), (0, 2)), strict=True):
        draw_bodies(ax, run.data["bodies"], frame, (i, j), color="C0")
        ax.set_xlim(*limits[i])
        ax.set_ylim(*limits[j])
        ax.set_ylabel(f"{'xyz'[j]} (μm)" + (" (distance to the wall)" if j == 2 and run.wall
                                            else ""))
        ax.ticklabel_format(axis="y", useOffset=False)
    axes[-1].set_xlabel("x (μm)")
    axes[0].set_title(f"t = {run.times[frame]:.5g} s ({run.data['run']})", fontsize=9)


@contextmanager
def movie_writer(path: Path, fps: float) -> Iterator[Callable[[np.ndarray], None]]:
    """A function that appends an RGB picture to the movie ``path`` (MP4, or GIF by name or
    when MP4 is not available); the file is complete when the block ends."""
    if path.suffix.lower() != ".gif":
        try:
            import imageio.v2 as imageio
            import imageio_ffmpeg  # noqa: F401  (the ffmpeg binary)
        except ImportError as error:
            raise ValueError(f"{path}: MP4 needs imageio and imageio-ffmpeg (pip install "
                             f"'parastokes[movie]'), missing {error.name}; or write a GIF: "
                             f"--out {path.with_suffix('.gif')}") from None
        writer = imageio.get_writer(path, fps=fps, codec="libx264", quality=7,
                                    macro_block_size=8, pixelformat="yuv420p")
        try:
            yield writer.append_data
        finally:
            writer.close()
        return
    from PIL import Image

    pictures: list[Any] = []
    yield lambda rgb: pictures.append(Image.fromarray(rgb).quantize(256))
    pictures[0].save(path, save_all=True, append_images=pictures[1:],
                     duration=round(1000 / fps), loop=0)


def write_movie(run: RunFrames, path: Path, frames: Sequence[int], fps: float,
                size: tuple[int, int], flow: Callable[[int], tuple[Any, np.ndarray]] | None,
                progress: bool) -> Path:
    """Write the movie of ``frames`` of ``run`` to ``path`` (``size`` in pixels, even numbers);
    ``flow(frame) -> (plane grid, velocity at its points)`` puts the flow under the bodies."""
    from tqdm import tqdm

    dpi = 100
    limits = _bodies_limits(run)
    fields, scale = {}, None
    if flow is not None:  # every frame's flow first: one colour scale for the whole movie
        for frame in tqdm(frames, desc="flow", unit="frame", disable=not progress,
                          file=sys.stderr, leave=False):
            fields[frame] = flow(frame)
        scale = speed_limits(np.concatenate([np.linalg.norm(v, axis=1)
                                             for _, v in fields.values()]))
    with movie_writer(path, fps) as append:
        for frame in tqdm(frames, desc="movie", unit="frame", disable=not progress,
                          file=sys.stderr, leave=False):
            fig = Figure(figsize=(size[0] / dpi, size[1] / dpi), dpi=dpi, layout="constrained")
            if flow is None:
                draw_bodies_frame(fig, run, frame, limits)
            else:
                grid, values = fields[frame]
                draw_plane(fig, grid, values, f"t = {run.times[frame]:.5g} s ({run.data['run']})",
                           run.wall, run.data["bodies"], frame, density=1.0, speed_range=scale)
            append(render_frame(fig))
    return path
