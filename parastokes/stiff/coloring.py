"""Sparse Jacobians by coloured finite differences (Curtis, Powell & Reid, IMA J. Appl. Math. 13,
1974): points whose loads never depend on a common point are perturbed together.

A body's loads at point ``i`` depend on the state of a few points only (a rod node on its two
neighbours, a vesicle vertex on the vertices it shares a spring with). ``coupling`` is that
pattern as an (n, n) sparse matrix (entry (i, j): the loads at ``i`` depend on point ``j``); the
points are coloured so that no row meets two points of one colour, and each colour costs two
evaluations (central differences) per rate column instead of two per point.

Perturbations are taken in the rates' own coordinates, ``advance(x, δ, 1)``: for positions a
shift, for a rod's frames a rotation, so the Jacobian is the one the stage solves of
:mod:`.stepper` need.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np
import scipy.sparse as sp

__all__ = ["banded", "colours", "fd_jacobian", "from_edges"]


def colours(coupling: sp.spmatrix | sp.sparray) -> np.ndarray:
    """A colour per point (column of ``coupling``) such that no row has two points of one colour
    (greedy, in point order); the number of colours is ``max + 1``."""
    pattern = sp.csc_array(coupling, dtype=bool).astype(np.int8)
    n = pattern.shape[1]
    # points that share a row may not share a colour: the column intersection graph
    graph = sp.csr_array(pattern.T @ pattern)
    out = np.full(n, -1, dtype=np.int64)
    for j in range(n):
        taken = out[graph.indices[graph.indptr[j]: graph.indptr[j + 1]]]
        used = np.zeros(len(taken) + 1, dtype=bool)
        used[taken[(taken >= 0) & (taken <= len(taken))]] = True
        out[j] = int(np.argmin(used))
    return out


_COLOURS: dict[tuple, np.ndarray] = {}


def _cached_colours(rows: np.ndarray, cols: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """:func:`colours` of a pattern given by its entries, kept per pattern (a body's coupling
    is the same at every step; at most 64 patterns are kept)."""
    key = (shape, hash(rows.tobytes()), hash(cols.tobytes()))
    if key not in _COLOURS:
        if len(_COLOURS) >= 64:
            _COLOURS.clear()
        _COLOURS[key] = colours(sp.coo_array((np.ones(len(rows), dtype=bool), (rows, cols)),
                                             shape=shape))
    return _COLOURS[key]


def fd_jacobian(
    function: Callable[[np.ndarray], np.ndarray],
    advance: Callable[[np.ndarray, np.ndarray, float], np.ndarray],
    x: np.ndarray,
    rate_columns: int,
    coupling: sp.spmatrix | sp.sparray,
    step: float,
) -> sp.bsr_array:
    """The Jacobian of ``function`` (state -> (n, L) values per point) with respect to a rate
    perturbation ``δ`` (n, ``rate_columns``) applied by ``advance(x, δ, 1)``, as a sparse
    (n L, n rate_columns) matrix in blocks of L x rate_columns (one per entry of ``coupling``),
    row ``L i + l`` and column ``rate_columns j + q`` point-major; central differences of size
    ``step``, one pair per colour of ``coupling`` and rate column.
    """
    pattern = sp.csr_array(coupling, dtype=bool)
    pattern.sort_indices()
    rows_all = np.repeat(np.arange(pattern.shape[0]), np.diff(pattern.indptr))
    cols_all = pattern.indices.astype(np.int64)
    colour = _cached_colours(rows_all, cols_all, pattern.shape)
    n, rc = len(colour), rate_columns
    n_colours = int(colour.max()) + 1 if n else 0
    diffs = []  # (colour, q) -> (n, L): each row meets one point of a colour
    for c in range(n_colours):
        points = colour == c
        for q in range(rc):
            delta = np.zeros((n, rc))
            delta[points, q] = step
            plus = np.asarray(function(advance(x, delta, 1.0)), dtype=float)
            minus = np.asarray(function(advance(x, -delta, 1.0)), dtype=float)
            diffs.append((plus - minus).reshape(n, -1) / (2.0 * step))
    width = diffs[0].shape[1] if diffs else 1
    if not diffs:
        return sp.bsr_array((n * width, n * rc), blocksize=(width, rc))
    table = np.stack(diffs).reshape(n_colours, rc, n, width)
    blocks = table[colour[cols_all], :, rows_all, :].transpose(0, 2, 1)  # (entries, L, rc)
    return sp.bsr_array((np.ascontiguousarray(blocks), cols_all, pattern.indptr),
                        shape=(n * width, n * rc))


@functools.lru_cache(maxsize=32)
def banded(n_groups: int, size: int, width: int) -> sp.csr_array:
    """The coupling of ``n_groups`` chains of ``size`` points whose loads depend on the points
    within ``width`` of them along their own chain (a rod's nodes: 1; a chain's beads: 2);
    cached, so do not modify it."""
    n = n_groups * size
    index = np.arange(n)
    rows, cols = [], []
    for offset in range(-width, width + 1):
        other = index + offset
        keep = (other >= 0) & (other < n) & (other // size == index // size)
        rows.append(index[keep])
        cols.append(other[keep])
    rows_all, cols_all = np.concatenate(rows), np.concatenate(cols)
    return sp.csr_array((np.ones(len(rows_all), dtype=bool), (rows_all, cols_all)), shape=(n, n))


def from_edges(n: int, edges: np.ndarray) -> sp.csr_array:
    """The coupling of ``n`` points whose loads depend on themselves and on the points they
    share an edge with (a vesicle's springs), edges (E, 2)."""
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    own = np.arange(n)
    rows = np.concatenate([own, edges[:, 0], edges[:, 1]])
    cols = np.concatenate([own, edges[:, 1], edges[:, 0]])
    return sp.csr_array((np.ones(len(rows), dtype=bool), (rows, cols)), shape=(n, n))
