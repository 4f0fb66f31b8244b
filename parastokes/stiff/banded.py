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

from .local import coefficients, near_mobility, pair_reach, support, taper

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
def _row_extents(k_ptr, k_idx):  # pragma: no cover - compiled
    """``(first, last)``: the first and last block column of each block row of ``k`` (an empty
    row j of n: first = j + n, last = j - n, so that no pair (i, j) reaches a column through
    it: i - first[j] and last[j] - i are negative)."""
    n = len(k_ptr) - 1
    first, last = np.arange(n, 2 * n), np.arange(-n, 0)
    for j in range(n):
        if k_ptr[j + 1] > k_ptr[j]:
            first[j] = last[j] = k_idx[k_ptr[j]]
        for q in range(k_ptr[j], k_ptr[j + 1]):
            first[j], last[j] = min(first[j], k_idx[q]), max(last[j], k_idx[q])
    return first, last


def _lane(size: int) -> int:
    """The columns a block of K takes in the product's strips (:func:`_strips`): 6 padded to
    8, 3 to 4, so that every block starts a whole vector of doubles (AVX-512's 8, AVX's 4)."""
    return 8 if size > 4 else 4


@njit(cache=True)
def _strips(k_ptr, k_idx, k_blk, k_lo, blocks, lane, pad):  # pragma: no cover - compiled
    """The block rows of ``k`` as dense strips, component-major: ``out[j, c, lane (l - j +
    k_lo) + b]`` = entry (c, b) of block (j, l), ``blocks`` blocks per strip, each padded with
    zeros to ``lane`` columns, then ``pad`` strips of zeros (``out[-m]``, m <= pad, is one of
    them too)."""
    rows, cols = k_blk.shape[1], k_blk.shape[2]
    out = np.zeros((len(k_ptr) - 1 + pad, rows, blocks * lane))
    for j in range(len(k_ptr) - 1):
        for q in range(k_ptr[j], k_ptr[j + 1]):
            first = (k_idx[q] - j + k_lo) * lane
            for c in range(rows):
                for b in range(cols):
                    out[j, c, first + b] = k_blk[q, c, b]
    return out


@njit(cache=True, fastmath=True, error_model="numpy")
def _near_band(pad, eps, cutoff, reach, viscosity, angular, strips, lp, k_lo, lane, kl, ku,
               data):  # pragma: no cover - compiled
    """``data`` = M K in LAPACK's band layout (entry (r, c) at ``data[ku + r - c, c]``). Per
    point i, over the window of points j = i - ``lp`` .. i + ``lp`` (``pad``: rows x, y, z,
    point j at column ``lp`` + j, zeros for the padding past the ends, whose strips are zero
    too, so that they add zeros): first the scalars of
    :func:`.local.coefficients` times :func:`.local.taper` of every j in one loop (it
    vectorizes; all zero beyond ``reach``, :func:`.local.support`), then each pair multiplies
    K's strip j (:func:`_strips`, blocks of ``lane`` columns, padded by ``lp`` strips) into
    the block row of i, held
    component-major (``row[a, lane B + b]``, block B from point i - lp - ``k_lo``), then
    written out. M's block is never formed: with r = X_i - X_j and a strip column's force
    rows k_f and torque rows k_n (``angular``), the velocity rows gain
    diag k_f + i3 r (r·k_f) - i3 r × k_n and the angular ones -q r × k_f + p1 k_n + p2 r (r·k_n)
    (a loop over the strip's columns, unsigned: it vectorizes)."""
    size = 6 if angular else 3
    strip = np.uint64(strips.shape[2])
    window = 2 * lp + 1
    width = window + strips.shape[2] // lane - 1  # the blocks of a row's window
    depth, e2, reach2 = kl + ku + 1, eps * eps, reach * reach
    scalars = np.empty((8, window))
    row = np.empty((size, lane * width))
    px, py, pz = pad[0], pad[1], pad[2]
    cx, cy, cz, cd, ci, cq, c1, c2 = (scalars[0], scalars[1], scalars[2], scalars[3],
                                      scalars[4], scalars[5], scalars[6], scalars[7])
    for i in range(data.shape[1] // size):
        xi, yi, zi = px[lp + i], py[lp + i], pz[lp + i]
        for w in range(window):  # point j = i - lp + w, column i + w of pad
            x, y, z = xi - px[i + w], yi - py[i + w], zi - pz[i + w]
            r2 = x * x + y * y + z * z
            diag, i3, q, p1, p2 = coefficients(r2, e2)
            scale = taper(r2, cutoff, viscosity) if r2 <= reach2 else 0.0
            cx[w], cy[w], cz[w] = x, y, z
            cd[w], ci[w], cq[w] = diag * scale, i3 * scale, q * scale
            c1[w], c2[w] = p1 * scale, p2 * scale
        row[:] = 0.0
        o0, o1, o2 = row[0], row[1], row[2]
        o3, o4, o5 = row[3 % size], row[4 % size], row[5 % size]
        for w in range(window):
            i3 = ci[w]
            if i3 == 0.0:  # no pair: beyond the reach
                continue
            x, y, z = cx[w], cy[w], cz[w]
            diag, q, p1, p2 = cd[w], cq[w], c1[w], c2[w]
            ux, uy, uz = i3 * x, i3 * y, i3 * z
            first = np.uint64(w * lane)
            k = strips[i - lp + w]  # past either end: a strip of zeros
            f0, f1, f2 = k[0], k[1], k[2]
            if angular:
                vx, vy, vz = q * x, q * y, q * z
                wx, wy, wz = p2 * x, p2 * y, p2 * z
                n0, n1, n2 = k[3], k[4], k[5]
                for e in range(np.uint64(0), strip):
                    a0, a1, a2 = f0[e], f1[e], f2[e]
                    b0, b1, b2 = n0[e], n1[e], n2[e]
                    rf = ux * a0 + uy * a1 + uz * a2
                    rn = wx * b0 + wy * b1 + wz * b2
                    o0[first + e] += diag * a0 + rf * x + uz * b1 - uy * b2
                    o1[first + e] += diag * a1 + rf * y + ux * b2 - uz * b0
                    o2[first + e] += diag * a2 + rf * z + uy * b0 - ux * b1
                    o3[first + e] += p1 * b0 + rn * x + vz * a1 - vy * a2
                    o4[first + e] += p1 * b1 + rn * y + vx * a2 - vz * a0
                    o5[first + e] += p1 * b2 + rn * z + vy * a0 - vx * a1
            else:
                for e in range(np.uint64(0), strip):
                    a0, a1, a2 = f0[e], f1[e], f2[e]
                    rf = ux * a0 + uy * a1 + uz * a2
                    o0[first + e] += diag * a0 + rf * x
                    o1[first + e] += diag * a1 + rf * y
                    o2[first + e] += diag * a2 + rf * z
        # out to the band: column col = col0 + size B + b, rows r = size i + a within it
        col0 = (i - lp - k_lo) * size
        top0 = ku + i * size - col0  # data's row of (size i, col0)
        for block in range(width):
            for b in range(size):
                col, top = col0 + block * size + b, top0 - block * size - b
                if col < 0 or col >= data.shape[1]:
                    continue
                source = block * lane + b
                if top >= 0 and top + size <= depth:  # the whole block row: no clipping
                    for a in range(size):
                        data[top + a, col] = row[a, source]
                else:
                    for a in range(max(0, -top), min(size, depth - top)):
                        data[top + a, col] = row[a, source]


def near_product(points: np.ndarray, epsilon: float, viscosity: float, angular: bool,
                 cutoff: float, k: sp.bsr_array) -> sp.dia_array | sp.bsr_array:
    """``A = M_near K``: the near mobility of :func:`.local.near_mobility` (the same arguments)
    times ``k`` (block-sparse, square, blocks of V x V, V = 6 with ``angular``, else 3). When
    the product's band is :func:`narrow` (a rod's or chain's points in order), one compiled
    pass writes it straight into LAPACK's band layout, never storing M nor listing the pairs
    (:func:`.local.pair_reach` bounds them): a ``dia_array`` whose ``data`` (kl + ku + 1, n),
    Fortran order, holds entry (i, j) at row ``ku + i - j`` of column j (offsets ku down to
    -kl), as :class:`.solve.Factorization` takes it. Otherwise (a vesicle, a rod curled onto
    itself) M's blocks and :func:`block_product`."""
    points = np.ascontiguousarray(points, dtype=float)
    size = 6 if angular else 3
    if k.blocksize != (size, size) or k.shape != (len(points) * size,) * 2:
        raise ValueError(f"near_product: K of shape {k.shape} in blocks {k.blocksize}; expected "
                         f"{(len(points) * size,) * 2} in blocks {(size, size)}")
    k_ptr, k_idx = k.indptr.astype(np.int64), k.indices.astype(np.int64)
    first, last = _row_extents(k_ptr, k_idx)
    reach = support(cutoff)
    lp, below, above = pair_reach(points, reach, first, last)
    kl, ku = max(below * size + size - 1, 0), max(above * size + size - 1, 0)
    n = len(points) * size
    if not narrow(kl, ku, n):
        return block_product(near_mobility(points, epsilon, viscosity, angular, cutoff), k)
    index = np.arange(len(points))
    k_lo = int(max((index - first).max(initial=0), 0))
    k_hi = int(max((last - index).max(initial=0), 0))
    lane = _lane(size)
    strips = _strips(k_ptr, k_idx, np.ascontiguousarray(k.data), k_lo, k_lo + k_hi + 1, lane,
                     lp)
    pad = np.zeros((3, len(points) + 2 * lp))
    pad[:, lp:lp + len(points)] = points.T
    data = np.zeros((kl + ku + 1, n), order="F")
    _near_band(pad, float(epsilon), float(cutoff), reach, float(viscosity), bool(angular),
               strips, lp, k_lo, lane, kl, ku, data)
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
    """Rows kl.. of ``ab`` = -hγ ``data`` (LAPACK's rows of A), zeros below them down to row
    2 kl + ku (the diagonals of a storage wider than ``data``'s band), plus 1 on the
    diagonal's row."""
    for c in range(data.shape[1]):
        column, source = ab[kl:, c], data[:, c]
        for r in range(data.shape[0]):
            column[r] = -hgamma * source[r]
        for r in range(data.shape[0], kl + ku + 1):
            column[r] = 0.0
        ab[kl + ku, c] += 1.0


def band_storage(matrix: sp.sparray, hgamma: float, kl: int, ku: int,
                 dtype: type = np.float64, out: np.ndarray | None = None) -> np.ndarray:
    """``I - hγ A`` in LAPACK's layout for dgbtrf (sgbtrf: ``dtype`` float32): (2 kl + ku + 1,
    n) in Fortran order (into ``out`` if given, of that shape and dtype), entry (i, j) at row
    ``kl + ku + i - j`` of column j; ``kl`` may exceed A's lower bandwidth (zero diagonals:
    :func:`.solve.elimination_width`). The first kl rows are dgbtrf's room for fill, which it
    does not read ("need not be set", LAPACK's documentation): from :func:`near_product`'s band
    (a ``dia_array`` with offsets ku down to -kl or fewer, these rows already: one scaled
    copy) they are left unset; a C-ordered array would be copied by scipy's wrapper, 2.6 ms of
    5 on the paper's rod."""
    n = matrix.shape[0]
    shape = (2 * kl + ku + 1, n)
    if isinstance(matrix, sp.dia_array) and len(matrix.offsets) <= kl + ku + 1 and (
            np.array_equal(matrix.offsets, np.arange(ku, ku - len(matrix.offsets), -1))):
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
