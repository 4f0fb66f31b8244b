"""Block-sparse products and banded storage for the approximate Jacobian (docs/stiff.md).

``A = M K`` (:mod:`.jacobian`) is the product of two block-sparse matrices: the near mobility
(a block per pair of points within the cutoff) and the loads' Jacobian (a block per pair of
coupled points). For a body whose points lie in order along it (a rod, a chain),
:func:`near_product` writes ``A`` in one compiled pass straight into LAPACK's band layout,
forming M's blocks on the fly and never storing M: a rod's or chain's band is
(cutoff / spacing + 2) points' rates, whatever its length. Otherwise :func:`block_product`
multiplies the stored near mobility by K (Gustavson's row-by-row product). :func:`band_storage`
writes ``I - hγ A`` in the layout of dgbtrf (:class:`.solve.Factorization`).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numba import njit

from .local import coefficients, near_mobility, sorted_pairs, taper

__all__ = ["band_storage", "bandwidth", "block_product", "narrow", "near_product"]


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
def _reach(m_ptr, m_idx, k_ptr, k_idx, rows, cols):  # pragma: no cover - compiled
    """How far the block patterns reach: ``(lp, up)`` the most points a pair of ``m`` reaches
    below and above its row, ``(k_lo, k_hi)`` the same for ``k``, and ``(kl, ku)`` of the
    product of ``m`` (rows x inner blocks) and ``k`` (inner x cols blocks), as
    :func:`bandwidth` counts them."""
    lp = up = k_lo = k_hi = kl = ku = 0
    for j in range(len(k_ptr) - 1):
        for q in range(k_ptr[j], k_ptr[j + 1]):
            k_lo = max(k_lo, j - k_idx[q])
            k_hi = max(k_hi, k_idx[q] - j)
    for i in range(len(m_ptr) - 1):
        for p in range(m_ptr[i], m_ptr[i + 1]):
            lp = max(lp, i - m_idx[p])
            up = max(up, m_idx[p] - i)
            for q in range(k_ptr[m_idx[p]], k_ptr[m_idx[p] + 1]):
                j = k_idx[q]
                kl = max(kl, (i * rows + rows - 1) - j * cols)
                ku = max(ku, (j * cols + cols - 1) - i * rows)
    return lp, up, k_lo, k_hi, kl, ku


@njit(cache=True)
def _dense_rows(k_ptr, k_idx, k_blk, k_lo, width):  # pragma: no cover - compiled
    """The block rows of ``k`` as dense strips, column-major: ``out[j, (l - j + k_lo) cols + b,
    c]`` = entry (c, b) of block (j, l), ``width`` blocks per strip."""
    rows, cols = k_blk.shape[1], k_blk.shape[2]
    out = np.zeros((len(k_ptr) - 1, width * cols, rows))
    for j in range(len(k_ptr) - 1):
        for q in range(k_ptr[j], k_ptr[j + 1]):
            first = (k_idx[q] - j + k_lo) * cols
            for b in range(cols):
                for c in range(rows):
                    out[j, first + b, c] = k_blk[q, c, b]
    return out


@njit(cache=True, fastmath=True, error_model="numpy")
def _near_band(points, m_ptr, m_idx, eps, cutoff, viscosity, angular, strips, lp, lo, width,
               kl, ku, data):  # pragma: no cover - compiled
    """``data`` = M K in LAPACK's band layout (entry (r, c) at ``data[ku + r - c, c]``). Per
    point i, each pair (i, j) of M multiplies K's strip j (:func:`_dense_rows`) into the block
    row of i, held column by column (``width`` blocks from point i - ``lo``; pair j at block
    j - i + ``lp``), which is then written out. M's block is never formed: with r = X_i - X_j,
    a column's force rows k_f and torque rows k_n (``angular``) and the scalars of
    :func:`.local.coefficients` times :func:`.local.taper`, the velocity rows gain
    diag k_f + i3 r (r·k_f) - i3 r × k_n and the angular ones -q r × k_f + p1 k_n + p2 r (r·k_n)
    (a column's six rows next to each other in memory: they vectorize)."""
    strip = strips.shape[1]
    size = 6 if angular else 3
    cols = data.shape[1] // (len(m_ptr) - 1)
    row = np.empty((width * cols, size))
    e2 = eps * eps
    for i in range(len(m_ptr) - 1):
        row[:] = 0.0
        for p in range(m_ptr[i], m_ptr[i + 1]):
            j = m_idx[p]
            x = points[i, 0] - points[j, 0]
            y = points[i, 1] - points[j, 1]
            z = points[i, 2] - points[j, 2]
            r2 = x * x + y * y + z * z
            diag, i3, q, p1, p2 = coefficients(r2, e2)
            scale = taper(r2, cutoff, viscosity)
            diag, i3, q, p1, p2 = diag * scale, i3 * scale, q * scale, p1 * scale, p2 * scale
            first = (j - i + lp) * cols
            for e in range(strip):
                k, out = strips[j, e], row[first + e]
                f0, f1, f2 = k[0], k[1], k[2]
                rf = i3 * (x * f0 + y * f1 + z * f2)
                if angular:
                    n0, n1, n2 = k[3], k[4], k[5]
                    rn = p2 * (x * n0 + y * n1 + z * n2)
                    out[0] += diag * f0 + rf * x - i3 * (y * n2 - z * n1)
                    out[1] += diag * f1 + rf * y - i3 * (z * n0 - x * n2)
                    out[2] += diag * f2 + rf * z - i3 * (x * n1 - y * n0)
                    out[3] += p1 * n0 + rn * x - q * (y * f2 - z * f1)
                    out[4] += p1 * n1 + rn * y - q * (z * f0 - x * f2)
                    out[5] += p1 * n2 + rn * z - q * (x * f1 - y * f0)
                else:
                    out[0] += diag * f0 + rf * x
                    out[1] += diag * f1 + rf * y
                    out[2] += diag * f2 + rf * z
        # out to the band: column c, rows r = i size + a with -kl <= c - r <= ku
        col0 = (i - lo) * cols
        for col in range(max(col0, 0), min(col0 + width * cols, data.shape[1])):
            top = ku + i * size - col  # data's row of (i size, col)
            for a in range(max(0, -top), min(size, kl + ku + 1 - top)):
                data[top + a, col] = row[col - col0, a]


def near_product(points: np.ndarray, epsilon: float, viscosity: float, angular: bool,
                 cutoff: float, k: sp.bsr_array) -> sp.dia_array | sp.bsr_array:
    """``A = M_near K``: the near mobility of :func:`.local.near_mobility` (the same arguments)
    times ``k`` (block-sparse, square, blocks of V x V, V = 6 with ``angular``, else 3). When
    the product's band is :func:`narrow` (a rod's or chain's points in order), one compiled
    pass writes it straight into LAPACK's band layout, never storing M: a ``dia_array`` whose
    ``data`` (kl + ku + 1, n), Fortran order, holds entry (i, j) at row ``ku + i - j`` of
    column j (offsets ku down to -kl), as :class:`.solve.Factorization` takes it. Otherwise (a
    vesicle, a rod curled onto itself) M's blocks and :func:`block_product`."""
    points = np.ascontiguousarray(points, dtype=float)
    size = 6 if angular else 3
    if k.blocksize != (size, size) or k.shape != (len(points) * size,) * 2:
        raise ValueError(f"near_product: K of shape {k.shape} in blocks {k.blocksize}; expected "
                         f"{(len(points) * size,) * 2} in blocks {(size, size)}")
    indptr, source = sorted_pairs(points, cutoff)
    k_ptr, k_idx = k.indptr.astype(np.int64), k.indices.astype(np.int64)
    lp, up, k_lo, k_hi, kl, ku = _reach(indptr, source, k_ptr, k_idx, size, size)
    n = len(points) * size
    if not narrow(kl, ku, n):
        return block_product(near_mobility(points, epsilon, viscosity, angular, cutoff), k)
    strips = _dense_rows(k_ptr, k_idx, np.ascontiguousarray(k.data), k_lo, k_lo + k_hi + 1)
    data = np.zeros((kl + ku + 1, n), order="F")
    _near_band(points, indptr, source, float(epsilon), float(cutoff), float(viscosity),
               bool(angular), strips, lp, lp + k_lo, lp + up + k_lo + k_hi + 1, kl, ku, data)
    return sp.dia_array((data, np.arange(ku, -kl - 1, -1)), shape=(n, n))


@njit(cache=True)
def _band_of(ptr, idx, rows, cols):  # pragma: no cover - compiled
    kl = ku = 0
    for i in range(len(ptr) - 1):
        for p in range(ptr[i], ptr[i + 1]):
            j = idx[p]
            kl = max(kl, (i * rows + rows - 1) - j * cols)
            ku = max(ku, (j * cols + cols - 1) - i * rows)
    return kl, ku


def narrow(kl: int, ku: int, n: int) -> bool:
    """Whether a square matrix of size ``n`` and bandwidths ``(kl, ku)`` is stored and
    factorized as a band (LAPACK's dgbtrf): its band below an eighth of its size."""
    return max(kl, ku) < n // 8


def bandwidth(matrix: sp.sparray) -> tuple[int, int]:
    """``(kl, ku)``: the lower and upper bandwidth of ``matrix`` (a block-sparse one counts its
    blocks' every entry, a diagonal one its every stored diagonal)."""
    if isinstance(matrix, sp.dia_array):
        return int(max(-matrix.offsets.min(), 0)), int(max(matrix.offsets.max(), 0))
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


@njit(cache=True)
def _scaled_band(data, hgamma, kl, ku, ab):  # pragma: no cover - compiled
    """Rows kl.. of ``ab`` = -hγ ``data`` (LAPACK's rows of A), plus 1 on the diagonal's row."""
    for c in range(data.shape[1]):
        column, source = ab[kl:, c], data[:, c]
        for r in range(data.shape[0]):
            column[r] = -hgamma * source[r]
        ab[kl + ku, c] += 1.0


def band_storage(matrix: sp.sparray, hgamma: float, kl: int, ku: int,
                 dtype: type = np.float64, out: np.ndarray | None = None) -> np.ndarray:
    """``I - hγ A`` in LAPACK's layout for dgbtrf (sgbtrf: ``dtype`` float32): (2 kl + ku + 1,
    n) in Fortran order (into ``out`` if given, of that shape and dtype), entry (i, j) at row
    ``kl + ku + i - j`` of column j. The first kl rows are dgbtrf's room for fill, which it
    does not read ("need not be set", LAPACK's documentation): from :func:`near_product`'s band
    (a ``dia_array`` with offsets ku down to -kl, these rows already: one scaled copy) they are
    left unset; a C-ordered array would be copied by scipy's wrapper, 2.6 ms of 5 on the
    paper's rod."""
    n = matrix.shape[0]
    shape = (2 * kl + ku + 1, n)
    if isinstance(matrix, sp.dia_array) and np.array_equal(matrix.offsets,
                                                            np.arange(ku, -kl - 1, -1)):
        ab = np.empty(shape, dtype=dtype, order="F") if out is None else out
        _scaled_band(matrix.data, float(hgamma), kl, ku, ab)
        return ab
    ab = np.zeros(shape, order="F")  # LAPACK's order: dgbtrf copies no more
    if isinstance(matrix, sp.bsr_array):
        _fill(matrix.indptr.astype(np.int64), matrix.indices.astype(np.int64),
              np.ascontiguousarray(matrix.data), float(hgamma), kl, ku, ab)
    else:
        coo = sp.coo_array(matrix)
        np.add.at(ab, (kl + ku + coo.row - coo.col, coo.col), -hgamma * coo.data)
    ab[kl + ku] += 1.0
    if out is None:
        return ab.astype(dtype, order="F", copy=False)
    out[...] = ab
    return out
