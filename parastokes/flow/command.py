"""The commands ``parastokes flow RUN_DIR`` and ``parastokes movie RUN_DIR`` (docs/tutorial.md,
"From a run to its flow"), and a run's own flow output (``output.flow_every``).

::

    parastokes flow RUN_DIR [--frame I | --time T | --average T0 T1] [--plane AXIS=V] [--box X0 X1
                    Y0 Y1 Z0 Z1] [--resolution N | NxM] [--no-background] [--run RUN] [--out STEM]
    parastokes movie RUN_DIR [--out swim.mp4] [--frames N] [--fps F] [--size WxH] [--flow]
                     [--plane AXIS=V] [--resolution N] [--run RUN]

``flow`` writes ``STEM.h5`` + ``STEM.xdmf`` (the grid, :mod:`.xdmf`) and ``STEM.png`` (speed and
streamlines, :mod:`.render`); STEM defaults to ``RUN_DIR/flow_<frame>``. Bad input (no
trajectory, a frame or time outside the saved ones, a plane below the wall or outside the box) is a
ValueError: exit status 2 with one line naming what to change.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # the handlers import numpy, matplotlib and the kernels on use (a fast CLI)
    import numpy as np

    from .run import RunFrames

__all__ = ["add_commands", "cmd_flow", "cmd_movie", "write_run_flow"]

#: Nodes along the longest side: a picture's plane, a movie's plane, a box.
PLANE_RESOLUTION, MOVIE_RESOLUTION, BOX_RESOLUTION = 128, 64, 32
#: The most dots per inch of the flow picture (7 inches wide: 7 000 pixels).
MAX_DPI = 1000
#: The most pixels along a movie's side (8K), and the most frames per second.
MAX_PIXELS, MAX_FPS = 7680, 1000.0


def _selection(run: RunFrames, args: argparse.Namespace) -> tuple[np.ndarray, np.ndarray, str]:
    """The frames, their weights and a label, from --frame / --time / --average."""
    import numpy as np

    from .fields import average_frames
    if args.average is not None:
        t0, t1 = args.average
        frames, weights = average_frames(run, t0, t1)
        return frames, weights, f"mean_{t0:g}-{t1:g}"
    frame = run.frame(args.frame, args.time)
    return np.array([frame]), np.ones(1), f"frame{frame}"


def _title(run: RunFrames, frames: np.ndarray, background: bool) -> str:
    times = run.times[frames]
    when = (f"t = {times[0]:.5g} s" if len(frames) == 1
            else f"mean over t = {times[0]:.5g} .. {times[-1]:.5g} s ({len(frames)} frames)")
    extra = "" if background or not hasattr(run.system, "shear_rate") else ", without u∞"
    return f"{when} ({run.data['run']}){extra}"


def _finite(values: np.ndarray, grid: Any) -> None:
    """ValueError when the flow ``values`` (nodes x 3, or frames x nodes x 3) is not finite at
    some node of ``grid`` (a grid so far from the bodies that the kernels overflow, or a damaged
    state)."""
    import numpy as np

    points = grid.points()
    finite = np.isfinite(np.reshape(values, (-1, len(points), 3))).all(axis=(0, 2))
    if not finite.all():
        where = points[np.argmin(finite)]
        raise ValueError(f"the flow is not finite at {int((~finite).sum())} of {finite.size} "
                         f"nodes (the first at {np.array2string(where, precision=4)}): bring the "
                         "plane or box nearer to the bodies")


def cmd_flow(args: argparse.Namespace, console: Any) -> int:
    """``parastokes flow``: the flow of a frame (or a window's mean) on a plane or a box."""
    import numpy as np

    from ..output import rundir
    from .fields import frames_velocity, run_grid, save_png
    from .grids import parse_box, parse_plane, parse_resolution
    from .run import load_run
    from .xdmf import suffixed, write_grid

    plane = parse_plane(args.plane) if args.plane is not None else None
    box = parse_box(args.box) if args.box is not None else None
    default = PLANE_RESOLUTION if plane is not None or box is None else BOX_RESOLUTION
    resolution = parse_resolution(args.resolution or default)
    if not 0 < args.dpi <= MAX_DPI:
        raise ValueError(f"--dpi {args.dpi}: give 1 to {MAX_DPI} dots per inch")
    rundir.check_free(args.run_dir)  # not while a run replaces its results
    run = load_run(args.run_dir, args.run, threads=args.threads)
    frames, weights, label = _selection(run, args)
    grid = run_grid(run, list(frames), plane, box, resolution)
    background = not args.no_background
    stem = Path(args.out) if args.out else run.directory / f"flow_{label}"
    if stem.suffix in (".h5", ".xdmf", ".png"):  # --out flow.h5: the stem flow
        stem = stem.with_suffix("")
    paths = [suffixed(stem, suffix) for suffix in (".h5", ".xdmf", ".png")]
    with rundir.claim_files(paths, reads=[run.directory]) as staging:
        values = frames_velocity(run, frames, weights, grid.points(), background, args.threads)
        _finite(values, grid)
        shown = int(frames[len(frames) // 2])
        attrs = {"run": run.data["run"], "frames": np.asarray(frames), "background": background}
        written = [*write_grid(stem, grid, run.times[frames[-1:]], values[None], attrs, staging),
                   save_png(paths[2], grid, values, run, shown, _title(run, frames, background),
                            dpi=args.dpi, staging=staging)]
    nx, ny, nz = grid.shape
    top = float(np.linalg.norm(values, axis=1).max())
    console.print(f"flow on {nx}x{ny}x{nz} nodes, |u| up to {top:.4g} μm/s:")
    for path in written:
        console.print(str(path))
    return 0


def cmd_movie(args: argparse.Namespace, console: Any) -> int:
    """``parastokes movie``: the bodies frame by frame, optionally over the flow."""
    from ..output import rundir
    from .fields import frames_velocity, run_grid
    from .grids import parse_plane, parse_resolution
    from .movie import choose_frames, write_movie
    from .run import load_run

    out = Path(args.out)
    if out.suffix.lower() not in (".mp4", ".gif"):
        raise ValueError(f"--out {out}: give a .mp4 or .gif file name")
    size = _movie_size(args.size)
    if not 0 < args.fps <= MAX_FPS:
        raise ValueError(f"--fps {args.fps}: give more than 0 and at most {MAX_FPS:g} frames per "
                         "second")
    rundir.check_free(args.run_dir)  # not while a run replaces its results
    run = load_run(args.run_dir, args.run, threads=args.threads)
    frames = choose_frames(len(run.times), args.frames)
    flow = None
    if args.flow:
        plane = parse_plane(args.plane) if args.plane is not None else None
        grid = run_grid(run, frames, plane, None, parse_resolution(args.resolution
                                                                  or MOVIE_RESOLUTION))
        points = grid.points()

        def flow(frame: int) -> tuple[Any, np.ndarray]:
            values = frames_velocity(run, [frame], [1.0], points, True, args.threads)
            _finite(values, grid)
            return grid, values

    progress = not args.quiet and sys.stderr.isatty()
    with rundir.claim_files([out], reads=[run.directory]) as staging:
        write_movie(run, out, frames, args.fps, size, flow, progress, staging)
    console.print(f"{out}: {len(frames)} frames at {args.fps:g} fps")
    return 0


def _movie_size(text: str) -> tuple[int, int]:
    """``--size WxH`` in pixels: two even numbers from 16 to :data:`MAX_PIXELS`."""
    parts = str(text).lower().split("x")
    try:
        width, height = (int(p) for p in parts)
    except ValueError:
        width = height = 0
    if not (16 <= width <= MAX_PIXELS and 16 <= height <= MAX_PIXELS) or width % 2 or height % 2:
        raise ValueError(f"--size {text}: give WxH in pixels, both even, from 16 to {MAX_PIXELS}, "
                         "e.g. 800x600")
    return width, height


def write_run_flow(directory: Path, every: int, plane: str | None, resolution: int) -> list[Path]:
    """A run's own flow output (``output.flow_every``): every ``every``-th saved frame on one
    plane as ``flow.h5`` + ``flow.xdmf`` (a time series) and ``flow.png`` (the last of them)."""
    import numpy as np

    from ..core.files import staged
    from .fields import frames_velocity, run_grid, save_png
    from .grids import PlaneSpec, parse_plane
    from .run import load_run
    from .xdmf import suffixed, write_grid

    run = load_run(directory)
    frames = list(range(0, len(run.times), every))
    spec: PlaneSpec | None = parse_plane(plane) if plane is not None else None
    grid = run_grid(run, frames, spec, None, (resolution,))
    points = grid.points()
    values = np.stack([frames_velocity(run, [f], [1.0], points) for f in frames])
    _finite(values, grid)
    stem = directory / "flow"
    with staged() as staging:
        written = [*write_grid(stem, grid, run.times[frames], values,
                               {"run": run.data["run"], "frames": np.asarray(frames)}, staging),
                   save_png(suffixed(stem, ".png"), grid, values[-1], run, frames[-1],
                            _title(run, np.array(frames[-1:]), True), staging=staging)]
    return written


def add_commands(sub: Any, parents: list[argparse.ArgumentParser]) -> None:
    """Add ``flow`` and ``movie`` to the subcommands ``sub`` of the ``parastokes`` parser."""
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("run_dir", metavar="RUN_DIR", help="output directory of a finished run")
    common.add_argument("--run", choices=["parareal", "serial"],
                        help="which run's frames (default: parareal when computed)")
    common.add_argument("--plane", metavar="AXIS=V",
                        help="a plane, e.g. z=5 or y=0 (default: x-z through the bodies)")
    common.add_argument("--resolution", metavar="N|NxM",
                        help="nodes along the longest side (square cells), or per axis")
    common.add_argument("--threads", type=int, default=None,
                        help="kernel threads (default: all of numba's)")

    p = sub.add_parser("flow", parents=[*parents, common],
                       help="the flow of a run's frame on a plane or box: HDF5+XDMF and PNG")
    which = p.add_mutually_exclusive_group()
    which.add_argument("--frame", type=int, metavar="INDEX", help="saved frame (default: last)")
    which.add_argument("--time", type=float, metavar="T", help="the saved frame nearest to T")
    which.add_argument("--average", type=float, nargs=2, metavar=("T0", "T1"),
                       help="mean over the saved frames in [T0, T1] (trapezoidal rule)")
    p.add_argument("--box", type=float, nargs=6, metavar=("X0", "X1", "Y0", "Y1", "Z0", "Z1"),
                   help="a box (3-D grid), or the extent of --plane (its range on the plane's "
                   "own axis must hold the plane)")
    # (argparse takes "-1e6" for an option unless told that such words are numbers)
    p._negative_number_matcher = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")
    p.add_argument("--no-background", action="store_true",
                   help="leave out the background shear u∞ (the bodies' disturbance only)")
    p.add_argument("--out", metavar="STEM",
                   help="output files STEM.h5, STEM.xdmf, STEM.png (default: RUN_DIR/flow_<frame>)")
    p.add_argument("--dpi", type=int, default=120, help="the picture's dots per inch (7 in wide)")
    p.set_defaults(func=cmd_flow)

    p = sub.add_parser("movie", parents=[*parents, common],
                       help="a movie of a run's bodies (MP4, or GIF), optionally over the flow")
    p.add_argument("--out", default="movie.mp4", help="movie file: .mp4, or .gif")
    p.add_argument("--frames", type=int, metavar="N", help="at most N frames (default: all saved)")
    p.add_argument("--fps", type=float, default=20.0, help="frames per second (default 20)")
    p.add_argument("--size", default="800x600", metavar="WxH", help="pixels (default 800x600)")
    p.add_argument("--flow", action="store_true", help="draw the flow of each frame under them")
    p.set_defaults(func=cmd_movie)
