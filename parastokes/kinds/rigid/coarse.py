"""A rigid body on a coarser surface for the coarse solver (Remark 4, eqs. 32-33, for rigid and
prescribed-motion bodies; docs/bodies.md, "Rigid bodies").

A rigid body's state is its pose plus its surface points, a function of the pose
(:mod:`.system`). Its coarse grid is the same shape with fewer points: every part of the surface
(a sphere's, a spheroid's, a helix's points; a rod's rings; a bacterium's head and flagellum)
gets ``ceil(n / factor)`` of its ``n`` (at least its minimum), and ε grows with the measured
spacing (ε_c = ε · h_c / h), so the blobs still cover the gaps as on the fine surface. The
grid transfer carries the pose row over unchanged and rebuilds the other grid's surface from it:
``restrict`` and ``prolong`` are exact (``prolong(restrict(x)) == x`` for a state whose surface
is that of its pose), there is nothing to interpolate. The dense solve of each coarse evaluation
then costs about factor⁻³ of the fine one (the assembly factor⁻²).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from .shapes import Bacterium, Helix, PointCloud, Rod, Sphere, Spheroid

__all__ = ["RigidTransfer", "coarse_shape"]


def _fewer(n: int, factor: int, least: int) -> int:
    return max(least, math.ceil(n / factor))


def coarse_shape(shape: Any, factor: int) -> Any:
    """``shape`` with its points divided by ``factor`` (module text); ValueError for a shape
    that cannot be resampled (a user's point cloud) or a bad factor."""
    if isinstance(factor, bool) or not isinstance(factor, int | np.integer) or factor < 1:
        raise ValueError(f"factor: must be a positive integer, got {factor!r}")
    factor = int(factor)
    if isinstance(shape, Sphere | Spheroid):
        return dataclasses.replace(shape, n_points=_fewer(shape.n_points, factor, 4))
    if isinstance(shape, Helix):
        return dataclasses.replace(shape, n_points=_fewer(shape.n_points, factor, 2))
    if isinstance(shape, Rod):
        return dataclasses.replace(shape, rings=_fewer(shape.rings, factor, 2))
    if isinstance(shape, Bacterium):
        return dataclasses.replace(shape, head=coarse_shape(shape.head, factor),
                                   tail=coarse_shape(shape.tail, factor))
    what = "a user's point cloud" if isinstance(shape, PointCloud) else type(shape).__name__
    raise ValueError(f"{what} cannot be resampled on a coarser surface (coarse.grid_factor); "
                     "use grid_factor = 1 (or a built-in shape)")


@dataclass(frozen=True)
class RigidTransfer:
    """Restriction (eq. 32) and prolongation (eq. 33) between the ``fine`` and the ``coarse``
    :class:`.system.RigidBody`: the pose row carried over, the surface rebuilt from it."""

    fine: Any
    coarse: Any

    @staticmethod
    def _pose(body: Any, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        if x.ndim != 2 or x.shape[1] != 8 or len(x) != 1 + body.n_surface:
            raise ValueError(f"state: expected shape {(1 + body.n_surface, 8)}, got {x.shape}")
        return x[0]

    def _moved(self, source: Any, target: Any, x: np.ndarray) -> np.ndarray:
        pose = self._pose(source, x)
        return target.state_of(pose[:3], pose[3:7], float(pose[7]))  # the pose row as it was

    def restrict(self, x_fine: np.ndarray) -> np.ndarray:
        """Fine state -> coarse state (the same pose, the coarse surface)."""
        return self._moved(self.fine, self.coarse, x_fine)

    def prolong(self, x_coarse: np.ndarray) -> np.ndarray:
        """Coarse state -> fine state (the same pose, the fine surface)."""
        return self._moved(self.coarse, self.fine, x_coarse)
