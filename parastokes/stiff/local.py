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


def _cross_matrix(r: np.ndarray) -> np.ndarray:
    """[r]_x, (P, 3, 3): [r]_x v = r × v."""
    out = np.zeros(r.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2] = -r[..., 2], r[..., 1]
    out[..., 1, 0], out[..., 1, 2] = r[..., 2], -r[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -r[..., 1], r[..., 0]
    return out


def pair_blocks(r: np.ndarray, eps: float, angular: bool) -> np.ndarray:
    """8π μ × the mobility blocks of pairs with separations ``r`` (P, 3): (P, 3, 3) force ->
    velocity, or with ``angular`` (P, 6, 6) of ``[u, w]`` from ``[f, n]``."""
    r2 = np.einsum("pk,pk->p", r, r)
    e2 = eps * eps
    i3 = (r2 + e2) ** -1.5
    i5 = i3 / (r2 + e2)
    rr = r[:, :, None] * r[:, None, :]
    eye = np.eye(3)
    uf = ((r2 + 2 * e2) * i3)[:, None, None] * eye + i3[:, None, None] * rr
    if not angular:
        return uf
    cross = _cross_matrix(r)
    out = np.empty((len(r), 6, 6))
    out[:, :3, :3] = uf
    out[:, :3, 3:] = -i3[:, None, None] * cross                          # (n × r)/r_ε³
    out[:, 3:, :3] = -0.5 * ((2 * r2 + 5 * e2) * i5)[:, None, None] * cross  # ½ q (f × r)
    p1 = 2.0 * (r2 - 2 * e2) * i5                                           # 8π × (4)'s p1
    p2 = -6.0 * i5
    out[:, 3:, 3:] = -0.25 * (p1[:, None, None] * eye + p2[:, None, None] * rr)
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
