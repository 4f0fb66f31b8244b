"""Factorized Stokeslet matrices of one set of points: the solves M⁻¹ b, M⁻¹ K and the 6B x 6B
resistance Kᵀ M⁻¹ K that the direct solver and the block preconditioner use.

- :class:`LabFactor`: LU of M assembled in the lab (any points, free space or wall).
- :class:`BodyFrameFactor`: LU of a rigid surface's free-space M in its own frame, made once per
  viscosity and kept by the surface; :class:`RotatedFactor` applies it at a placement using
  M(c + R p) = blockdiag(R) M(p) blockdiag(R)ᵀ (the free-space Stokeslet is invariant under
  translation and rotates as a tensor), so M⁻¹ b = blockdiag(R) M(p)⁻¹ blockdiag(R)ᵀ b.
- :class:`RotatedBatch`: the solves of many placements of one body-frame factorization at once
  (the copies of a suspension): one LU solve with a right-hand side per body, the rotations
  batched, instead of a Python call per body.
"""

from __future__ import annotations

import threading
import warnings

import numpy as np
import scipy.linalg as sla

from ..mrs.operator import StokesletOperator
from .errors import SolveError
from .rigid import PlacedSurface, RigidSurface, rigid_motion
from .threads import LAPACK

#: Smallest reciprocal condition number (1-norm estimate, LAPACK gecon) accepted for M.
MIN_RCOND = 1e-12
#: Right-hand sides remembered by :meth:`BodyFrameFactor.solve_cached`.
CACHED_SOLVES = 4


def lu_checked(matrix: np.ndarray, what: str) -> tuple:
    """``scipy.linalg.lu_factor`` of ``matrix``; :class:`SolveError` when it is singular or its
    estimated reciprocal condition number is below :data:`MIN_RCOND`."""
    anorm = float(np.max(np.sum(np.abs(matrix), axis=0)))
    with warnings.catch_warnings(), LAPACK:
        warnings.simplefilter("ignore", sla.LinAlgWarning)
        lu = sla.lu_factor(matrix, check_finite=False)
        rcond, _ = sla.lapack.dgecon(lu[0], anorm, norm="1")
    if not rcond >= MIN_RCOND:
        raise SolveError(
            f"{what}: the regularized Stokeslet matrix is singular or ill-conditioned "
            f"(reciprocal condition number {rcond:.2g} < {MIN_RCOND:g}): ε is too large for the "
            f"point spacing or points nearly coincide; use ε about half the spacing"
        )
    return lu


def block_rotate(rotation: np.ndarray, v: np.ndarray) -> np.ndarray:
    """blockdiag(R) v for v (3N,) or (3N, k): each point's 3-vector turned by R."""
    n = v.shape[0] // 3
    return np.einsum("ab,nb...->na...", rotation, v.reshape(n, 3, *v.shape[1:])).reshape(v.shape)


class LabFactor:
    """LU of the Stokeslet matrix M of ``points`` (free or ``wall``), with the motion matrix
    ``motion`` K (3N, 6B): ``solve``, ``minv_k`` = M⁻¹ K and ``resistance`` = Kᵀ M⁻¹ K."""

    def __init__(
        self,
        points: np.ndarray,
        epsilon: np.ndarray,
        mu: float,
        wall: bool,
        motion: np.ndarray,
        what: str,
    ) -> None:
        self.matrix = StokesletOperator(None, points, epsilon, mu, wall=wall).dense()
        self._lu = lu_checked(self.matrix, what)
        self.motion = motion
        self.minv_k = self.solve(motion)
        self.resistance = motion.T @ self.minv_k

    def solve(self, b: np.ndarray) -> np.ndarray:
        with LAPACK:
            return sla.lu_solve(self._lu, b, check_finite=False)

    def apply_minv_k(self, y: np.ndarray) -> np.ndarray:
        return self.minv_k @ y


class BodyFrameFactor:
    """A rigid surface's free-space M in its own frame, factorized once (viscosity ``mu``).

    ``residual``: the relative residual ||M M⁻¹K - K|| / ||K|| of the factorization's own solve
    of the six rigid motions, measured once here (what a reused solve reports).
    """

    def __init__(self, surface: RigidSurface, mu: float) -> None:
        k0 = rigid_motion(surface.points, np.zeros(3))
        self.lab = LabFactor(surface.points, surface.epsilon, mu, False, k0, surface.name)
        self.residual = float(
            np.linalg.norm(self.lab.matrix @ self.lab.minv_k - k0) / np.linalg.norm(k0)
        )
        self.lab.matrix = np.empty((0, 0))  # only the LU is kept: half the memory
        self._recent: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._lock = threading.Lock()

    def solve_cached(self, b_body: np.ndarray) -> np.ndarray:
        """M0⁻¹ b_body, remembered for the last :data:`CACHED_SOLVES` right-hand sides (a slip
        fixed in the body frame, as a squirmer's, is solved once; hits are checked bit for bit)."""
        key = hash(b_body.tobytes())
        with self._lock:
            hit = self._recent.get(key)
        if hit is not None and np.array_equal(hit[0], b_body):
            return hit[1]
        x = self.lab.solve(b_body)
        with self._lock:  # (threads of hosted solves share the factorization)
            if len(self._recent) >= CACHED_SOLVES:
                self._recent.pop(next(iter(self._recent)))
            self._recent[key] = (b_body.copy(), x)
        return x


class RotatedFactor:
    """A :class:`BodyFrameFactor` applied at a placement (free space): the same interface as
    :class:`LabFactor` in the lab frame, nothing refactorized and nothing of size N x N formed.
    As K = blockdiag(R) K0 diag(Rᵀ, Rᵀ), M⁻¹K in the lab is blockdiag(R) (M0⁻¹ K0) diag(Rᵀ, Rᵀ),
    applied to a vector in :meth:`apply_minv_k`."""

    def __init__(self, placed: PlacedSurface, mu: float) -> None:
        self.base = placed.surface.self_factor(mu)
        r = placed.rotation
        self.rotation = r
        self.r6 = np.zeros((6, 6))
        self.r6[:3, :3] = self.r6[3:, 3:] = r
        self.motion = placed.motion()
        self.resistance = self.r6 @ self.base.lab.resistance @ self.r6.T

    @property
    def minv_k(self) -> np.ndarray:
        """M⁻¹K (3N, 6B) in the lab."""
        return block_rotate(self.rotation, self.base.lab.minv_k) @ self.r6.T

    def apply_minv_k(self, y: np.ndarray) -> np.ndarray:
        return block_rotate(self.rotation, self.base.lab.minv_k @ (self.r6.T @ y))

    def solve_body(self, b_body: np.ndarray) -> np.ndarray:
        """M⁻¹ b in the lab for b given in the body frame (b = blockdiag(R) b_body), through
        the body frame factorization's cache of recent right-hand sides."""
        return block_rotate(self.rotation, self.base.solve_cached(b_body))

    def solve(self, b: np.ndarray) -> np.ndarray:
        r = self.rotation
        return block_rotate(r, self.base.lab.solve(block_rotate(r.T, b)))


def saddle_solve(
    factor, motion: np.ndarray, g: np.ndarray, ft: np.ndarray, minv_g: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Solve M f = K Y + g, Kᵀ f = ft for (f, Y) with a factorized M (Schur complement on the
    6B rigid unknowns): Y = (Kᵀ M⁻¹ K)⁻¹ (ft - Kᵀ M⁻¹ g), f = M⁻¹ K Y + M⁻¹ g. ``minv_g``:
    M⁻¹ g when the caller has it."""
    if minv_g is None:
        minv_g = factor.solve(g) if np.any(g) else np.zeros_like(g)
    y = np.linalg.solve(factor.resistance, ft - motion.T @ minv_g)
    return factor.apply_minv_k(y) + minv_g, y


class RotatedBatch:
    """The solves of :class:`RotatedFactor` s of one :class:`BodyFrameFactor` (the same surface
    at several placements), for all of them at once: each body's residual turned into its frame
    (blockdiag(Rᵀ)), one LU solve with a column per body, and back. :meth:`saddle` is
    :func:`saddle_solve` of every body: with K = blockdiag(R) K0 diag(Rᵀ, Rᵀ) (K0, M0⁻¹K0 =
    Z0 and the resistance R0 = K0ᵀ Z0 of the body frame),

        c = R0⁻¹ (diag(Rᵀ, Rᵀ) ft - K0ᵀ m),  m = M0⁻¹ blockdiag(Rᵀ) g,
        Y = diag(R, R) c,  f = blockdiag(R) (Z0 c + m)."""

    def __init__(self, factors: list[RotatedFactor]) -> None:
        base = factors[0].base
        if any(f.base is not base for f in factors):
            raise ValueError("RotatedBatch: the factors must share one body-frame factorization")
        self.lab = base.lab
        self.rotation = np.array([f.rotation for f in factors])  # (m, 3, 3)
        self.r6 = np.array([f.r6 for f in factors])  # (m, 6, 6)

    def _body(self, g: np.ndarray) -> np.ndarray:
        """M0⁻¹ blockdiag(Rᵀ) g for every body, columns (3n, m) of g (m, 3n)."""
        m = len(g)
        turned = np.einsum("kba,knb->kna", self.rotation, g.reshape(m, -1, 3))
        return self.lab.solve(turned.reshape(m, -1).T)

    def _lab(self, body: np.ndarray) -> np.ndarray:
        """blockdiag(R) of every body's column of ``body`` (3n, m), as rows (m, 3n)."""
        m = body.shape[1]
        return np.einsum("kab,knb->kna", self.rotation, body.T.reshape(m, -1, 3)).reshape(m, -1)

    def solve(self, g: np.ndarray) -> np.ndarray:
        """M⁻¹ g of every body (rows of ``g``, (m, 3n))."""
        return self._lab(self._body(g))

    def saddle(self, g: np.ndarray, ft: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Forces (m, 3n) and motions Y (m, 6) of M f = K Y + g, Kᵀ f = ft for every body."""
        m = self._body(g)
        rhs = np.einsum("kba,kb->ka", self.r6, ft) - (self.lab.motion.T @ m).T
        c = np.linalg.solve(self.lab.resistance, rhs.T)  # (6, m)
        return self._lab(self.lab.minv_k @ c + m), np.einsum("kab,bk->ka", self.r6, c)
