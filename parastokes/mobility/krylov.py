"""The iterative solver: GMRES (scipy.sparse.linalg) on the matrix-free operator, right-
preconditioned by each body's own factorized self block, swept over the bodies with the
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

import numpy as np
from scipy.sparse.linalg import LinearOperator, gmres

from .errors import OVERFLOW, SolveError, SolveInfo
from .precondition import BlockSweep, block_factors
from .rigid_modes import RigidModeSweep, use_rigid_modes
from .scaling import Scaling, relative_residual
from .system import SurfaceSet

#: Krylov vectors kept between restarts, and the most GMRES iterations in all.
RESTART = 100
MAX_ITERATIONS = 500


def _run(op: LinearOperator, b: np.ndarray, tol: float) -> tuple[np.ndarray, int, int]:
    count = [0]

    def tick(_residual: float) -> None:
        count[0] += 1

    z, code = gmres(
        op,
        b,
        rtol=tol,
        atol=0.0,
        restart=RESTART,
        maxiter=MAX_ITERATIONS // RESTART,
        callback=tick,
        callback_type="pr_norm",
    )
    return z, code, count[0]


def _fail(code: int, iterations: int, residual: float, tol: float) -> SolveError:
    if not np.isfinite(residual):
        return SolveError(f"GMRES gave a non-finite result (relative residual {residual:.3g}): "
                          f"{OVERFLOW}")
    return SolveError(
        f"GMRES did not reach the relative residual {tol:g}: {residual:.3g} after {iterations} "
        f"iterations (scipy code {code}); try method='dense' for this size, "
        f"precondition='wall' near a wall, move the bodies apart, or loosen tol"
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
        a = LinearOperator((n3, n3), matvec=lambda z: op.matvec(pre.forces(z)), dtype=np.float64)
        z, code, its = _run(a, g, tol)
        f = pre.forces(z)
        residual = float(np.linalg.norm(op.matvec(f) - g) / np.linalg.norm(g))
        if code != 0 or not residual <= 10 * tol:
            raise _fail(code, its, residual, tol)
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
    size = n3 + 6 * nb
    if not np.any(b_vec):
        return np.zeros(n3), np.zeros((nb, 6)), SolveInfo("gmres", 0, 0.0)
    a = LinearOperator((size, size), matvec=lambda z: apply_a(prec(z)), dtype=np.float64)
    z, code, its = _run(a, b_vec, tol)
    f, y = split(prec(z))
    r_v = op.matvec(f) - sset.apply_motion(y) - g
    residual = relative_residual(r_v, sset.reduce(f) - ft, g, ft, sc)
    if code != 0 or not residual <= 10 * tol:
        raise _fail(code, its, residual, tol)
    return f, y, SolveInfo("gmres", its, residual)
