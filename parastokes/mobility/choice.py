"""Which solver a call uses: ``method="auto"`` picks the direct solver where it is cheap or
reusable and GMRES otherwise (the crossover measured in docs/benchmarks.md, "Rigid bodies"); and
the check of every solve's result (:func:`checked`): finite, with its residual within tolerance,
else a :class:`SolveError` (a run's blow-up), never a result taken as it is."""

from __future__ import annotations

import numpy as np

from .direct import direct_solve
from .errors import OVERFLOW, SolveError, SolveInfo
from .krylov import gmres_solve
from .system import SurfaceSet
from .threads import blas_threads

#: Most surface points (all bodies) solved by a fresh dense factorization under "auto"; a single
#: body in free space always uses its reused body-frame factorization. Measured (benchmarks/
#: mobility.py): with the wall, GMRES with the reused free-space blocks beats a fresh assembly and
#: LU from 400 points on (0.1-0.5 s against 0.8 s), and two bodies of 400 (0.4 s against 2.2 s).
DENSE_MAX_POINTS = 200

METHODS = ("auto", "dense", "gmres")
#: Largest relative residual accepted from a direct solve: LU is backward stable, and M's
#: conditioning is bounded (:data:`.selfsolve.MIN_RCOND`), so a larger one is a breakdown (a
#: right-hand side that overflows, a matrix of NaN).
DENSE_RESIDUAL = 1e-6


def chosen_method(sset: SurfaceSet, method: str) -> str:
    """``"dense"`` or ``"gmres"`` for ``method`` (one of :data:`METHODS`)."""
    if method not in METHODS:
        raise ValueError(f"method: must be one of {METHODS}, got {method!r}")
    if method != "auto":
        return method
    if sset.n_bodies == 1 and not sset.wall:
        return "dense"
    return "dense" if sset.n_points <= DENSE_MAX_POINTS else "gmres"


def solve(
    sset: SurfaceSet,
    g: np.ndarray,
    ft: np.ndarray | None,
    method: str,
    tol: float,
    precondition: str,
    y_known: np.ndarray | None = None,
    g_body: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, SolveInfo]:
    """Dispatch to the direct or the GMRES solver (arguments of
    :func:`parastokes.mobility.direct.direct_solve`), BLAS on at most the fluid's threads
    (:func:`.threads.blas_threads`)."""
    if not (np.isfinite(tol) and 0 < tol < 1):
        raise ValueError(f"tol: must lie in (0, 1), got {tol!r}")
    # (overflow in a result is reported by checked(), not as numpy's warnings)
    with blas_threads(sset.n_threads), np.errstate(over="ignore", invalid="ignore"):
        if chosen_method(sset, method) == "dense":
            return checked(sset, *direct_solve(sset, g, ft, y_known, g_body), DENSE_RESIDUAL)
        if ft is None:
            assert y_known is not None
            f, _, info = gmres_solve(sset, g + sset.apply_motion(y_known), None, tol, precondition)
            return checked(sset, f, y_known, info, 10 * tol)
        f, y, info = gmres_solve(sset, g, ft, tol, precondition)
        assert y is not None
        return checked(sset, f, y, info, 10 * tol)


def checked(sset: SurfaceSet, f: np.ndarray, y: np.ndarray, info: SolveInfo,
            limit: float) -> tuple[np.ndarray, np.ndarray, SolveInfo]:
    """``(f, y, info)`` when the forces ``f`` and motions ``y`` are finite and the residual is at
    most ``limit``; otherwise a :class:`SolveError` naming the bodies, the residual and the likely
    cause (loads, slip or background too large for floating point; a system the solver cannot
    resolve)."""
    finite = bool(np.isfinite(f).all() and np.isfinite(y).all())
    if finite and info.residual <= limit:
        return f, y, info
    names = ", ".join(p.name for p in sset.placed)
    if not (finite and np.isfinite(info.residual)):
        cause = f"{'non-finite forces or motions' if not finite else 'a non-finite residual'}: " \
                f"{OVERFLOW}"
    else:
        cause = ("the system is beyond what the solver resolves (bodies too close to each other "
                 "or to the wall for their ε)")
    raise SolveError(f"the {info.method} solve of {names} failed (relative residual "
                     f"{info.residual:.3g}, limit {limit:.3g}): {cause}")
