"""The Jacobian of a rod's point loads by compiled segment-wise central differences (the rod's
``load_jacobian`` hook, for the linearly implicit schemes of :mod:`parastokes.stiff`).

The loads of eq. 12 are sums over segments, and each segment's force F, moment N and lever
½ ΔX × F (:func:`.mechanics.segment_loads`) depend on its two nodes only. So each segment is
differentiated alone, in one compiled loop: central differences of size ``step`` in the rates'
own coordinates, as :func:`parastokes.stiff.coloring.fd_jacobian` takes them (a node shifted by
``step`` along an axis, or its frame rotated by the angle ``step`` about one, by the same
Rodrigues rotation as ``advance``), 18 segment evaluations per segment (the shifts of one node
only: a segment sees X_{k+1} - X_k) instead of 36 evaluations of every load with Python between
them, and the results added into the blocks of the nodes each segment's loads go to
(f_k += F, f_{k+1} -= F, n_k += N + L, n_{k+1} += L - N).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ...bodies.frames import advance_node
from .mechanics import segment_loads

__all__ = ["load_blocks"]


@njit(cache=True, error_model="numpy")
def _turned(state, step):  # pragma: no cover - compiled
    """Every node's row with its frame rotated by the angle ±``step`` about each axis
    (``advance`` by the rate ±step e_{3+d}): (n, 3 axes, 2 signs, 12)."""
    out = np.empty((state.shape[0], 3, 2, 12))
    rate = np.zeros(6)
    for k in range(state.shape[0]):
        for d in range(3):
            for s in range(2):
                rate[3 + d] = step if s == 0 else -step
                advance_node(state[k], rate, 1.0, out[k, d, s])
            rate[3 + d] = 0.0
    return out


@njit(cache=True, error_model="numpy")
def load_blocks(state, n_rods, ds, a, b, omega_hat, step, indptr, indices):  # pragma: no cover
    """The 6 x 6 blocks of the loads' Jacobian (rows [f, n] of node k, columns the rates
    [u, w] of node l), in the order of the block pattern ``indptr``/``indices`` (each node and
    its neighbours on its rod, column indices sorted); arguments as
    :func:`.mechanics.rod_loads`, ``step`` the differences' size. A segment depends on its
    nodes' positions through X_{k+1} - X_k only, so the columns of node k's shifts are those of
    node k+1's, negated: 18 segment evaluations per segment (3 shifts and 6 rotations, ±)."""
    n = state.shape[0]
    m = n // n_rods
    inv_ds = 1.0 / ds
    out = np.zeros((len(indices), 6, 6))
    turned = _turned(state, step)
    moved = np.empty(12)
    diff = np.empty(9)
    for r in range(n_rods):
        for k in range(r * m, (r + 1) * m - 1):
            o = omega_hat[k - r * m]
            for column in range(9):  # shifts of node k+1, rotations of node k, of node k+1
                diff[:] = 0.0
                for s in range(2):
                    p, q = state[k], state[k + 1]
                    if column < 3:
                        moved[:] = q
                        moved[column] += step if s == 0 else -step
                        q = moved
                    elif column < 6:
                        p = turned[k, column - 3, s]
                    else:
                        q = turned[k + 1, column - 6, s]
                    loads = segment_loads(p, q, inv_ds, a[0], a[1], a[2], b[0], b[1], b[2],
                                          o[0], o[1], o[2])
                    for e in range(9):
                        diff[e] += loads[e] if s == 0 else -loads[e]
                for e in range(9):
                    diff[e] /= 2.0 * step
                for node in range(k, k + 2):  # the columns (node, d) this difference gives
                    if column < 3:
                        d, sign_node = column, 1.0 if node == k + 1 else -1.0
                    elif node == k + (column >= 6):
                        d, sign_node = column - 3 * (column >= 6), 1.0
                    else:
                        continue
                    for target in range(k, k + 2):  # the blocks (target, node)
                        slot = indptr[target] + node - indices[indptr[target]]
                        sign = sign_node if target == k else -sign_node
                        for e in range(3):
                            out[slot, e, d] += sign * diff[e]  # ±F
                            out[slot, 3 + e, d] += sign * diff[3 + e] + sign_node * diff[6 + e]
    return out
