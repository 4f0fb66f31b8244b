"""The iterative solver: GMRES (:mod:`parastokes.mobility.gmres`) on the matrix-free operator,
right-preconditioned by each body's own factorized self block, swept over the bodies with the
couplings of near bodies (:mod:`parastokes.mobility.precondition`); in the resistance problem
(motions given) of several bodies behind a coarse correction on their rigid modes
(:mod:`parastokes.mobility.rigid_modes`).

Right preconditioning (A P⁻¹ z = b, x = P⁻¹ z) keeps GMRES's residual the true residual of
A x = b, in the dimensionless form of :mod:`parastokes.mobility.scaling`. The block of body b is
its exact single-body solve (the saddle system of its own M_bb and K_b): with ``precondition=
"free"`` the reused free-space body-frame factorization, with ``"wall"`` its self block
assembled with the wall images and factorized at every solve.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .errors import OVERFLOW, SolveError, SolveInfo
from .gmres import gmres
from .precondition import BlockSweep, block_factors
from .rigid_modes import RigidModeSweep, use_rigid_modes
from .scaling import Scaling
from .system import SurfaceSet

#: Krylov vectors kept between restarts, and the most GMRES iterations in all.
RESTART = 100
MAX_ITERATIONS = 500


def _run(apply: Callable[[np.ndarray], np.ndarray], b: np.ndarray, tol: float,
         forces: Callable[[np.ndarray], np.ndarray],
         residual: Callable[[np.ndarray], np.ndarray]) -> tuple[np.ndarray, int, float]:
    """GMRES on ``apply`` (A P⁻¹) from 0; x = ``forces(z)``. Returns x, the GMRES iterations
    and the relative residual: GMRES's own (Arnoldi) residual when it reached ``tol``, which
    right preconditioning makes the residual of A x = b (to round-off, far below ``tol``), so
    no product of the operator is spent on checking it; when it did not, the true one
    (``residual(x)``, one product) for the error."""
    norm = float(np.linalg.norm(b))
    result = gmres(apply, b, tol, restart=RESTART, max_iterations=MAX_ITERATIONS)
    x = forces(result.x)
    if result.estimate <= tol * norm:
        return x, result.iterations, result.estimate / norm
    return x, result.iterations, float(np.linalg.norm(residual(x))) / norm


def _fail(iterations: int, residual: float, tol: float) -> SolveError:
    if not np.isfinite(residual):
        return SolveError(f"GMRES gave a non-finite result (relative residual {residual:.3g}): "
                          f"{OVERFLOW}")
    return SolveError(
        f"GMRES did not reach the relative residual {tol:g}: {residual:.3g} after {iterations} "
        f"iterations; try method='dense' for this size, precondition='wall' near "
        f"a wall, move the bodies apart, or loosen tol"
    )


def gmres_solve(
    sset: SurfaceSet, g: np.ndarray, ft: np.ndarray | None, tol: float, precondition: str = "free"
) -> tuple[np.ndarray, np.ndarray | None, SolveInfo]:
    """As :func:`parastokes.mobility.direct.direct_solve`, by preconditioned GMRES."""
    op = sset.operator()
    factors = block_factors(sset, precondition)
    sweep = BlockSweep(sset, factors)
    nb, n3 = sset.n_bodies, 3 * sset.n_points
    sc = Scaling(sset.mu, sset.length)
    if ft is None:
        if not np.any(g):
            return np.zeros(n3), None, SolveInfo("gmres", 0, 0.0)
        pre = RigidModeSweep(sset, factors, sweep) if use_rigid_modes(sset) else sweep
        f, its, residual = _run(lambda z: op.matvec(pre.forces(z)), g, tol, pre.forces,
                                lambda f: g - op.matvec(f))
        if not residual <= 10 * tol:
            raise _fail(its, residual, tol)
        return f, None, SolveInfo("gmres", its, residual)

    def split(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """x̃ -> (f, Y) unscaled."""
        return x[:n3] * sc.force, sc.y_unscaled(x[n3:].reshape(nb, 6))

    def join(f: np.ndarray, y: np.ndarray) -> np.ndarray:
        return np.concatenate([f / sc.force, sc.y_scaled(y).ravel()])

    def apply_a(x: np.ndarray) -> np.ndarray:
        """Ã x̃: rows (M f - K Y; -Kᵀ f scaled)."""
        f, y = split(x)
        return np.concatenate(
            [op.matvec(f) - sset.apply_motion(y), -sc.ft_scaled(sset.reduce(f)).ravel()]
        )

    def prec(z: np.ndarray) -> np.ndarray:
        """P⁻¹ z̃: the sweep of each body's own saddle solve over the scaled residual."""
        return join(*sweep.saddle(z[:n3], -sc.ft_unscaled(z[n3:].reshape(nb, 6))))

    b_vec = np.concatenate([g, -sc.ft_scaled(ft).ravel()])
    if not np.any(b_vec):
        return np.zeros(n3), np.zeros((nb, 6)), SolveInfo("gmres", 0, 0.0)
    x, its, residual = _run(lambda z: apply_a(prec(z)), b_vec, tol, prec,
                            lambda x: b_vec - apply_a(x))
    if not residual <= 10 * tol:
        raise _fail(its, residual, tol)
    f, y = split(x)
    return f, y, SolveInfo("gmres", its, residual)
