"""The chain's mechanics as compiled functions (shared by its Python methods and its compiled
parts, :mod:`.stepping`): the forces of the energy E of :mod:`parastokes.kinds.chain`, E itself in
plain numpy (their oracle) and the stability monitor."""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["bond_strain", "chain_energy", "chain_forces"]


@njit(cache=True, error_model="numpy")
def chain_forces(x, bond, stiffness, bending):
    """F = -∂E/∂X (N, 3) of the springs and the bending penalty of the module docstring."""
    n = x.shape[0]
    out = np.zeros_like(x)
    t = np.empty((n - 1, 3))
    length = np.empty(n - 1)
    for i in range(n - 1):
        for j in range(3):
            t[i, j] = x[i + 1, j] - x[i, j]
        length[i] = np.sqrt(t[i, 0] ** 2 + t[i, 1] ** 2 + t[i, 2] ** 2)
        c = stiffness * (length[i] - bond) / length[i]
        for j in range(3):
            out[i, j] += c * t[i, j]
            out[i + 1, j] -= c * t[i, j]
    w = bending / bond
    for i in range(1, n - 1):
        a, b = i - 1, i  # bonds on either side of bead i
        cos = (t[a, 0] * t[b, 0] + t[a, 1] * t[b, 1] + t[a, 2] * t[b, 2]) / (length[a] * length[b])
        for j in range(3):
            ua = t[a, j] / length[a]
            ub = t[b, j] / length[b]
            da = (ub - cos * ua) / length[a]  # ∂cos/∂t_a
            db = (ua - cos * ub) / length[b]  # ∂cos/∂t_b
            out[i - 1, j] -= w * da
            out[i, j] += w * (da - db)
            out[i + 1, j] += w * db
    return out


def chain_energy(x: np.ndarray, bond: float, stiffness: float, bending: float) -> float:
    """E of the module docstring (plain numpy: the oracle of :func:`chain_forces`)."""
    t = np.diff(x, axis=0)
    length = np.linalg.norm(t, axis=1)
    unit = t / length[:, None]
    cos = np.einsum("ij,ij->i", unit[:-1], unit[1:])
    return float(0.5 * stiffness * ((length - bond) ** 2).sum() + bending / bond * (1 - cos).sum())


@njit(cache=True, error_model="numpy")
def bond_strain(x, bond):
    """The largest relative deviation of a bond length from the rest length b."""
    worst = 0.0
    for i in range(x.shape[0] - 1):
        dx = x[i + 1, 0] - x[i, 0]
        dy = x[i + 1, 1] - x[i, 1]
        dz = x[i + 1, 2] - x[i, 2]
        strain = abs(np.sqrt(dx * dx + dy * dy + dz * dz) / bond - 1.0)
        if not strain <= worst:  # NaN propagates
            worst = strain
    return worst
