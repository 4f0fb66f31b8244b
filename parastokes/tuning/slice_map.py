"""The linearized slice map DG of x0 -> G(x0) on position perturbations, from finite differences.

DG is only available through products DG d = (G(x0 + h d) - G(x0)) / h, one call of the coarse
map per product, on the positions (columns 0-2 of every row of the state, docs/contracts.md);
there is no adjoint. Two quantities (docs/validation.md section 2, "Measured: the linearized
coarse map over one slice"; why the tuner tests the first: docs/tuning.md, step 7):

- the spectral radius ρ(DG), the growth per slice of a perturbation under repeated slices, by
  ARPACK's implicitly restarted Arnoldi iteration (:func:`radius`: largest modulus, a fixed
  start, a residual tolerance and a bound on the calls; a run that does not converge within the
  bound says so instead of returning a number);
- for small states, the whole Jacobian (:func:`dense`: 3M + 1 calls) and from it ρ and the norm
  ‖DG‖ (largest singular value, the worst one-slice amplification of one perturbation).

A few steps of power iteration, which this replaces, return neither for the coarse maps of the
paper: DG is far from normal (on Table 5 G¹ over the paper's slice ‖DG‖ = 50 with eigenvalues
within 1e-3 of 1), and the iterates read 1.19-1.39 depending on the start.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.sparse.linalg

__all__ = ["Diverged", "Probe", "Radius", "dense", "norms", "radius"]

#: Finite-difference step on the positions, relative to their largest coordinate: large enough
#: that the round-off of the combination's weighted sums (weights up to 1.7e5), which grows as
#: 1/step, is small, small enough for the truncation error (forward differences: about 3e-4 of
#: DG d on Table 5 G¹ along its top eigenvector). docs/validation.md section 2: on Table 5 G¹
#: over the paper's slice ρ read 1.92, 1.28, 1.053, 1.0009 at absolute steps 1e-7 .. 3e-5.
STEP = 1e-5
#: Defaults of :func:`radius` (the tuner's): Krylov space, relative residual tolerance, most calls
#: of G. On the rods' clustered eigenvalues near 1 (docs/tuning.md, step 7) ARPACK converged in
#: 22-49 calls at 1e-2 to ρ within 3e-2 (the non-normality multiplies the residual's error); a
#: Krylov space of 12 often needed 60-75, and 1e-3 or 1e-4 needed 100-200 for no better a value.
KRYLOV = 20
TOLERANCE = 1e-2
MAX_CALLS = 80


class Diverged(ArithmeticError):
    """A perturbed call of the map returned a non-finite state."""


class Probe:
    """DG d by finite differences of ``propagate`` (x0 -> G(x0), full state) on the positions
    ``positions(state)`` = ``state[:, :3]``; counts the calls of ``propagate`` (``calls``)."""

    def __init__(self, propagate: Callable[[np.ndarray], np.ndarray],
                 positions: Callable[[np.ndarray], np.ndarray], x0: np.ndarray,
                 step: float = STEP, central: bool = False) -> None:
        self.propagate, self.positions, self.central = propagate, positions, central
        self.x0 = np.array(x0, dtype=float)
        own = np.asarray(positions(self.x0), dtype=float)
        if self.x0.ndim != 2 or self.x0.shape[1] < 3 or not np.array_equal(own, self.x0[:, :3]):
            raise ValueError("slice map: the system's positions must be columns 0-2 of every row "
                             "of its state (docs/contracts.md); this state's are not")
        self.step = step * (float(np.abs(own).max()) or 1.0)
        self.size = own.size
        self.calls = 0
        self.base = None if central else self._positions_after(self.x0)

    def _positions_after(self, y: np.ndarray) -> np.ndarray:
        self.calls += 1
        out = np.asarray(self.positions(self.propagate(y)), dtype=float).ravel()
        if not np.all(np.isfinite(out)):
            raise Diverged("the slice map returned a non-finite state")
        return out

    def moved(self, d: np.ndarray) -> np.ndarray:
        """Positions of G(x0 + d) (d: the flat position perturbation)."""
        y = self.x0.copy()
        y[:, :3] += d.reshape(-1, 3)
        return self._positions_after(y)

    def __call__(self, d: np.ndarray) -> np.ndarray:
        d = self.step * np.real(np.asarray(d)).ravel()
        if self.central:
            return (self.moved(d) - self.moved(-d)) / (2 * self.step)
        assert self.base is not None  # (forward differences)
        return (self.moved(d) - self.base) / self.step

    def jacobian(self) -> np.ndarray:
        """The whole DG, column by column (``size`` products)."""
        return np.array([self(e) for e in np.eye(self.size)]).T


def norms(jac: np.ndarray) -> tuple[float, float]:
    """(ρ, ‖DG‖) of a whole Jacobian ``jac`` (eigenvalues, singular values)."""
    rho = float(np.abs(np.linalg.eigvals(jac)).max())
    return rho, float(np.linalg.svd(jac, compute_uv=False)[0])


def dense(probe: Probe) -> tuple[float, float]:
    """(ρ, ‖DG‖) from the whole finite-difference Jacobian (:func:`norms`)."""
    return norms(probe.jacobian())


@dataclass(frozen=True)
class Radius:
    """ρ(DG) by :func:`radius`: ``rho`` (NaN where not ``converged``) and the ``calls`` of G
    (the probe's, including its base call)."""

    rho: float
    converged: bool
    calls: int


class _Spent(Exception):
    """The probe reached its bound on the calls."""


def radius(probe: Probe, seed: int = 0, krylov: int = KRYLOV, tol: float = TOLERANCE,
           max_calls: int | None = MAX_CALLS) -> Radius:
    """ρ(DG) by ARPACK (``scipy.sparse.linalg.eigs``, largest modulus, one eigenvalue) on the
    probe's products, from the random start ``seed``, with a Krylov space of ``krylov`` vectors.

    Converged means ARPACK's test: the Ritz pair (θ, v) has ``‖DG v - θ v‖ <= tol |θ|``, so θ is
    an eigenvalue of DG + E with ``‖E‖ <= tol |θ|`` (for a non-normal DG, ρ may differ from θ by
    more than ``tol |θ|``). ``max_calls`` (None: ARPACK's own limit) bounds the probe's calls of G,
    its base call included; past it, or on ARPACK's no-convergence, the result has
    ``converged=False`` and ``rho`` NaN. Raises :class:`Diverged` when a perturbed call returns a
    non-finite state.
    """
    if probe.size < 3:
        raise ValueError(f"slice map: {probe.size} unknowns; Arnoldi needs at least 3")
    krylov = min(max(krylov, 3), probe.size - 1)

    def product(d: np.ndarray) -> np.ndarray:
        if max_calls is not None and probe.calls >= max_calls:
            raise _Spent
        return probe(d)

    operator = scipy.sparse.linalg.LinearOperator((probe.size, probe.size), matvec=product,
                                                  dtype=float)
    start = np.random.default_rng(seed).standard_normal(probe.size)
    try:
        found = scipy.sparse.linalg.eigs(operator, k=1, which="LM", v0=start, ncv=krylov, tol=tol,
                                         return_eigenvectors=False)
    except (_Spent, scipy.sparse.linalg.ArpackNoConvergence):
        return Radius(float("nan"), False, probe.calls)
    return Radius(float(np.abs(found).max()), True, probe.calls)
