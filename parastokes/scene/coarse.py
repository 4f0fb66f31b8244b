"""A scene on a coarser grid for the coarse solver (Remark 4, eqs. 32-33, body by body).

:meth:`parastokes.scene.Scene.coarsened` calls :func:`coarsened`: every body that has a coarser
grid (a ``coarsened(factor)`` method: rods, σ_c = factor σ_f; rigid and prescribed-motion bodies,
each part of the surface with ``factor`` times fewer points) is replaced by its coarse body, the
others (vesicles, chains, users' bodies) are kept as they are; ``Scene.coarse_bodies`` (config:
``[scene] coarse_bodies``) names the bodies to coarsen when not all should be (a rod's coarse
grid may cost Parareal more iterations than a rigid body's coarse surface: docs/bodies.md). The
coarse scene has the same
bodies, names, fluid and Θ (a coarse body's parameters mean the same as the fine body's), so
Lagrange nodes such as ``"sphere.epsilon"`` carry over.

:class:`SceneTransfer` maps a scene state between the grids block by block: each coarsened body's
rows through its own transfer (a rigid body's pose row carried over exactly and its surface
rebuilt; a rod's spline in arclength), a kept body's rows copied. So a rigid body's pose survives
``restrict`` and ``prolong`` bit for bit, and ``prolong(restrict(x))`` is exact for a scene of
rigid and kept bodies (a rod's spline interpolates the fine nodes: exact to round-off).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["SceneTransfer", "coarsened"]


def has_coarse_grid(body: Any) -> bool:
    """Whether ``body`` offers ``coarsened(factor) -> (coarse body, transfer)``."""
    return callable(getattr(body, "coarsened", None))


def check_names(scene: Any) -> None:
    """ValueError unless every name in ``scene.coarse_bodies`` is one of its bodies that has a
    coarser grid."""
    for name in scene.coarse_bodies:
        if name not in scene.names:
            raise ValueError(f"coarse_bodies: no body is named {name!r}; the bodies: "
                             f"{', '.join(scene.names)}")
        if not has_coarse_grid(scene.bodies[scene.names.index(name)]):
            raise ValueError(f"coarse_bodies: {name} has no coarser grid (rods and rigid bodies "
                             "have); leave it out")


def coarsened(scene: Any, factor: int) -> tuple[Any, SceneTransfer]:
    """``scene`` (a :class:`~parastokes.scene.Scene`, which imports this module) with every body
    that has a coarser grid on it (module text; only those named in ``scene.coarse_bodies`` when
    it is not None), and the transfer; ValueError when there is none to coarsen, or naming the
    body whose grid ``factor`` does not fit."""
    if isinstance(factor, bool) or not isinstance(factor, int | np.integer) or factor < 1:
        raise ValueError(f"factor: must be a positive integer, got {factor!r}")
    which = [i for i, body in enumerate(scene.bodies) if has_coarse_grid(body) and (
        scene.coarse_bodies is None or scene.names[i] in scene.coarse_bodies)]
    if not which:
        what = "is named in coarse_bodies" if scene.coarse_bodies is not None else (
            "has a coarser grid (rods and rigid bodies have)")
        raise ValueError(f"none of the scene's bodies ({', '.join(scene.names)}) {what}; use "
                         "coarse.grid_factor = 1")
    bodies: list[Any] = list(scene.bodies)
    transfers: list[Any] = [None] * len(bodies)
    for i in which:
        try:
            bodies[i], transfers[i] = scene.bodies[i].coarsened(int(factor))
        except ValueError as error:
            raise ValueError(f"{scene.names[i]}: {error}") from error
    try:
        coarse = dataclasses.replace(scene, bodies=tuple(bodies))
    except ValueError as error:
        raise ValueError(f"on the grid {factor} times coarser: {error}") from error
    return coarse, SceneTransfer(scene, coarse, tuple(transfers))


@dataclass(frozen=True)
class SceneTransfer:
    """Restriction (eq. 32) and prolongation (eq. 33) between the ``fine`` and the ``coarse``
    scene: body by body, through ``transfers`` (None: the body is the same on both grids)."""

    fine: Any  # Scene
    coarse: Any
    transfers: tuple[Any, ...]

    def _moved(self, source: Any, target: Any, x: np.ndarray, way: str) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        rows = sum(n for _, n, _ in source.shapes)
        width = max(c for _, _, c in source.shapes)
        if x.shape != (rows, width):
            raise ValueError(f"state: expected shape {(rows, width)}, got {x.shape}")
        parts = [np.array(block) if transfer is None else getattr(transfer, way)(block)
                 for block, transfer in zip(source.blocks(x), self.transfers, strict=True)]
        return target.stack(parts)

    def restrict(self, x_fine: np.ndarray) -> np.ndarray:
        """Fine scene state -> coarse scene state."""
        return self._moved(self.fine, self.coarse, x_fine, "restrict")

    def prolong(self, x_coarse: np.ndarray) -> np.ndarray:
        """Coarse scene state -> fine scene state."""
        return self._moved(self.coarse, self.fine, x_coarse, "prolong")
