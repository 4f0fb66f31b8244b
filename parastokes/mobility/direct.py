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


def _minv_g(
    factor: LabFactor | RotatedFactor, g: np.ndarray, g_body: np.ndarray | None
) -> np.ndarray:
    """M⁻¹ g: zero for g = 0; through the body frame's cache when ``g_body`` (g in the body
    frame) is given and the factorization is the reused one."""
    if not np.any(g):
        return np.zeros_like(g)
    if g_body is not None and isinstance(factor, RotatedFactor):
        return factor.solve_body(g_body)
    return factor.solve(g)


def direct_solve(
    sset: SurfaceSet,
    g: np.ndarray,
    ft: np.ndarray | None,
    y_known: np.ndarray | None = None,
    g_body: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, SolveInfo]:
    """M f = K Y + g with either the loads ``ft`` (B, 6) given and Kᵀ f = ft (mobility) or
    the motions ``y_known`` (B, 6) given (resistance). Returns (f (3N,), Y (B, 6), info).
    ``g_body``: g in the body frame (a single body), for the reused factorization's cache.

    The residual is computed with the assembled matrix; a reused body-frame factorization reports
    the residual of its own check (:class:`parastokes.mobility.selfsolve.BodyFrameFactor`).
    """
    factor, reused = factor_for(sset)
    minv_g = _minv_g(factor, g, g_body)
    if ft is None:
        assert y_known is not None
        y = y_known
        f = factor.apply_minv_k(y.ravel()) + minv_g
        r_ft = ft_ref = np.zeros((sset.n_bodies, 6))
    else:
        f, yflat = saddle_solve(factor, factor.motion, g, ft.ravel(), minv_g)
        y = yflat.reshape(-1, 6)
        r_ft, ft_ref = sset.reduce(f) - ft, ft
    if isinstance(factor, RotatedFactor):
        residual = factor.base.residual
    else:
        ky = sset.apply_motion(y)
        r_v = factor.matrix @ f - g - ky
        rhs = g + ky if ft is None else g
        residual = relative_residual(r_v, r_ft, rhs, ft_ref, Scaling(sset.mu, sset.length))
    return f, y, SolveInfo("dense", 0, residual, reused)
