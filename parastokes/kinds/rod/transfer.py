"""Grid transfer of rod states between a fine and a coarse node set (paper Remark 4, eqs. 32-33).

The paper maps solutions between grids "using cubic splines in terms of the arclength of the rod"
(section 5.1.2). Here every column of a rod's state (positions and the three frame vectors) is
interpolated by a cubic spline (scipy's not-a-knot ``CubicSpline``) in arclength s and evaluated at
the other grid's nodes; the frames are then re-orthonormalized (polar factor,
:func:`~parastokes.bodies.frames.orthonormalize`). With σ_c = c σ_f the coarse nodes are a subset of
the fine ones, so restriction reproduces the fine node values (the spline interpolates) and
``restrict(prolong(x_c)) == x_c`` to round-off.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline

from ...bodies.frames import orthonormalize


def resample(state: np.ndarray, n_rods: int, m_from: int, m_to: int) -> np.ndarray:
    """Spline-resample each rod of ``state`` from ``m_from`` to ``m_to`` equispaced nodes."""
    x = np.asarray(state, dtype=float)
    if x.shape != (n_rods * m_from, 12):
        raise ValueError(f"state: expected shape {(n_rods * m_from, 12)}, got {x.shape}")
    s_from = np.linspace(0.0, 1.0, m_from)
    s_to = np.linspace(0.0, 1.0, m_to)
    out = CubicSpline(s_from, x.reshape(n_rods, m_from, 12), axis=1)(s_to)
    return orthonormalize(np.ascontiguousarray(out.reshape(n_rods * m_to, 12)))


@dataclass(frozen=True)
class RodTransfer:
    """Restriction I_σ^{σ_c} and prolongation I_{σ_c}^σ between ``fine_points`` and
    ``coarse_points`` nodes per rod (eqs. 32-33); used by the coarse-grid combinator of
    :mod:`parastokes.parareal`."""

    n_rods: int
    fine_points: int
    coarse_points: int

    def restrict(self, x_fine: np.ndarray) -> np.ndarray:
        """Fine state -> coarse state."""
        return resample(x_fine, self.n_rods, self.fine_points, self.coarse_points)

    def prolong(self, x_coarse: np.ndarray) -> np.ndarray:
        """Coarse state -> fine state."""
        return resample(x_coarse, self.n_rods, self.coarse_points, self.fine_points)
