"""Figures from saved results (matplotlib's object API with the Agg canvas, so no display and no
global pyplot state is involved; every figure as PNG and/or PDF).

From one run directory (:func:`draw_run`):

- ``error_decay``: η^k and η̃^k (eq. 34) against the iteration k (Figs. 4, 6a, 7a, 8a, 12a, 13a);
- ``speedup_vs_error``: the measured speedup reached for a desired error, a staircase because the
  iteration count is an integer (Figs. 6b, 7b, 12b, 13b); at least one iteration is assumed;
- ``speedup_by_iteration``: measured and theoretical speedup (eq. 14) after k iterations, with the
  bound of eq. 15 as text above each group (Figs. 6c, 7c, 8b, 12c, 13c); the measured speedup
  after the last iteration is the one the run prints;
- ``structure``: the bodies drawn by their kinds (registry): rods in the x-y and x-z planes over
  time (z: the distance to the wall; each title states how much its vertical axis is stretched);
  the vesicle projected on the x-z plane at the first and last frame with its tracked points
  (Fig. 11); a scene of several kinds also gets ``structure`` itself: all bodies together in the
  x-z plane at four times, centred on the first body (``structure_<kind>`` per kind);
- ``gantt``: which worker ran which task when (:mod:`parastokes.output.gantt`), when the summary
  holds per-task timings.

Legends sit beside the axes, never over the data; one run's legend names the curves only (its title
is above the axes), a comparison's names each run by its directory.

From several run directories (:func:`draw_comparison`): the same error and speedup figures with one
curve per run (e.g. the coarse solvers G^1..G^4 of one table), and, when the runs differ in the
number of slices, ``scaling``: speedup against N_c (strong scaling, Fig. 9c) and the runtime and
parallel-sweep time against N_c (weak scaling when T grows with N_c, Fig. 9d).

From the JSON of ``benchmarks/parareal.py --json`` (:func:`draw_benchmark`):

- ``scaling_benchmark``: strong scaling, measured and theoretical speedup against the cores per
  iteration count (Fig. 9c), and weak scaling, the runtime against the cores with eq. 37 (Fig. 9d);
- ``spatial_vs_temporal``: the speedup of the spatially parallel F (threads; process blocks), of
  Parareal and of both against the cores, with a dashed line at 1 (Fig. 10).
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from ..core.files import read_input
from ..registry import kinds as registry
from . import trajectory as io
from .figures import save_figure as _save

__all__ = [
    "RunData",
    "draw_benchmark",
    "draw_body",
    "draw_comparison",
    "draw_run",
    "error_decay",
    "load_run",
    "scaling",
    "scaling_from_benchmark",
    "spatial_vs_temporal",
    "speedup_by_iteration",
    "speedup_vs_error",
    "staircase",
    "structure",
]

FORMATS = ("png", "pdf")
#: The figures of :func:`draw_comparison` and of :func:`draw_benchmark`, by stem.
COMPARISON_FIGURES = ("error_decay", "speedup_vs_error", "speedup_by_iteration", "scaling")
BENCHMARK_FIGURES = ("scaling_benchmark", "spatial_vs_temporal")


@dataclass
class RunData:
    """What the figures need from one run directory."""

    label: str
    summary: dict[str, Any]
    trajectory: Path | None

    @property
    def has_parareal(self) -> bool:
        return bool(self.summary.get("speedup"))

    def accuracy(self) -> tuple[np.ndarray, str]:
        """η^k when a serial reference was computed, else η̃^k; and the symbol's name."""
        errors = self.summary.get("errors")
        if errors:
            return np.asarray(errors, dtype=float), "relative error η"
        return np.asarray(self.summary["increments"], dtype=float), "relative increment η̃"


def load_run(directory: str | Path, label: str | None = None) -> RunData:
    """Read ``summary.json`` (and locate ``trajectory.h5``) of a run directory; the label is the
    directory's name (short, for legends) unless given."""
    directory = Path(directory)
    summary = io.read_summary(directory / "summary.json")
    trajectory = directory / "trajectory.h5"
    return RunData(
        label=label or directory.resolve().name,
        summary=summary,
        trajectory=trajectory if trajectory.exists() else None,
    )


def _finish(fig: Figure, ax, stem: Path, formats: Sequence[str], *, integer_x: bool = False,
            **grid) -> list[Path]:
    """Integer ticks on x (iteration counts) if asked, a light grid (``grid``: which/axis), the
    legend outside the axes (never over the data), and the files."""
    if integer_x:
        ax.xaxis.get_major_locator().set_params(integer=True)
    ax.grid(True, alpha=0.3, **grid)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0)
    return _save(fig, stem, formats)


def _named(runs: Sequence[RunData], run: RunData, what: str) -> str:
    """A legend entry: ``what`` alone for one run, prefixed by the run's label for several."""
    return what if len(runs) == 1 else f"{run.label}: {what}"


def _titled(ax, runs: Sequence[RunData]) -> None:
    """One run: its title (shortened) above the axes, since the legend names no run."""
    title = runs[0].summary.get("title") if len(runs) == 1 else ""
    if title:
        ax.set_title(title if len(title) <= 60 else title[:57] + "...", fontsize=8)


# ---- accuracy and speedup --------------------------------------------------------------------
def error_decay(runs: Sequence[RunData], stem: Path, formats: Sequence[str] = FORMATS):
    """η^k (solid) and η̃^k (dashed) against k, one colour per run."""
    fig = Figure(figsize=(5.5, 4))
    ax = fig.subplots()
    for i, run in enumerate(runs):
        k = np.arange(1, len(run.summary["increments"]) + 1)
        color = f"C{i}"
        if run.summary.get("errors"):
            label = _named(runs, run, "error η^k")
            ax.semilogy(k, run.summary["errors"], "o-", color=color, label=label)
        label = _named(runs, run, "increment η̃^k")
        ax.semilogy(k, run.summary["increments"], "s--", color=color, alpha=0.7, label=label)
    ax.set_xlabel("iteration k")
    ax.set_ylabel("relative error / increment (eq. 34)")
    _titled(ax, runs)
    return _finish(fig, ax, stem, formats, integer_x=True, which="both")


def staircase(
    accuracy: Sequence[float] | np.ndarray, measured: Sequence[float], desired: np.ndarray
):
    """Speedup for each desired error: the measured speedup after the first k >= 1 with
    accuracy[k-1] <= desired (NaN where no iteration reaches it)."""
    out = np.full(len(desired), np.nan)
    for i, target in enumerate(desired):
        reached = [k for k, value in enumerate(accuracy) if value <= target]
        if reached:
            out[i] = measured[reached[0]]
    return out


def speedup_vs_error(runs: Sequence[RunData], stem: Path, formats: Sequence[str] = FORMATS):
    """The staircase of Fig. 6b: speedup against the desired error, one curve per run."""
    fig = Figure(figsize=(5.5, 4))
    ax = fig.subplots()
    finite = [v for run in runs for v in run.accuracy()[0] if np.isfinite(v) and v > 0]
    low = 10 ** np.floor(np.log10(min(finite))) if finite else 1e-12
    desired = np.logspace(np.log10(low) - 0.5, -1, 400)
    for i, run in enumerate(runs):
        accuracy, name = run.accuracy()
        measured = run.summary["speedup"]["by_iteration"]["measured"]
        steps = staircase(accuracy, measured, desired)
        ax.semilogx(desired, steps, color=f"C{i}", label=_named(runs, run, "measured"))
    ax.set_xlabel(f"desired {name}" if len(runs) == 1 else "desired error")
    ax.set_ylabel("measured speedup (eq. 14)")
    _titled(ax, runs)
    return _finish(fig, ax, stem, formats, which="both")


def speedup_by_iteration(runs: Sequence[RunData], stem: Path, formats: Sequence[str] = FORMATS):
    """Measured (bars) and theoretical (hatched) speedup after k iterations, a line at 1; the
    bound of eq. 15 as text above each group (as a bar it would flatten the others). A run of the
    pipelined schedule shows that schedule's model and critical-path bound instead."""
    fig = Figure(figsize=(5.5, 4))
    ax = fig.subplots()
    width = 0.8 / (2 * len(runs))
    pipelined = {run.summary["speedup"].get("schedule") == "pipelined" for run in runs}
    for i, run in enumerate(runs):
        data = run.summary["speedup"]["by_iteration"]
        model = ("pipelined model" if run.summary["speedup"].get("schedule") == "pipelined"
                 else "eq. 14")
        k = np.asarray(data["iterations"], dtype=float)
        # an iteration whose time was lost (an interrupt between checkpoint and history) is
        # null in the summary: nan here, no bar
        measured = np.asarray(data["measured"], dtype=float)
        offset = (2 * i - len(runs) + 0.5) * width
        ax.bar(k + offset, measured, width, color=f"C{i}", label=_named(runs, run, "measured"))
        ax.bar(
            k + offset + width,
            data["theoretical"],
            width,
            color=f"C{i}",
            alpha=0.4,
            hatch="//",
            label=_named(runs, run, f"theoretical ({model})"),
        )
        tops = np.fmax(measured, np.asarray(data["theoretical"], dtype=float))
        for x, top, bound in zip(k + offset + width / 2, tops, data["bound"], strict=True):
            ax.annotate(f"≤{bound:.3g}", (x, top), xytext=(0, 2), textcoords="offset points",
                        ha="center", va="bottom", fontsize=6, color="0.3")
    ax.axhline(1.0, color="0.5", lw=0.8, ls=":")
    ax.set_ylim(top=ax.get_ylim()[1] * 1.12)  # room for the bounds' text
    ax.set_xlabel("iterations N_it")
    bounds = {False: "eq. 15", True: "critical path"}
    ax.set_ylabel(f"speedup (text: bound, {' / '.join(bounds[p] for p in sorted(pipelined))})")
    ax.set_xticks(sorted({k for run in runs for k in run.summary["speedup"]["by_iteration"]
                          ["iterations"]}))
    _titled(ax, runs)
    return _finish(fig, ax, stem, formats, axis="y")


def scaling(runs: Sequence[RunData], stem: Path, formats: Sequence[str] = FORMATS):
    """Speedup against N_c (measured solid, theoretical dashed, per iteration count; Fig. 9c) and
    the runtime and parallel-sweep time of the first iteration against N_c (Fig. 9d)."""
    runs = sorted(runs, key=lambda r: r.summary["speedup"]["n_slices"])
    cores = np.array([r.summary["speedup"]["n_slices"] for r in runs])
    fig = Figure(figsize=(10, 4))
    left, right = fig.subplots(1, 2)
    depth = min(len(r.summary["speedup"]["by_iteration"]["iterations"]) for r in runs)
    for j in range(depth):
        measured = [r.summary["speedup"]["by_iteration"]["measured"][j] for r in runs]
        theory = [r.summary["speedup"]["by_iteration"]["theoretical"][j] for r in runs]
        left.plot(cores, measured, "o-", color=f"C{j}", label=f"N_it = {j + 1}: measured")
        left.plot(cores, theory, "s--", color=f"C{j}", label=f"N_it = {j + 1}: theoretical")
    left.set_xlabel("N_c (slices)")
    left.set_ylabel("speedup")
    left.legend(fontsize=7)
    left.grid(True, alpha=0.3)
    total = [r.summary["timings"]["elapsed_by_iteration"][0] for r in runs]
    sweep = [r.summary["timings"]["parallel_sweeps"][0] for r in runs]
    right.plot(cores, total, "o-", label="Parareal, N_it = 1")
    right.plot(cores, sweep, "s-", label="parallel sweep")
    right.set_xlabel("N_c (slices)")
    right.set_ylabel("wall time (s)")
    right.legend(fontsize=7)
    right.grid(True, alpha=0.3)
    return _save(fig, stem, formats)


# ---- benchmark figures (benchmarks/parareal.py --json) --------------------------------------
def _column(rows: Sequence[dict[str, Any]], key: str) -> tuple[np.ndarray, np.ndarray]:
    """Cores and ``key`` of the rows where ``key`` is a number (None: not measured)."""
    pairs = [(row["cores"], row[key]) for row in rows if row.get(key) is not None]
    cores = np.array([c for c, _ in pairs], dtype=float)
    return cores, np.array([v for _, v in pairs], dtype=float)


def _core_axis(ax: Any, rows: Sequence[dict[str, Any]]) -> None:
    """Ticks at the measured core counts, from 0.5 to half a core past the largest."""
    cores = sorted({row["cores"] for row in rows})
    if cores:
        ax.set_xticks(cores)
        ax.set_xlim(0.5, cores[-1] + 0.5)


def scaling_from_benchmark(data: dict[str, Any], stem: Path, formats: Sequence[str] = FORMATS):
    """Fig. 9 from the benchmark's ``scaling`` section: strong scaling speedup against the cores
    (measured solid, theoretical dashed, one colour per N_it; the speedup against an actual serial
    run dotted) and weak scaling runtime against the cores, with eq. 37 dashed."""
    section = data["scaling"]
    fig = Figure(figsize=(10, 4))
    left, right = fig.subplots(1, 2)
    strong = section["strong"]
    for j, n_it in enumerate(sorted({row["iterations"] for row in strong})):
        rows = sorted((r for r in strong if r["iterations"] == n_it), key=lambda r: r["cores"])
        color = f"C{j}"
        left.plot(*_column(rows, "measured"), "o-", color=color, label=f"N_it = {n_it}: measured")
        left.plot(
            *_column(rows, "theoretical"), "s--", color=color, label=f"N_it = {n_it}: theoretical"
        )
        if any(r.get("vs_serial") is not None for r in rows):
            left.plot(
                *_column(rows, "vs_serial"),
                "^:",
                color=color,
                alpha=0.7,
                label=f"N_it = {n_it}: vs serial run",
            )
    left.set_xlabel("cores N_c")
    left.set_ylabel("speedup")
    left.set_title("strong scaling (T fixed)")
    left.legend(fontsize=7)
    left.grid(True, alpha=0.3)
    weak = sorted(section["weak"], key=lambda r: r["cores"])
    right.plot(*_column(weak, "runtime"), "o-", label="Parareal, N_it = 1")
    if any(r.get("parallel_sweep") is not None for r in weak):
        right.plot(*_column(weak, "parallel_sweep"), "s-", label="parallel sweep")
    if any(r.get("model") is not None for r in weak):
        right.plot(*_column(weak, "model"), "k--", label="2 N_c γ_G + γ_F (eq. 37)")
    right.set_xlabel("cores N_c")
    right.set_ylabel("wall time (s)")
    right.set_title("weak scaling (T / N_c fixed)")
    right.set_ylim(bottom=0)
    right.legend(fontsize=7)
    right.grid(True, alpha=0.3)
    _core_axis(left, strong)
    _core_axis(right, weak)
    return _save(fig, stem, formats)


#: The strategies of Fig. 10: key in the benchmark's ``fig10`` rows, label, marker.
STRATEGIES = (
    ("spatial_threads", "spatial F, threads", "o-"),
    ("spatial_blocks", "spatial F, process blocks", "s-"),
    ("parareal", "temporal (Parareal)", "^-"),
    ("both", "both (N_c/2 workers x 2 threads)", "D-"),
)


def spatial_vs_temporal(data: dict[str, Any], stem: Path, formats: Sequence[str] = FORMATS):
    """Fig. 10 from the benchmark's ``fig10`` section: speedup against the cores for each
    strategy (a strategy not measured at a core count, e.g. "both" below 4 cores, is left out),
    with a dashed line at 1 (no speedup)."""
    rows = sorted(data["fig10"], key=lambda r: r["cores"])
    fig = Figure(figsize=(5.5, 4))
    ax = fig.subplots()
    for i, (key, label, style) in enumerate(STRATEGIES):
        cores, values = _column(rows, key)
        if len(cores):
            ax.plot(cores, values, style, color=f"C{i}", label=label)
    ax.axhline(1.0, color="k", ls="--", lw=1, label="no speedup")
    ax.set_xlabel("cores N_c")
    ax.set_ylabel("speedup over serial F (eq. 35)")
    ax.set_ylim(bottom=0)
    _core_axis(ax, rows)
    return _finish(fig, ax, stem, formats)


def draw_benchmark(
    json_path: str | Path, out_dir: str | Path, formats: Sequence[str] = FORMATS
) -> list[Path]:
    """The figures of a ``benchmarks/parareal.py --json`` file in ``out_dir``: ``scaling_benchmark``
    when it has a ``scaling`` section, ``spatial_vs_temporal`` when it has ``fig10``. Returns the
    files written; a missing file or one without either section raises (FileNotFoundError,
    ValueError)."""
    json_path = Path(json_path)
    if not json_path.exists():
        raise FileNotFoundError(f"benchmark file {json_path} not found")
    try:
        data = json.loads(read_input(json_path, "measurements").decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise ValueError(f"{json_path}: not a JSON file ({error})") from error
    if not isinstance(data, dict) or (not data.get("scaling") and not data.get("fig10")):
        raise ValueError(
            f"{json_path}: no 'scaling' or 'fig10' section (write it with "
            "benchmarks/parareal.py --sections scaling fig10 --json FILE)"
        )
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    figures = (("scaling", scaling_from_benchmark), ("fig10", spatial_vs_temporal))
    for section, draw in figures:
        if not data.get(section):
            continue
        name = "scaling_benchmark" if section == "scaling" else "spatial_vs_temporal"
        try:
            written += draw(data, out / name, formats)
        except (KeyError, TypeError, AttributeError) as error:
            raise ValueError(
                f"{json_path}: section '{section}' is not in the format of "
                f"benchmarks/parareal.py --json ({type(error).__name__}: {error})"
            ) from error
    return written


# ---- structures ------------------------------------------------------------------------------
def structure(
    trajectory: Path, stem: Path, formats: Sequence[str] = FORMATS, run: str | None = None
):
    """The bodies over time, drawn by their kinds (registry): rods in the x-y plane coloured by
    time, the vesicle's x-z projection at the first and last frame with tracked points (Fig. 11).
    One figure per kind: ``stem`` for one kind, ``stem_<kind>`` for several."""
    data = io.read_trajectory(trajectory, run)
    by_kind: dict[str, dict[str, Any]] = {}
    for name, body in data["bodies"].items():
        by_kind.setdefault(body["kind"], {})[name] = body
    written = []
    for kind, bodies in by_kind.items():
        fig = Figure()
        registry.get(kind).draw(fig, bodies, data["time"], data["run"])
        name = stem if len(by_kind) == 1 else stem.with_name(f"{stem.name}_{kind.split(':')[-1]}")
        written += _save(fig, name, formats)
    if len(by_kind) > 1:
        fig = Figure()
        scene_snapshots(fig, data["bodies"], data["time"], data["run"])
        written += _save(fig, stem, formats)
    return written


def draw_body(ax: Any, body: Mapping[str, Any], frame: int, axes: tuple[int, int],
              color: str, label: str | None = None) -> None:
    """One frame of ``body`` (as :func:`parastokes.output.trajectory.read_trajectory` gives it)
    projected on the plane of ``axes``: its triangles' edges, its polyline (thicker), or its points
    as dots (a rigid surface, its centre)."""
    from matplotlib.collections import LineCollection

    i, j = axes
    points = np.asarray(body["positions"][frame])
    cells = np.asarray(body["connectivity"])
    if cells.shape[1] == 1:
        ax.plot(points[:, i], points[:, j], ".", color=color, ms=2, label=label)
        return
    pairs = {3: [0, 1, 1, 2, 2, 0], 2: [0, 1]}[cells.shape[1]]
    segments = points[:, [i, j]][cells[:, pairs].reshape(-1, 2)]
    ax.add_collection(LineCollection(list(segments), colors=color, label=label,
                                     linewidths=1.5 if cells.shape[1] == 2 else 0.4))


def scene_snapshots(fig: Figure, bodies: dict[str, dict[str, Any]], times: np.ndarray, run: str,
                    count: int = 4) -> None:
    """Bodies of several kinds together: the x-z plane at ``count`` times, one axes each, centred
    on the first body (so that the others are seen passing it), at true scale."""
    frames = sorted(set(np.linspace(0, len(times) - 1, count).round().astype(int).tolist()))
    first = next(iter(bodies.values()))
    centres = [float(first["positions"][f][:, 0].mean()) for f in frames]
    reach = max(float(np.abs(b["positions"][f][:, 0] - c).max())
                for b in bodies.values() for f, c in zip(frames, centres, strict=True))
    fig.set_size_inches(7, 1.6 + 1.4 * len(frames))
    fig.set_layout_engine("constrained")
    axes = fig.subplots(len(frames), 1, squeeze=False)[:, 0]
    for ax, frame, centre in zip(axes, frames, centres, strict=True):
        for index, (name, body) in enumerate(bodies.items()):
            draw_body(ax, body, frame, (0, 2), f"C{index}", name)
        ax.set_xlim(centre - 1.05 * reach, centre + 1.05 * reach)
        ax.set_aspect("equal")
        ax.autoscale_view(scalex=False)
        ax.set_ylabel("z (μm)")
        ax.set_title(f"t = {times[frame]:.4g} s ({run}); centred on {next(iter(bodies))}",
                     fontsize=8)
    axes[-1].set_xlabel("x (μm)")
    axes[0].legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)


# ---- entry points ----------------------------------------------------------------------------
def draw_run(directory: str | Path, formats: Sequence[str] = FORMATS) -> list[Path]:
    """All figures of one run directory, written into it; returns the files written."""
    directory = Path(directory)
    run = load_run(directory)
    written = []
    if run.has_parareal:
        written += error_decay([run], directory / "error_decay", formats)
        written += speedup_vs_error([run], directory / "speedup_vs_error", formats)
        written += speedup_by_iteration([run], directory / "speedup_by_iteration", formats)
        written += _gantt_of(run, directory / "gantt", formats)
    if run.trajectory is not None:
        written += structure(run.trajectory, directory / "structure", formats)
    return written


def _gantt_of(run: RunData, stem: Path, formats: Sequence[str]) -> list[Path]:
    """The Gantt chart of a run whose summary holds per-task timings (none for older runs)."""
    from .gantt import gantt_figure

    timings = run.summary.get("timings") or {}
    if not timings.get("tasks"):
        return []
    schedule = timings.get("schedule", "standard")
    title = f"{run.label}: {schedule} schedule, {run.summary.get('workers')} workers"
    return _save(gantt_figure(timings["tasks"], title), stem, formats)


def draw_comparison(
    directories: Sequence[str | Path], out: str | Path, formats: Sequence[str] = FORMATS
) -> list[Path]:
    """Comparison figures of several runs (one curve each) in ``out``; returns the files."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    runs = [r for r in (load_run(d) for d in directories) if r.has_parareal]
    if not runs:
        return []
    written = error_decay(runs, out / "error_decay", formats)
    written += speedup_vs_error(runs, out / "speedup_vs_error", formats)
    written += speedup_by_iteration(runs, out / "speedup_by_iteration", formats)
    if len({r.summary["speedup"]["n_slices"] for r in runs}) > 1:
        written += scaling(runs, out / "scaling", formats)
    return written
