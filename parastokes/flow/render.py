"""Pictures of a flow in a plane: the speed as colour, streamlines of the in-plane velocity, the
bodies drawn over it (matplotlib's object API, Agg canvas; no display involved).

The streamlines are those of the two in-plane components (``streamplot``), so in a plane the flow
crosses they are the projection of the flow, not particle paths. The speed is shown on a
logarithmic scale (it falls off like r⁻¹ or r⁻² away from the bodies, so a linear scale shows only
their neighbourhood), over three decades below its 99.5th percentile.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from matplotlib.colors import LogNorm
from matplotlib.figure import Figure

from ..output.plots import draw_body
from .grids import AXES, Grid

__all__ = ["draw_bodies", "draw_plane", "speed_limits"]


def draw_bodies(ax: Any, bodies: Mapping[str, Mapping[str, np.ndarray]], frame: int,
                axes: tuple[int, int], color: str = "k") -> None:
    """Every body of ``bodies`` (as :func:`parastokes.output.trajectory.read_trajectory` gives them)
    at ``frame``, projected on the plane of ``axes`` (:func:`parastokes.output.plots.draw_body`)."""
    for body in bodies.values():
        draw_body(ax, body, frame, axes, color)


def speed_limits(speed: np.ndarray) -> tuple[float, float] | None:
    """The colour scale of ``speed`` values: three decades below their 99.5th percentile (or
    from their 1st percentile if higher); None when all are zero."""
    positive = speed[speed > 0]
    if not positive.size:
        return None
    high = float(np.percentile(positive, 99.5))
    low = max(float(np.percentile(positive, 1.0)), 1e-3 * high)
    return low, max(high, low * 1.0001)


def draw_plane(fig: Figure, grid: Grid, velocity: np.ndarray, title: str, wall: bool = False,
               bodies: Mapping[str, Mapping[str, np.ndarray]] | None = None,
               frame: int = -1, density: float = 1.2,
               speed_range: tuple[float, float] | None = None) -> Any:
    """The speed and streamlines of ``velocity`` (points of ``grid``, 3) in the plane ``grid``,
    with ``bodies`` at ``frame`` over them and the wall z = 0 shaded; returns the axes.
    ``speed_range``: the colour scale's (low, high) (default: :func:`speed_range` of this
    field; a movie passes one for all its frames)."""
    plane = grid.plane_axes
    if plane is None:
        raise ValueError("draw_plane: the grid is not a plane")
    i, j = plane
    field = grid.field(velocity).squeeze()  # (n_j, n_i, 3)
    axes = grid.axes()
    a, b = axes[i], axes[j]
    speed = np.linalg.norm(field, axis=-1)
    ax = fig.subplots()
    limits = speed_range or speed_limits(speed)
    if limits is not None:
        low, high = limits
        norm = LogNorm(vmin=low, vmax=high)
        mesh = ax.pcolormesh(a, b, np.clip(speed, low, None), norm=norm, cmap="magma",
                             shading="gouraud", rasterized=True)
        fig.colorbar(mesh, ax=ax, label="|u| (μm/s)", shrink=0.85)
        ax.streamplot(a, b, field[..., i], field[..., j], color="w", linewidth=0.6,
                      density=density, arrowsize=0.6)
    bottom = b[0]
    if wall and j == 2:  # the wall z = 0 as a grey band below the fluid
        bottom = min(b[0], 0.0) - 0.03 * (b[-1] - b[0])
        ax.axhspan(bottom, 0.0, color="0.55", zorder=3)
    if bodies is not None:
        draw_bodies(ax, bodies, frame, (i, j), color="c")
    ax.set_xlim(a[0], a[-1])
    ax.set_ylim(bottom, b[-1])
    ax.set_aspect("equal")
    ax.set_xlabel(f"{AXES[i]} (μm)")
    ax.set_ylabel(f"{AXES[j]} (μm)")
    ax.set_title(title, fontsize=8)
    return ax
