"""The regularized Stokeslet mobility restricted to near pairs: a sparse matrix (docs/stiff.md).

The stiff modes of a body are short (a rod's bending modes of a few Δs, a vesicle's spring
modes of one edge), and the fluid couples them through the kernels within a few ε of each
point. :func:`near_mobility` keeps the pairs of points closer than ``cutoff`` (a k-d tree,
scipy.spatial) and writes their blocks in free space, from the formulas of
:mod:`parastokes.mrs.reference` ((1)-(4) of docs/kernels.md; the torque blob ψ_ε of the
default variant): force -> velocity (Stokeslet), torque -> velocity (rotlet), force -> angular
velocity (½ curl of the Stokeslet), torque -> angular velocity (potential dipole). The wall's
images and the far pairs are left out: the matrix is the approximate Jacobian of a W-method,
whose order does not depend on it.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numba import njit
from scipy.spatial import cKDTree

__all__ = ["near_mobility", "near_pairs"]

_EIGHT_PI = 8.0 * np.pi


def near_pairs(points: np.ndarray, cutoff: float) -> tuple[np.ndarray, np.ndarray]:
    """Target and source indices of every ordered pair closer than ``cutoff``, self pairs
    included."""
    pairs = cKDTree(points).query_pairs(cutoff, output_type="ndarray")
    n = len(points)
    own = np.arange(n)
    return (np.concatenate([own, pairs[:, 0], pairs[:, 1]]),
            np.concatenate([own, pairs[:, 1], pairs[:, 0]]))


@njit(cache=True, error_model="numpy")
def _pair_blocks(r, eps, angular, out):  # pragma: no cover - compiled
    e2 = eps * eps
    for p in range(r.shape[0]):
        x, y, z = r[p, 0], r[p, 1], r[p, 2]
        r2 = x * x + y * y + z * z
        i3 = (r2 + e2) ** -1.5
        i5 = i3 / (r2 + e2)
        diag = (r2 + 2.0 * e2) * i3
        v = (x, y, z)
        for a in range(3):
            for b in range(3):
                out[p, a, b] = i3 * v[a] * v[b] + (diag if a == b else 0.0)
        if not angular:
            continue
        q = 0.5 * (2.0 * r2 + 5.0 * e2) * i5
        p1 = -0.5 * (r2 - 2.0 * e2) * i5  # -1/4 of 8π × (4)'s p1
        p2 = 1.5 * i5                      # -1/4 of 8π × (4)'s p2
        # [r]_x rows: (0, -z, y), (z, 0, -x), (-y, x, 0)
        cross = ((0.0, -z, y), (z, 0.0, -x), (-y, x, 0.0))
        for a in range(3):
            for b in range(3):
                out[p, a, 3 + b] = -i3 * cross[a][b]
                out[p, 3 + a, b] = -q * cross[a][b]
                out[p, 3 + a, 3 + b] = p2 * v[a] * v[b] + (p1 if a == b else 0.0)


def pair_blocks(r: np.ndarray, eps: float, angular: bool) -> np.ndarray:
    """8π μ × the mobility blocks of pairs with separations ``r`` (P, 3): (P, 3, 3) force ->
    velocity, or with ``angular`` (P, 6, 6) of ``[u, w]`` from ``[f, n]``: the Stokeslet
    (r² + 2ε²)/r_ε³ I + r rᵀ/r_ε³, the rotlet -[r]ₓ/r_ε³, ½ the Stokeslet's curl
    -½ (2r² + 5ε²)/r_ε⁵ [r]ₓ and the potential dipole -¼ (p₁ I + p₂ r rᵀ)."""
    r = np.ascontiguousarray(r, dtype=float)
    size = 6 if angular else 3
    out = np.empty((len(r), size, size))
    _pair_blocks(r, float(eps), bool(angular), out)
    return out


def wendland(q: np.ndarray) -> np.ndarray:
    """Wendland's compactly supported C² function (1 - q)⁴ (4q + 1) for q < 1, else 0:
    positive definite in three dimensions (Wendland, Adv. Comput. Math. 4, 1995), so the
    mobility tapered by it stays positive semi-definite (Schur's product theorem)."""
    q = np.minimum(q, 1.0)
    return (1.0 - q) ** 4 * (4.0 * q + 1.0)


def near_mobility(points: np.ndarray, epsilon: float, viscosity: float, angular: bool,
                  cutoff: float) -> sp.bsr_array:
    """The free-space mobility of the pairs closer than ``cutoff``, tapered by :func:`wendland`:
    (n V, n V) sparse in blocks of V x V, V = 6 (``[u, w]`` from ``[f, n]``) with ``angular``,
    else 3, point-major rows and columns."""
    points = np.ascontiguousarray(points, dtype=float)
    target, source = near_pairs(points, cutoff)
    order = np.lexsort((source, target))
    target, source = target[order], source[order]
    r = points[target] - points[source]
    blocks = pair_blocks(r, float(epsilon), angular)
    blocks *= (wendland(np.sqrt(np.einsum("pk,pk->p", r, r)) / cutoff)
               / (_EIGHT_PI * viscosity))[:, None, None]
    n, v = len(points), blocks.shape[1]
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(target, minlength=n), out=indptr[1:])
    return sp.bsr_array((blocks, source, indptr), shape=(n * v, n * v))
