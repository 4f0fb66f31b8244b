"""Movies of a run: its bodies frame by frame, optionally over the flow of each frame.

MP4 through the ffmpeg binary that imageio-ffmpeg's wheel ships (the ``movie`` extra), fed the
frames on a pipe; a GIF through Pillow when the name ends in ``.gif``. Either is written to a
temporary file of a :class:`~parastokes.core.files.Staging` and moved into place only when complete:
an encoder that fails (its exit status), writes nothing, or leaves an MP4 without its index (a
full disk, a file-size limit) is a :class:`~parastokes.core.files.FileWriteError` naming the movie,
and the previous movie stays.
Without the flow, each picture shows the bodies in the planes the figures use (x-y above, x-z,
the distance to the wall, below), on fixed axes that hold every frame; with the flow, the x-z plane
(or the given one) with the speed, the streamlines and the bodies (:mod:`.render`), the speed's
colour scale fixed over the movie (all frames' flows are computed first).
"""

from __future__ import annotations

import errno
import os
import signal
import subprocess
import sys
import tempfile
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..core import signals
from ..core.files import FileWriteError, Staging, open_input
from .render import draw_bodies, draw_plane, speed_limits
from .run import RunFrames

__all__ = ["check_mp4", "choose_frames", "movie_writer", "render_frame", "write_movie"]


#: H.264's constant rate factor of the MP4 (0 lossless .. 51; 15: no visible loss).
CRF = 15


def choose_frames(n_saved: int, count: int | None) -> list[int]:
    """At most ``count`` frames spread evenly over the ``n_saved`` saved ones (all by default),
    the first and the last included; a movie needs two."""
    if n_saved < 2:
        raise ValueError(f"the run saved {n_saved} frame(s): a movie needs at least 2; draw a "
                         "single frame with `parastokes flow` or `parastokes plot`, or save more "
                         "frames (output.every)")
    if count is not None and count < 2:
        raise ValueError(f"--frames {count}: a movie needs at least 2 frames")
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
    """The bodies of ``frame`` in the x-y and x-z planes on the fixed ``limits``, at true scale
    (a micrometre as long across as up), each panel as tall as its extent makes it (no gap
    between flat panels), its axis named by a horizontal label beside it (a rotated one hung far
    above and below a flat panel), what z measures in the panel's title."""
    extent = limits[:, 1] - limits[:, 0]
    axes = fig.subplots(2, 1, sharex=True, height_ratios=[extent[1], extent[2]])
    for ax, (i, j) in zip(axes, ((0, 1), (0, 2)), strict=True):
        draw_bodies(ax, run.data["bodies"], frame, (i, j), color="C0")
        ax.set_xlim(*limits[i])
        ax.set_ylim(*limits[j])
        ax.set_aspect("equal", adjustable="box")
        ax.set_ylabel(f"{'xyz'[j]}\n(μm)", rotation=0, ha="right", va="center")
        ax.ticklabel_format(axis="y", useOffset=False)
    axes[-1].set_xlabel("x (μm)")
    axes[0].set_title(f"t = {run.times[frame]:.5g} s ({run.data['run']})", fontsize=9)
    if run.wall:
        axes[1].set_title("z: the distance to the wall", fontsize=8)


def _ffmpeg(path: Path) -> str:
    """The ffmpeg binary of imageio-ffmpeg; ValueError saying what to install otherwise."""
    try:
        import imageio_ffmpeg

        return str(imageio_ffmpeg.get_ffmpeg_exe())
    except (ImportError, RuntimeError) as error:
        raise ValueError(f"{path}: MP4 needs the ffmpeg of imageio-ffmpeg (pip install "
                         f"'parastokes[movie]'), which is not available ({error}); or write a "
                         f"GIF: --out {path.with_suffix('.gif')}") from None


def _failed(path: Path, reason: str) -> FileWriteError:
    return FileWriteError(path, OSError(errno.EIO, reason))


def check_mp4(path: Path, written: Path) -> None:
    """:class:`FileWriteError` naming ``path`` unless ``written`` is a whole MP4: its top-level
    boxes cover the file exactly and include ``ftyp``, ``mdat`` and ``moov`` (the index, written
    last: a file cut short by a full disk or a size limit lacks it)."""
    length = written.stat().st_size if written.is_file() else 0
    if not length:
        raise _failed(path, "the encoder ended without writing the movie")
    boxes, at = set(), 0
    with open_input(written, "movie") as handle:  # (the box headers only, not the frames)
        while at + 8 <= length:
            handle.seek(at)
            head = handle.read(16)
            size, kind = int.from_bytes(head[:4], "big"), head[4:8]
            if size == 1 and len(head) == 16:
                size = int.from_bytes(head[8:16], "big")
            elif size == 0:
                size = length - at
            if size < 8:
                break
            boxes.add(kind)
            at += size
    if at != length or not {b"ftyp", b"mdat", b"moov"} <= boxes:
        raise _failed(path, f"the encoder left an incomplete MP4 ({length} bytes, no index)")


def _wait(process: subprocess.Popen) -> int:
    """The encoder's exit status, a stop asked for meanwhile raised again (:mod:`core.signals`:
    one lost while the frames were drawn would otherwise wait for the encoder and then report
    its half-written file)."""
    while True:
        signals.honour()
        try:
            return process.wait(timeout=0.2)
        except subprocess.TimeoutExpired:
            continue


@contextmanager
def _encoder(path: Path, written: Path, fps: float) -> Iterator[Callable[[np.ndarray], None]]:
    """A function that pipes an RGB picture to ffmpeg, which encodes them as the H.264 MP4
    ``written`` (for ``path``); the encoder's failure is a :class:`FileWriteError` naming
    ``path`` with its last message."""
    command = [_ffmpeg(path), "-y", "-loglevel", "error", "-f", "rawvideo", "-pix_fmt", "rgb24",
               "-r", f"{fps:g}"]
    process: subprocess.Popen | None = None
    with tempfile.TemporaryFile() as log:

        def append(rgb: np.ndarray) -> None:
            nonlocal process
            if process is None:
                size = f"{rgb.shape[1]}x{rgb.shape[0]}"
                process = subprocess.Popen(
                    [*command, "-s", size, "-i", "-", "-an", "-c:v", "libx264", "-crf", str(CRF),
                     "-pix_fmt", "yuv420p", "-f", "mp4", str(written)],
                    stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=log)
            assert process.stdin is not None
            try:
                process.stdin.write(np.ascontiguousarray(rgb, dtype=np.uint8).tobytes())
            except BrokenPipeError:  # the encoder stopped: its exit status says why (below)
                pass

        try:
            yield append
            code = 0
            if process is not None:
                assert process.stdin is not None
                try:
                    process.stdin.close()
                except BrokenPipeError:
                    pass
                code = _wait(process)
        finally:
            if process is not None and process.poll() is None:  # interrupted: stop it
                process.kill()
                process.wait()
        limit = getattr(signal, "SIGXFSZ", None)  # (subprocess restores its default action)
        if limit is not None and code == -limit:
            raise FileWriteError(path, OSError(errno.EFBIG, os.strerror(errno.EFBIG)))
        if code != 0:
            log.seek(0)
            lines = log.read().decode(errors="replace").strip().splitlines()
            last = f": {lines[-1]}" if lines else ""
            how = (f"killed by {signal.Signals(-code).name}" if -code in signal.valid_signals()
                   else f"exit status {code}")
            raise _failed(path, f"the encoder ffmpeg failed ({how}){last}")
    check_mp4(path, written)


@contextmanager
def movie_writer(path: Path, fps: float,
                 staging: Staging) -> Iterator[Callable[[np.ndarray], None]]:
    """A function that appends an RGB picture to the movie ``path`` (MP4, or GIF by name),
    written through ``staging`` (in place when it commits); the file is complete and checked
    when the block ends."""
    if path.suffix.lower() != ".gif":
        with _encoder(path, staging.temporary(path), fps) as append:
            yield append
        return
    from PIL import Image

    pictures: list[Any] = []
    yield lambda rgb: pictures.append(Image.fromarray(rgb).quantize(256))
    staging.write(path, lambda handle: pictures[0].save(
        handle, format="GIF", save_all=True, append_images=pictures[1:],
        duration=round(1000 / fps), loop=0))


def write_movie(run: RunFrames, path: Path, frames: Sequence[int], fps: float,
                size: tuple[int, int], flow: Callable[[int], tuple[Any, np.ndarray]] | None,
                progress: bool, staging: Staging) -> Path:
    """Write the movie of ``frames`` of ``run`` to ``path`` through ``staging`` (``size`` in
    pixels, even numbers); ``flow(frame) -> (plane grid, velocity at its points)`` puts the flow
    under the bodies."""
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
    with movie_writer(path, fps, staging) as append:
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
