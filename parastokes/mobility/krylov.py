"""The iterative solver: GMRES (scipy.sparse.linalg) on the matrix-free operator, right-
preconditioned by each body's own factorized self block.

Right preconditioning (A P⁻¹ z = b, x = P⁻¹ z) keeps GMRES's residual the true residual of
A x = b, in the dimensionless form of :mod:`parastokes.mobility.scaling`. The block of body b is
its exact single-body solve (the saddle system of its own M_bb and K_b): with ``precondition=
"free"`` the reused free-space body-frame factorization (:class:`RotatedFactor`, nothing
refactorized), with ``"wall"`` its self block assembled with the wall images and factorized at
every solve (:class:`LabFactor`).
"""

from __future__ import annotations

import numpy as np
from scipy.sparse.linalg import LinearOperator, gmres

from .errors import SolveError, SolveInfo
from .scaling import Scaling, relative_residual
from .selfsolve import LabFactor, RotatedFactor, saddle_solve
from .system import SurfaceSet

#: Krylov vectors kept between restarts, and the most GMRES iterations in all.
RESTART = 100
MAX_ITERATIONS = 500


def block_factors(sset: SurfaceSet, precondition: str) -> list[LabFactor | RotatedFactor]:
    """Each body's self-block factorization (see the module docstring for ``precondition``)."""
    if precondition not in ("free", "wall"):
        raise ValueError(f"precondition: must be 'free' or 'wall', got {precondition!r}")
    out: list[LabFactor | RotatedFactor] = []
    for b, p in enumerate(sset.placed):
        if precondition == "wall" and sset.wall:
            out.append(LabFactor(p.points, p.epsilon, sset.mu, True, sset.motions[b], p.name))
        else:
            out.append(RotatedFactor(p, sset.mu))
    return out


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
    nb, n3 = sset.n_bodies, 3 * sset.n_points
    sc = Scaling(sset.mu, sset.length)
    rows = [sset.rows(b) for b in range(nb)]
    if ft is None:

        def prec_r(z: np.ndarray) -> np.ndarray:
            return np.concatenate([fa.solve(z[r]) for fa, r in zip(factors, rows, strict=True)])

        a = LinearOperator((n3, n3), matvec=lambda z: op.matvec(prec_r(z)), dtype=np.float64)
        if not np.any(g):
            return np.zeros(n3), None, SolveInfo("gmres", 0, 0.0)
        z, code, its = _run(a, g, tol)
        f = prec_r(z)
        residual = float(np.linalg.norm(op.matvec(f) - g) / np.linalg.norm(g))
        if code != 0 or residual > 10 * tol:
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
        """P⁻¹ z̃: each body's own saddle solve of its block of the residual."""
        rv, rft = z[:n3], -sc.ft_unscaled(z[n3:].reshape(nb, 6))
        f = np.empty(n3)
        y = np.empty((nb, 6))
        for b, (fa, r) in enumerate(zip(factors, rows, strict=True)):
            f[r], y[b] = saddle_solve(fa, fa.motion, rv[r], rft[b])
        return join(f, y)

    b_vec = np.concatenate([g, -sc.ft_scaled(ft).ravel()])
    size = n3 + 6 * nb
    if not np.any(b_vec):
        return np.zeros(n3), np.zeros((nb, 6)), SolveInfo("gmres", 0, 0.0)
    a = LinearOperator((size, size), matvec=lambda z: apply_a(prec(z)), dtype=np.float64)
    z, code, its = _run(a, b_vec, tol)
    f, y = split(prec(z))
    r_v = op.matvec(f) - sset.apply_motion(y) - g
    residual = relative_residual(r_v, sset.reduce(f) - ft, g, ft, sc)
    if code != 0 or residual > 10 * tol:
        raise _fail(code, its, residual, tol)
    return f, y, SolveInfo("gmres", its, residual)
