"""Restarted GMRES (Saad & Schultz 1986): Arnoldi with modified Gram–Schmidt, Givens rotations
on the Hessenberg matrix, the least-squares residual as the stopping rule.

The mobility solves (:mod:`parastokes.mobility.krylov`) call it instead of
``scipy.sparse.linalg.gmres`` for what scipy's does besides: scipy's computes the true residual
b - A x with one more product of the operator after every cycle, the last one included, and
:mod:`.krylov` then computed it once more to check the solution, so every solve paid two
products of the whole fluid operator (two iterations' worth) beyond its iterations. Here a cycle
ends on the Arnoldi residual (the least-squares residual of the Hessenberg problem), which equals
the true residual up to round-off (MGS-GMRES is backward stable: Paige, Rozložník & Strakoš,
SIAM J. Matrix Anal. Appl. 28 (2006)), and a restart continues from the Arnoldi residual's
vector, also without a product. Same iterates as scipy's in exact arithmetic (same Arnoldi
process, same stopping rule ‖r_k‖ <= tol ‖b‖): the iteration counts pinned in docs/numbers.toml
did not change; ``tests/test_mobility_gmres.py`` checks the true residual against the estimate.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_triangular

__all__ = ["GmresResult", "gmres"]


@dataclass(frozen=True)
class GmresResult:
    """``x``, the products of the operator made (``iterations``) and the Arnoldi estimate of
    the residual ‖b - A x‖ at the end (``estimate``)."""

    x: np.ndarray
    iterations: int
    estimate: float


def _givens(a: float, b: float) -> tuple[float, float, float]:
    """(c, s, r) with [c s; -s c] [a; b] = [r; 0]."""
    if b == 0.0:
        return 1.0, 0.0, a
    r = math.hypot(a, b)
    return a / r, b / r, r


def gmres(apply: Callable[[np.ndarray], np.ndarray], b: np.ndarray, tol: float, *,
          restart: int, max_iterations: int) -> GmresResult:
    """Solve A x = b (``apply``: x -> A x) from x = 0 until the Arnoldi residual is at most
    ``tol`` ‖b‖ or ``max_iterations`` products were made, keeping at most ``restart`` Krylov
    vectors."""
    n = len(b)
    x = np.zeros(n)
    r = b.copy()
    target = tol * float(np.linalg.norm(b))
    beta = float(np.linalg.norm(r))
    iterations = 0
    while beta > target and iterations < max_iterations:
        m = min(restart, max_iterations - iterations)
        v = [r / beta]  # the Krylov basis, grown as the iterations go (memory ~ iterations x n)
        h = np.zeros((m + 1, m))
        rotations: list[tuple[float, float]] = []
        g = np.zeros(m + 1)
        g[0] = beta
        k = 0
        while k < m:
            w = apply(v[k])
            iterations += 1
            for i in range(k + 1):  # modified Gram–Schmidt
                h[i, k] = float(v[i] @ w)
                w -= h[i, k] * v[i]
            h[k + 1, k] = float(np.linalg.norm(w))
            breakdown = h[k + 1, k] <= 1e-14 * float(np.linalg.norm(h[: k + 2, k]))
            v.append(w / h[k + 1, k] if not breakdown else np.zeros(n))
            for i, (c, s) in enumerate(rotations):
                h[i, k], h[i + 1, k] = (c * h[i, k] + s * h[i + 1, k],
                                        -s * h[i, k] + c * h[i + 1, k])
            c, s, h[k, k] = _givens(h[k, k], h[k + 1, k])
            h[k + 1, k] = 0.0
            rotations.append((c, s))
            g[k], g[k + 1] = c * g[k], -s * g[k]
            k += 1
            if abs(g[k]) <= target or breakdown:
                break
        y = solve_triangular(h[:k, :k], g[:k]) if k else np.zeros(0)
        for coefficient, vector in zip(y, v, strict=False):
            x += coefficient * vector
        beta = abs(float(g[k]))
        if k < m and beta > target:  # a breakdown short of the target: the true residual
            r = b - apply(x)
            iterations += 1
            beta = float(np.linalg.norm(r))
            if beta > target:
                break
        elif beta > target:  # restart from the Arnoldi residual's vector
            r = np.zeros(n)
            for coefficient, vector in zip(_residual_coefficients(rotations, g[k], k), v,
                                           strict=False):
                r += coefficient * vector
    return GmresResult(x, iterations, beta)


def _residual_coefficients(rotations: list[tuple[float, float]], last: float, k: int
                           ) -> np.ndarray:
    """The coefficients of the residual b - A x in the Arnoldi basis v_0..v_k after k steps:
    Qᵀ (0, ..., 0, g_k), undoing the Givens rotations."""
    e = np.zeros(k + 1)
    e[k] = last
    for i in range(k - 1, -1, -1):
        c, s = rotations[i]
        e[i], e[i + 1] = c * e[i] - s * e[i + 1], s * e[i] + c * e[i + 1]
    return e
