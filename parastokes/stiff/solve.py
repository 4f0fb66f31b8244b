"""The stage solves of the linearly implicit schemes: ``(I - h γ A) k = r`` over the rates.

- :class:`StageSolver` with ``krylov=False``: ``A`` is the approximate Jacobian of
  :mod:`.jacobian`, factorized once (:class:`Factorization`: LAPACK's banded LU, eliminated in
  :data:`BAND_PRECISION` and solved in double by :func:`band_solve`, when ``A`` is banded in
  the body's own point order, as a rod's is, else scipy's SuperLU; O(points) entries)
  and reused for every stage and every step that keeps the same ``A`` and a step within a
  factor of the factorized one (:mod:`.stepper`). No dense (3N)² matrix is ever formed.
- ``krylov=True``: the exact Jacobian of the rates, applied matrix-free by a forward difference
  of the rates (one evaluation of the compiled kernels per product), solved by GMRES to a
  relative residual of :data:`GMRES_RTOL` (:data:`GMRES_RTOL_ORDER3` for a third-order
  scheme; checked again after it within
  :data:`GMRES_ACCEPT`), preconditioned by the LU of the approximate ``A``.

A factorization of a singular matrix or a GMRES that does not converge is a
:class:`StiffSolveError` naming the time, the residual and the iterations; the integrator
reports it as a blow-up (``integrate.BlowUpError``, exit 3 of a run) with advice.
"""

from __future__ import annotations

import threading
import weakref
from collections.abc import Callable
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numba import njit
from scipy.linalg import lapack

from ..mobility.threads import LAPACK, blas_threads
from .banded import band_storage, bandwidth, narrow

__all__ = ["BAND_PRECISION", "GBTRF_BLOCK", "GMRES_ACCEPT", "GMRES_MAXITER", "GMRES_RTOL",
           "GMRES_RTOL_ORDER3", "SPARES", "Factorization", "Spares", "StageSolver",
           "StiffSolveError", "band_solve", "elimination_width"]

#: Relative residual of the GMRES stage solves, as scipy's GMRES measures it (W-methods keep
#: their order with an inexact Jacobian, so the stage systems need not be solved to round-off).
GMRES_RTOL = 1e-5
#: The same for a scheme of order 3 (``ros34pw2-krylov``): at 1e-5 the solves' errors showed as
#: a fitted order of 2.7 on a rod at small steps (``parastokes.testing.check_system``), at 1e-6
#: 1.8 on another; at 1e-7 3 (1.6x the CPU at 2.5e-4 s on the rod of 601 points, two runs).
GMRES_RTOL_ORDER3 = 1e-7
#: The largest relative residual of a stage solve recomputed after GMRES (the finite-difference
#: products carry noise of about 1e-8 relative, amplified by h γ times the Jacobian's norm):
#: above it the solve failed.
GMRES_ACCEPT = 1e-3
#: The most GMRES iterations of one stage solve.
GMRES_MAXITER = 60


@njit(cache=True, error_model="numpy")
def band_solve(lu, kl, ku, piv, b):  # pragma: no cover - compiled
    """``x`` with ``P L U x = b`` from the factors of dgbtrf or sgbtrf (``lu``, ``piv`` as scipy
    returns them: 0-based), in double whatever the factors' precision: LAPACK's dgbtrs
    (L with its row interchanges, then U of bandwidth kl + ku), reading single-precision
    factors as they are (half dgbtrs's memory, no conversion) and exact for them to double's
    round-off, so the solves are linear in ``b``. The inner loops run over unsigned indices:
    numba then drops its check for negative (wrapped-around) indices, and they vectorize
    without a slice's set-up per column (the same operations in the same order as before,
    the same bits, in half the time: docs/benchmarks.md, "Round 5, third session")."""
    n = lu.shape[1]
    kv = kl + ku  # the diagonal's row
    diagonal = np.uint64(kv)
    x = b.copy()
    for j in range(n - 1):
        pivot = piv[j]
        if pivot != j:
            x[pivot], x[j] = x[j], x[pivot]
        xj = x[j]
        if xj != 0.0:  # the multipliers: rows kv + 1.. of column j
            column = np.uint64(j)
            for i in range(np.uint64(1), np.uint64(min(kl, n - j - 1) + 1)):
                x[column + i] -= np.float64(lu[diagonal + i, column]) * xj
    for j in range(n - 1, -1, -1):
        if x[j] != 0.0:
            x[j] /= np.float64(lu[kv, j])
            xj = x[j]
            column, first = np.uint64(j), np.uint64(max(0, j - kv))
            row = diagonal + first - column  # U's entry (first, j)
            for i in range(np.uint64(0), column - first):
                x[first + i] -= np.float64(lu[row + i, column]) * xj
    return x


class StiffSolveError(RuntimeError):
    """A stage solve failed: ``t`` (time of the step), ``residual`` (relative, ``nan`` when the
    matrix could not be factorized), ``iterations``; ``reason`` says what failed and what to
    change."""

    def __init__(self, t: float, residual: float, iterations: int, reason: str) -> None:
        super().__init__(f"linear solve failed at t={t:.10g}: {reason} (relative residual "
                         f"{residual:.3g} after {iterations} iterations)")
        self.t = t
        self.residual = residual
        self.iterations = iterations
        self.reason = reason

    def __reduce__(self) -> tuple:
        return type(self), (self.t, self.residual, self.iterations, self.reason)


def _ordering(matrix: sp.sparray) -> str:
    """SuperLU's column ordering: the natural one for a banded matrix (a rod's or chain's points
    in order along it: no fill outside the band, measured 2x faster to factorize), else COLAMD."""
    return "NATURAL" if narrow(*bandwidth(matrix), matrix.shape[0]) else "COLAMD"


#: The precision of the banded LU's elimination (dgbtrf or sgbtrf). Single: the factors of
#: ``I - hγ A'`` with A' = A + O(2^-24 ‖I - hγA‖ / hγ) (single precision's backward error),
#: solved in double (:func:`band_solve`), exact for A' to double's round-off: a W-method on A'
#: (any A keeps its order), bit-reproducible, at half the factorization's CPU
#: (docs/benchmarks.md, "Stiff bodies: cheaper implicit steps").
BAND_PRECISION = np.float32
_GBTRF = {"f": lapack.sgbtrf, "d": lapack.dgbtrf}
#: The block of LAPACK's banded elimination (ILAENV's NB for xGBTRF).
GBTRF_BLOCK = 32


def elimination_width(kl: int) -> int:
    """The lower bandwidth to eliminate a band of lower bandwidth ``kl`` with: the next multiple
    of :data:`GBTRF_BLOCK` when it adds at most 4 zero diagonals, else ``kl``. The zero
    diagonals change neither the factors' values nor the pivots, but sgbtrf's time does not
    follow its work: on the paper's rod (kl = ku = 95) it took 1.12-1.15 ms with kl = 95 and
    0.85-0.90 with 96 (0.98 with 101; one process, docs/benchmarks.md "Round 5, fourth
    session")."""
    up = -(-kl // GBTRF_BLOCK) * GBTRF_BLOCK
    return up if up - kl <= 4 else kl


class Spares:
    """Work arrays freed by their owners, kept for the next of the same shape and dtype (the
    latest ``keep`` in all; thread-safe). A fresh multi-megabyte array costs its page faults on
    first touch: 0.7 ms for the 2.2 MB of the banded LU of the paper's rod, ten times filling a
    reused one (docs/benchmarks.md, "Stiff bodies: cheaper implicit steps")."""

    def __init__(self, keep: int = 4) -> None:
        self._lock = threading.Lock()
        self._free: list[np.ndarray] = []
        self.keep = keep

    def take(self, shape: tuple[int, int], dtype: type) -> np.ndarray:
        """A kept array of ``shape`` and ``dtype`` (contents unset), else a new one; Fortran
        order."""
        with self._lock:
            for i, array in enumerate(self._free):
                if array.shape == shape and array.dtype == dtype:
                    return self._free.pop(i)
        return np.empty(shape, dtype=dtype, order="F")

    def give(self, array: np.ndarray) -> None:
        """Keep ``array`` (no longer used by anyone) for a later :meth:`take`, forgetting the
        oldest kept beyond ``keep``."""
        with self._lock:
            self._free.append(array)
            del self._free[:-self.keep]


#: The banded factorizations' arrays: a Factorization gives its factors back when it is freed
#: (the stepper drops the old one before it factorizes anew).
SPARES = Spares()


class Factorization:
    """The LU factorization of ``I - hγ A`` (``A`` sparse, square, nonzero): LAPACK's banded
    LU in :data:`BAND_PRECISION` (on one BLAS thread,
    :func:`parastokes.mobility.threads.blas_threads`; the lower bandwidth of
    :func:`elimination_width`) when ``A``'s band is below an eighth of its size (a rod's or
    chain's points in order), else SuperLU; a
    singular matrix is a :class:`StiffSolveError` at time ``t``. ``solve(v)`` solves with it
    (``v`` flat)."""

    def __init__(self, matrix: sp.sparray, hgamma: float, t: float) -> None:
        self.hgamma = hgamma
        n = matrix.shape[0]
        kl, ku = bandwidth(matrix)
        self._band: tuple[np.ndarray, np.ndarray, int, int] | None = None
        self._superlu: Any = None
        if narrow(kl, ku, n):
            kl = elimination_width(kl)
            ab = band_storage(matrix, hgamma, kl, ku, BAND_PRECISION,
                              out=SPARES.take((2 * kl + ku + 1, n), BAND_PRECISION))
            with LAPACK, blas_threads(1):
                lu, piv, info = _GBTRF[ab.dtype.char](ab, kl, ku, overwrite_ab=1)
            weakref.finalize(self, SPARES.give, lu)  # the factors' memory, for the next one
            singular = info > 0 or not np.isfinite(lu[kl + ku]).all()
            self._band = (lu, piv, kl, ku)
            reason = f"U[{info - 1}, {info - 1}] = 0"
        else:
            system = sp.eye_array(n, format="csc") - hgamma * sp.csc_array(matrix)
            try:
                self._superlu = spla.splu(system, permc_spec=_ordering(matrix))
                singular = False
            except RuntimeError as error:  # "Factor is exactly singular"
                singular, reason = True, str(error)
        if singular:
            raise StiffSolveError(t, float("nan"), 0, f"I - h*gamma*A is singular ({reason}); "
                                  "use a smaller step")

    @property
    def banded(self) -> bool:
        """Whether LAPACK's banded LU holds the factors (else SuperLU)."""
        return self._band is not None

    def solve(self, v: np.ndarray) -> np.ndarray:
        """``(I - hγ A)⁻¹ v``."""
        if self._band is None:
            return self._superlu.solve(v)
        lu, piv, kl, ku = self._band
        return band_solve(lu, kl, ku, piv, np.asarray(v, dtype=float))


class StageSolver:
    """Solves ``(I - hγ A) k = r`` at one step (see the module docstring).

    ``lu``: the :class:`Factorization` of ``I - h'γ A`` (None: ``A = 0``), where ``h'`` may
    differ from this step's ``h`` (a W-method's ``A`` is any matrix: the factorization is that
    of ``I - hγ (h'/h) A``); with ``krylov``, ``rates_at(y)`` gives the rates at the step's
    time at a state ``y`` near ``x`` and ``advance`` moves ``x`` along a rate perturbation, for
    the products of the exact Jacobian with ``f0 = rates_at(x)``, and ``lu`` preconditions.
    """

    def __init__(self, lu: Factorization | None, hgamma: float, t: float, *,
                 krylov: bool = False,
                 rates_at: Callable[[np.ndarray], np.ndarray] | None = None,
                 advance: Callable[[np.ndarray, np.ndarray, float], np.ndarray] | None = None,
                 x: np.ndarray | None = None, f0: np.ndarray | None = None,
                 rtol: float = GMRES_RTOL) -> None:
        self.hgamma = hgamma
        self.rtol = rtol
        self.t = t
        self.lu = lu
        self.iterations = 0
        self.krylov = krylov
        self.rates_at, self.advance, self.x, self.f0 = rates_at, advance, x, f0

    def _precondition(self, v: np.ndarray) -> np.ndarray:
        return v if self.lu is None else self.lu.solve(v)

    def solve(self, r: np.ndarray) -> np.ndarray:
        """``k`` of the shape of ``r``."""
        b = np.ascontiguousarray(r, dtype=float).ravel()
        if not self.krylov:
            return self._precondition(b).reshape(r.shape)
        return self._gmres(b).reshape(r.shape)

    def _jacobian_product(self, v: np.ndarray) -> np.ndarray:
        assert self.rates_at is not None and self.advance is not None
        assert self.x is not None and self.f0 is not None
        norm = float(np.linalg.norm(v))
        if norm == 0.0:
            return np.zeros_like(v)
        sigma = 1e-7 * max(1.0, float(np.abs(self.x[:, :3]).max())) / norm
        shifted = self.advance(self.x, (sigma * v).reshape(self.f0.shape), 1.0)
        return (self.rates_at(shifted) - self.f0).ravel() / sigma

    def _gmres(self, b: np.ndarray) -> np.ndarray:
        n = b.size
        operator = spla.LinearOperator(
            (n, n), matvec=lambda v: v - self.hgamma * self._jacobian_product(v), dtype=float)
        preconditioner = spla.LinearOperator((n, n), matvec=self._precondition, dtype=float)
        count = [0]

        def counted(_: object) -> None:
            count[0] += 1

        scale = float(np.linalg.norm(b))
        if scale == 0.0:
            return np.zeros_like(b)
        k, info = spla.gmres(operator, b, x0=self._precondition(b), rtol=self.rtol,
                             atol=0.0, restart=GMRES_MAXITER, maxiter=1, M=preconditioner,
                             callback=counted, callback_type="pr_norm")
        self.iterations += count[0]
        residual = float(np.linalg.norm(operator.matvec(k) - b)) / scale
        if info < 0 or not np.isfinite(residual) or residual > GMRES_ACCEPT:
            raise StiffSolveError(self.t, residual, count[0],
                                  "GMRES did not converge; use a smaller step, or the scheme "
                                  "ros2 (approximate Jacobian, direct solve)")
        return k
