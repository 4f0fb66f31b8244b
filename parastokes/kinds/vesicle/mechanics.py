"""The spring-network vesicle (paper section 5.2; docs/physics.md section 4, (14)).

Every mesh edge is a Hookean spring of stiffness κ with rest length ℓ⁰ = its initial length; the
point force on the fluid at vertex i is
``F_i = Σ_{j~i} κ (|X_j - X_i| - ℓ⁰_ij) (X_j - X_i)/|X_j - X_i|``.
A stretched spring pulls its two ends toward each other, so the forces relax the shape; they sum to
zero and have zero net torque about any point (each spring contributes an equal and opposite pair
along the line joining its ends).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(inline="always", cache=True, error_model="numpy")
def spring_pull(points, i, j, rest, stiffness):
    """κ (d - ℓ⁰) (X_j - X_i)/d, ``d = |X_j - X_i|``: the force of the spring (i, j) on the fluid at
    X_i (minus it at X_j). Also compiled as a CUDA device function by :mod:`parastokes.gpu`."""
    dx = points[j, 0] - points[i, 0]
    dy = points[j, 1] - points[i, 1]
    dz = points[j, 2] - points[i, 2]
    d = math.sqrt(dx * dx + dy * dy + dz * dz)
    c = stiffness * (d - rest) / d
    return c * dx, c * dy, c * dz


@njit(cache=True, error_model="numpy")
def spring_forces(points, edges, rest, stiffness):
    """Point forces (N, 3) on the fluid from springs on ``edges`` (E, 2), rest lengths ``rest``."""
    out = np.zeros_like(points)
    for e in range(edges.shape[0]):
        i = edges[e, 0]
        j = edges[e, 1]
        px, py, pz = spring_pull(points, i, j, rest[e], stiffness)
        out[i, 0] += px
        out[i, 1] += py
        out[i, 2] += pz
        out[j, 0] -= px
        out[j, 1] -= py
        out[j, 2] -= pz
    return out
