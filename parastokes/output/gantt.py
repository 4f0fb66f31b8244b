"""The Gantt chart of a Parareal run: which worker ran which task when.

Drawn from ``Timings.tasks`` (``[kind, slice, iteration, start, end, worker]`` per task, recorded
by both schedules; in ``summary.json`` under ``timings.tasks``) or from a simulated schedule
(:func:`parastokes.parareal.simulate`). One row per worker (the manager, which runs Algorithm 1's
coarse steps, on top), fine solves in blue, coarse steps in red, auxiliary solves of an
extrapolated coarse step in orange; each bar is labelled with its iteration k when it is wide
enough.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from matplotlib.figure import Figure
from matplotlib.patches import Patch

from ..parareal.timings import MANAGER
from .figures import save_figure

__all__ = ["COLORS", "gantt", "gantt_figure"]

#: Bar colour of each kind of task.
COLORS = {"fine": "C0", "coarse": "C3", "auxiliary": "C1"}


def gantt(
    tasks: Sequence[Sequence],
    stem: Path,
    formats: Sequence[str] = ("png", "pdf"),
    title: str = "",
) -> list[Path]:
    """Draw ``tasks`` as a Gantt chart into ``stem`` + each format; returns the files."""
    return save_figure(gantt_figure(tasks, title), stem, formats)


def gantt_figure(tasks: Sequence[Sequence], title: str = "") -> Figure:
    """The Gantt chart of ``tasks`` (one row per worker, the manager on top)."""
    workers = sorted({int(task[5]) for task in tasks})
    rows = {worker: i for i, worker in enumerate(reversed(workers))}
    fig = Figure(figsize=(7.5, 1.2 + 0.28 * len(workers)))
    ax = fig.subplots()
    end_time = max((float(task[4]) for task in tasks), default=1.0)
    for kind, _, k, start, end, worker in tasks:
        row = rows[int(worker)]
        width = float(end) - float(start)
        ax.broken_barh(
            [(float(start), width)], (row - 0.4, 0.8), facecolors=COLORS.get(kind, "C7"),
            edgecolor="white", linewidth=0.3,
        )
        if width > 0.025 * end_time:
            ax.text(float(start) + width / 2, row, str(k), ha="center", va="center", fontsize=5,
                    color="white")
    ax.set_yticks(list(rows.values()))
    ax.set_yticklabels(["manager" if w == MANAGER else f"worker {w}" for w in rows], fontsize=6)
    ax.set_xlabel("time since the start of the run (s)")
    ax.set_xlim(0.0, end_time * 1.01)
    kinds = [kind for kind in COLORS if any(task[0] == kind for task in tasks)]
    ax.legend(
        handles=[Patch(color=COLORS[kind], label=kind) for kind in kinds], fontsize=7,
        loc="upper left", bbox_to_anchor=(1.0, 1.0), title="bar label: iteration k",
        title_fontsize=6,
    )
    if title:
        ax.set_title(title, fontsize=8)
    ax.grid(True, axis="x", alpha=0.3)
    return fig
