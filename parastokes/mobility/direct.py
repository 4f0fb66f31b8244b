"""The direct solver: LU factorization of the Stokeslet matrix (scipy.linalg), reused from the
body frame for a single body in free space (:mod:`parastokes.mobility.selfsolve`)."""

from __future__ import annotations

import numpy as np

from .errors import SolveInfo
from .scaling import Scaling, relative_residual
from .selfsolve import LabFactor, RotatedFactor, saddle_solve
from .system import SurfaceSet


def factor_for(sset: SurfaceSet) -> tuple[LabFactor | RotatedFactor, bool]:
    """The factorization of M for ``sset`` and whether it is a reused body-frame one."""
    if sset.n_bodies == 1 and not sset.wall:
        return RotatedFactor(sset.placed[0], sset.mu), True
    names = ", ".join(p.name for p in sset.placed)
    return LabFactor(sset.points, sset.epsilon, sset.mu, sset.wall, sset.motion(), names), False


def direct_solve(
    sset: SurfaceSet, g: np.ndarray, ft: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray | None, SolveInfo]:
    """Mobility (``ft`` (B, 6) given: M f = K Y + g, Kᵀ f = ft) or, with ``ft`` None, the
    resistance solve M f = g. Returns (f (3N,), Y (B, 6) or None, info).

    The residual is computed with the assembled matrix; a reused body-frame factorization reports
    the residual of its own check (:class:`parastokes.mobility.selfsolve.BodyFrameFactor`).
    """
    factor, reused = factor_for(sset)
    if ft is None:
        f, y = factor.solve(g), None
        r_v, r_ft, ft_ref = None, np.zeros((sset.n_bodies, 6)), np.zeros((sset.n_bodies, 6))
    else:
        motion = factor.motion
        f, yflat = saddle_solve(factor, motion, g, ft.ravel())
        y = yflat.reshape(-1, 6)
        r_ft, ft_ref = sset.reduce(f) - ft, ft
    if isinstance(factor, RotatedFactor):
        residual = factor.base.residual
    else:
        r_v = factor.matrix @ f - g - (0.0 if y is None else sset.apply_motion(y))
        residual = relative_residual(r_v, r_ft, g, ft_ref, Scaling(sset.mu, sset.length))
    return f, y, SolveInfo("dense", 0, residual, reused)
