"""The linearized map DG of x0 -> G(x0) over one slice, on position perturbations: its spectral
radius rho(DG) (the growth per slice of a perturbation under repeated application, what decides
whether a sweep of coarse steps is stable) and, where the Jacobian is small enough to form, its
norm ‖DG‖ (largest singular value: the worst one-slice amplification of a single perturbation).
docs/validation.md section 2, "Measured: the linearized coarse map over one slice".

The method is the package's (``parastokes.tuning.slice_map``, which the tuner uses too): DG is
only available through finite differences of G, one call of G per product DG d; there is no
adjoint (so no Lanczos bidiagonalization for the norm of a large DG). This module chooses by size,
with the study's tolerances (tighter than the tuner's):

- 3M <= ``DENSE_LIMIT`` (the rods, M = 61: 184 calls): the whole Jacobian by forward
  differences; rho from its eigenvalues, ‖DG‖ from its singular values (numpy), both exact up to
  the differences' error. This DG is far from normal (norm 50, eigenvalues near 1), so its
  eigenvalues move with that error: on Table 5 G^1 over the paper's slice forward differences
  gave rho = 1.92, 1.28, 1.053, 1.00086, 1.00075, 1.00099 at absolute steps 1e-7, 1e-6, 1e-5,
  3e-5, 1e-4, 1.2e-4 (round-off of the weighted sums falls as 1/step), central ones
  (``central=True``) 1.0016 and 1.0011 at 1.2e-4 and 4e-4; the norm 49.78 +- 0.01 throughout.
- larger (the vesicle, 3M = 1926, whose Jacobian takes 1927 calls): rho by ARPACK's
  implicitly restarted Arnoldi (scipy.sparse.linalg.eigs, largest modulus) on the products,
  converged to ``RTOL``; the norm is left out here (a Krylov space of forward products alone gave
  a lower bound that still grew by 0.5% between 24 and 90 directions on Table 8 G^1). It needs no
  adjoint: :func:`dense_resumable` forms the whole Jacobian at any size, column by column with a
  resumable checkpoint (``validation.coarse_slices.dense_map``, ``--dense-norms``): 7 to 21 min
  on one shared core for the 642-point vesicle over its former quick slices (4 to 12 steps).

The five-step power iteration d <- DG d / |DG d| that this replaces returned neither: on Table 5
G^1 over the paper's slice it gave 1.19 and 1.37 from two starts and 1.39 after ten steps, while
the eigenvalues of largest modulus there cluster within 1e-3 of 1 (so the iteration barely
converges towards rho) and the norm is 50 (a perturbation of one point against the rod's frames
turns the whole tail, a transient that a stable map has too); on Table 8 G^1 over the former
quick slice it gave 18.08 where rho is 20.34.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from parastokes.tuning.slice_map import Probe, dense, norms, radius

__all__ = ["DENSE_LIMIT", "RTOL", "Probe", "arnoldi_radius", "dense", "dense_resumable",
           "jacobian", "linearization"]

#: Largest 3M for which the Jacobian is formed whole.
DENSE_LIMIT = 600
#: Relative tolerance of ARPACK's rho.
RTOL = 1e-6


def arnoldi_radius(probe: Probe, seed: int = 0, ncv: int = 20) -> float:
    """rho by ARPACK (largest modulus) from a random start ``seed``, to ``RTOL``, without a bound
    on the calls; RuntimeError if ARPACK does not converge."""
    found = radius(probe, seed, krylov=ncv, tol=RTOL, max_calls=None)
    if not found.converged:
        raise RuntimeError(f"ARPACK did not converge to rho within {found.calls} calls")
    return found.rho


def linearization(propagate: Callable[[np.ndarray], np.ndarray], positions, x0: np.ndarray,
                  seed: int = 0) -> dict:
    """{"rho", "norm" (NaN where not formed), "method", "calls"} of DG at ``x0``."""
    probe = Probe(propagate, positions, x0)
    if probe.size <= DENSE_LIMIT:
        rho, norm = dense(probe)
        method = "dense"
    else:
        rho, norm, method = arnoldi_radius(probe, seed), float("nan"), "arnoldi"
    return {"rho": rho, "norm": norm, "method": method, "calls": probe.calls}


def jacobian(probe: Probe, checkpoint: Path | None = None, every: int = 32) -> np.ndarray:
    """The whole Jacobian of ``probe``, column by column (one call of G each), as
    ``Probe.jacobian``; with ``checkpoint`` (a ``.npy`` path) the columns done so far are saved
    every ``every`` columns and a rerun resumes from them (the vesicle's 1926 columns took 7 to
    21 min on one shared core over its former quick slices of 4 to 12 coarse steps)."""
    columns: list[np.ndarray] = []
    if checkpoint is not None and checkpoint.exists():
        saved = np.load(checkpoint)
        if saved.shape[1:] != (probe.size,):
            raise ValueError(f"{checkpoint}: columns of size {saved.shape[1:]}, this map has "
                             f"{probe.size}; delete it or choose another path")
        columns = list(saved)
    for i in range(len(columns), probe.size):
        unit = np.zeros(probe.size)
        unit[i] = 1.0
        columns.append(probe(unit))
        if checkpoint is not None and (len(columns) % every == 0 or i == probe.size - 1):
            partial = checkpoint.with_suffix(".partial")
            with partial.open("wb") as out:  # whole or not at all, should the run be killed
                np.save(out, np.array(columns))
            partial.replace(checkpoint)
    return np.array(columns).T


def dense_resumable(probe: Probe, checkpoint: Path | None = None) -> tuple[float, float]:
    """(rho, ‖DG‖) as ``dense``, from the Jacobian of :func:`jacobian` (resumable)."""
    return norms(jacobian(probe, checkpoint))
