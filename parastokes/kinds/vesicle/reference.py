"""Plain-numpy oracle of the vesicle's compiled spring forces (readable, slow; used by the tests):
docs/physics.md (14) with whole-array operations, against :func:`.mechanics.spring_forces`'s loop.
"""

from __future__ import annotations

import numpy as np


def spring_forces(
    points: np.ndarray, edges: np.ndarray, rest: np.ndarray, stiffness: float
) -> np.ndarray:
    """Hookean edge springs, docs/physics.md (14)."""
    d = points[edges[:, 1]] - points[edges[:, 0]]
    length = np.linalg.norm(d, axis=1, keepdims=True)
    pull = stiffness * (length - rest[:, None]) * d / length
    out = np.zeros_like(points)
    np.add.at(out, edges[:, 0], pull)
    np.add.at(out, edges[:, 1], -pull)
    return out
