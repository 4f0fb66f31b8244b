"""The Jacobian of a rod's point loads by compiled segment-wise central differences (the rod's
``load_jacobian`` hook, for the linearly implicit schemes of :mod:`parastokes.stiff`).

The loads of eq. 12 are sums over segments, and each segment's force F, moment N and lever
½ ΔX × F (:func:`.mechanics.segment_loads`) depend on its two nodes only. So each segment is
differentiated alone, in one compiled loop: central differences of size ``step`` in the rates'
own coordinates, as :func:`parastokes.stiff.coloring.fd_jacobian` takes them (a node shifted by
``step`` along an axis, or its frame rotated by the angle ``step`` about one, by the same
Rodrigues rotation as ``advance``), 24 segment evaluations per segment instead of 36 evaluations
of every load with Python between them, and the results added into the blocks of the nodes
each segment's loads go to (f_k += F, f_{k+1} -= F, n_k += N + L, n_{k+1} += L - N).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ...bodies.frames import advance_node
from .mechanics import segment_loads

__all__ = ["load_blocks"]


@njit(cache=True, error_model="numpy")
def load_blocks(state, n_rods, ds, a, b, omega_hat, step, indptr, indices):  # pragma: no cover
    """The 6 x 6 blocks of the loads' Jacobian (rows [f, n] of node k, columns the rates
    [u, w] of node l), in the order of the block pattern ``indptr``/``indices`` (each node and
    its neighbours on its rod, column indices sorted); arguments as
    :func:`.mechanics.rod_loads`, ``step`` the differences' size."""
    n = state.shape[0]
    m = n // n_rods
    inv_ds = 1.0 / ds
    out = np.zeros((len(indices), 6, 6))
    rate = np.zeros(6)
    moved = np.empty(12)
    diff = np.empty(9)
    for r in range(n_rods):
        for k in range(r * m, (r + 1) * m - 1):
            o = omega_hat[k - r * m]
            for side in range(2):  # the perturbed node: k or k + 1
                node = k + side
                for d in range(6):
                    diff[:] = 0.0
                    for sign in (1.0, -1.0):
                        rate[d] = sign * step
                        advance_node(state[node], rate, 1.0, moved)
                        p = moved if side == 0 else state[k]
                        q = moved if side == 1 else state[k + 1]
                        loads = segment_loads(p, q, inv_ds, a[0], a[1], a[2], b[0], b[1], b[2],
                                              o[0], o[1], o[2])
                        for e in range(9):
                            diff[e] += sign * loads[e]
                    rate[d] = 0.0
                    for e in range(9):
                        diff[e] /= 2.0 * step
                    for target in range(k, k + 2):  # the blocks (target, node)
                        slot = indptr[target] + node - indices[indptr[target]]
                        sign = 1.0 if target == k else -1.0
                        for e in range(3):
                            out[slot, e, d] += sign * diff[e]              # ±F
                            out[slot, 3 + e, d] += sign * diff[3 + e] + diff[6 + e]  # ±N + L
    return out
