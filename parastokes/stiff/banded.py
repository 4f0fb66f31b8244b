"""Block-sparse products and banded storage for the approximate Jacobian (docs/stiff.md).

``A = M K`` (:mod:`.jacobian`) is the product of two block-sparse matrices: the near mobility
(a block per pair of points within the cutoff) and the loads' Jacobian (a block per pair of
coupled points). :func:`block_product` forms it in one compiled pass (Gustavson's row-by-row
product: about 3 GFLOP/s, no faster than scipy's BSR product, but no conversion follows it).
:func:`band_storage` writes ``I - hγ A`` in LAPACK's banded layout for dgbtrf
(:class:`.solve.Factorization`): a rod's or chain's points in order along it give a band of
(cutoff / spacing + 2) points' rates, whatever its length.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numba import njit

__all__ = ["band_storage", "bandwidth", "block_product"]


@njit(cache=True, fastmath=True)
def _product(m_ptr, m_idx, m_blk, k_ptr, k_idx, k_blk, n_cols):  # pragma: no cover - compiled
    n = len(m_ptr) - 1
    rows, inner, cols = m_blk.shape[1], m_blk.shape[2], k_blk.shape[2]
    marker = np.full(n_cols, -1, dtype=np.int64)
    ptr = np.zeros(n + 1, dtype=np.int64)
    for i in range(n):
        count = 0
        for p in range(m_ptr[i], m_ptr[i + 1]):
            for q in range(k_ptr[m_idx[p]], k_ptr[m_idx[p] + 1]):
                if marker[k_idx[q]] != i:
                    marker[k_idx[q]] = i
                    count += 1
        ptr[i + 1] = ptr[i] + count
    idx = np.empty(ptr[n], dtype=np.int64)
    blk = np.zeros((ptr[n], rows, cols))
    slot = np.full(n_cols, -1, dtype=np.int64)
    for i in range(n):
        end = ptr[i]
        for p in range(m_ptr[i], m_ptr[i + 1]):
            for q in range(k_ptr[m_idx[p]], k_ptr[m_idx[p] + 1]):
                j = k_idx[q]
                if slot[j] < ptr[i]:  # j not yet in row i
                    slot[j] = end
                    idx[end] = j
                    end += 1
                out, mb, kb = blk[slot[j]], m_blk[p], k_blk[q]
                for a in range(rows):
                    for c in range(inner):
                        mac = mb[a, c]
                        for b in range(cols):
                            out[a, b] += mac * kb[c, b]
    return ptr, idx, blk


def block_product(m: sp.bsr_array, k: sp.bsr_array) -> sp.bsr_array:
    """``m @ k`` of two block-sparse arrays whose inner block sizes agree (one compiled pass; the
    column indices of a row are in the order first met)."""
    inner, (inner_k, c) = m.blocksize[1], k.blocksize
    if inner != inner_k or m.shape[1] != k.shape[0]:
        raise ValueError(f"block_product: blocks {m.blocksize} x {k.blocksize}, shapes "
                         f"{m.shape} x {k.shape} do not chain")
    n_cols = k.shape[1] // c
    ptr, idx, blk = _product(m.indptr.astype(np.int64), m.indices.astype(np.int64),
                             np.ascontiguousarray(m.data), k.indptr.astype(np.int64),
                             k.indices.astype(np.int64), np.ascontiguousarray(k.data), n_cols)
    return sp.bsr_array((blk, idx, ptr), shape=(m.shape[0], k.shape[1]))


@njit(cache=True)
def _band_of(ptr, idx, rows, cols):  # pragma: no cover - compiled
    kl = ku = 0
    for i in range(len(ptr) - 1):
        for p in range(ptr[i], ptr[i + 1]):
            j = idx[p]
            kl = max(kl, (i * rows + rows - 1) - j * cols)
            ku = max(ku, (j * cols + cols - 1) - i * rows)
    return kl, ku


def bandwidth(matrix: sp.sparray) -> tuple[int, int]:
    """``(kl, ku)``: the lower and upper bandwidth of ``matrix`` (a block-sparse one counts its
    blocks' every entry)."""
    if isinstance(matrix, sp.bsr_array):
        r, c = matrix.blocksize
        return _band_of(matrix.indptr.astype(np.int64), matrix.indices.astype(np.int64), r, c)
    coo = sp.coo_array(matrix)
    offset = coo.col.astype(np.int64) - coo.row
    return int(-offset.min(initial=0)), int(offset.max(initial=0))


@njit(cache=True)
def _fill(ptr, idx, blk, hgamma, kl, ku, ab):  # pragma: no cover - compiled
    rows, cols = blk.shape[1], blk.shape[2]
    for i in range(len(ptr) - 1):
        for p in range(ptr[i], ptr[i + 1]):
            for b in range(cols):  # down a column of ``ab`` (Fortran order): contiguous
                col = idx[p] * cols + b
                for a in range(rows):
                    ab[kl + ku + i * rows + a - col, col] -= hgamma * blk[p, a, b]


def band_storage(matrix: sp.sparray, hgamma: float, kl: int, ku: int) -> np.ndarray:
    """``I - hγ A`` in LAPACK's layout for dgbtrf: (2 kl + ku + 1, n) in Fortran order, entry
    (i, j) at row ``kl + ku + i - j`` of column ``j`` (the first kl rows are dgbtrf's room for
    fill; a C-ordered array would be copied by scipy's wrapper, 2.6 ms of 5 on the paper's
    rod)."""
    n = matrix.shape[0]
    ab = np.zeros((2 * kl + ku + 1, n), order="F")  # LAPACK's order: dgbtrf copies no more
    ab[kl + ku] = 1.0
    if isinstance(matrix, sp.bsr_array):
        _fill(matrix.indptr.astype(np.int64), matrix.indices.astype(np.int64),
              np.ascontiguousarray(matrix.data), float(hgamma), kl, ku, ab)
    else:
        coo = sp.coo_array(matrix)
        np.add.at(ab, (kl + ku + coo.row - coo.col, coo.col), -hgamma * coo.data)
    return ab
