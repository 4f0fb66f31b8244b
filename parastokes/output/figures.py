"""A matplotlib figure written as ``stem.FMT`` for every format, each file atomically (never half a
file): what :mod:`parastokes.output.plots` and :mod:`parastokes.output.gantt` share."""

from __future__ import annotations

import functools
from collections.abc import Sequence
from pathlib import Path
from typing import IO

from matplotlib.figure import Figure

from ..core.files import atomic_write

__all__ = ["save_figure"]


def save_figure(fig: Figure, stem: Path, formats: Sequence[str]) -> list[Path]:
    """``fig`` as ``stem.FMT`` for every format, each written atomically (never half a file)."""
    paths = []
    for fmt in formats:
        path = stem.with_suffix(f".{fmt}")
        atomic_write(path, functools.partial(_savefig, fig, fmt))
        paths.append(path)
    return paths


def _savefig(fig: Figure, fmt: str, handle: IO[bytes]) -> None:
    fig.savefig(handle, format=fmt, dpi=150, bbox_inches="tight")
