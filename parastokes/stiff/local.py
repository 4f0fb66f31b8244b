"""The regularized Stokeslet mobility restricted to near pairs: a sparse matrix (docs/stiff.md).

The stiff modes of a body are short (a rod's bending modes of a few Δs, a vesicle's spring
modes of one edge), and the fluid couples them through the kernels within a few ε of each
point. :func:`near_mobility` keeps the pairs of points closer than ``cutoff`` whose taper is
not negligible (:func:`support`; a compiled sort
and sweep, :func:`sorted_pairs`) and writes their blocks in free space, from the formulas of
:mod:`parastokes.mrs.reference` ((1)-(4) of docs/kernels.md; the torque blob ψ_ε of the
default variant): force -> velocity (Stokeslet), torque -> velocity (rotlet), force -> angular
velocity (½ curl of the Stokeslet), torque -> angular velocity (potential dipole). The wall's
images and the far pairs are left out: the matrix is the approximate Jacobian of a W-method,
whose order does not depend on it.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import scipy.sparse as sp
from numba import njit

__all__ = ["NEGLIGIBLE_TAPER", "coefficients", "near_mobility", "pair_block", "pair_blocks",
           "pair_reach", "sorted_pairs", "support", "taper"]

_EIGHT_PI = 8.0 * np.pi


@njit(cache=True, error_model="numpy", inline="always")
def coefficients(r2, e2):  # pragma: no cover - compiled
    """The scalars of 8π μ × a pair's mobility block at squared distance ``r2``, ε² = ``e2``:
    ``(diag, i3, q, p1, p2)`` of the Stokeslet diag I + i3 r rᵀ, the rotlet -i3 [r]ₓ, the
    curl -q [r]ₓ and the dipole p1 I + p2 r rᵀ (:func:`pair_blocks`)."""
    s = r2 + e2
    i3 = 1.0 / (s * math.sqrt(s))  # not s ** -1.5: a square root vectorizes, a power does not
    i5 = i3 / s
    return ((r2 + 2.0 * e2) * i3, i3, 0.5 * (2.0 * r2 + 5.0 * e2) * i5,
            -0.5 * (r2 - 2.0 * e2) * i5,  # -1/4 of 8π × (4)'s p1
            1.5 * i5)                      # -1/4 of 8π × (4)'s p2


@njit(cache=True, error_model="numpy", inline="always")
def pair_block(x, y, z, e2, angular, out):  # pragma: no cover - compiled
    """8π μ × the mobility block of the pair at separation (x, y, z) into ``out`` (V, V), with
    ε² = ``e2`` (:func:`coefficients`)."""
    diag, i3, q, p1, p2 = coefficients(x * x + y * y + z * z, e2)
    v = (x, y, z)
    for a in range(3):
        for b in range(3):
            out[a, b] = i3 * v[a] * v[b] + (diag if a == b else 0.0)
    if angular:
        # [r]_x rows: (0, -z, y), (z, 0, -x), (-y, x, 0)
        cross = ((0.0, -z, y), (z, 0.0, -x), (-y, x, 0.0))
        for a in range(3):
            for b in range(3):
                out[a, 3 + b] = -i3 * cross[a][b]
                out[3 + a, b] = -q * cross[a][b]
                out[3 + a, 3 + b] = p2 * v[a] * v[b] + (p1 if a == b else 0.0)


@njit(cache=True, error_model="numpy", inline="always")
def taper(r2, cutoff, viscosity):  # pragma: no cover - compiled
    """The factor of a pair at squared distance ``r2`` in the near mobility: Wendland's
    compactly supported C² function (1 - q)⁴ (4q + 1) of q = r / ``cutoff`` (0 from q = 1 on),
    positive definite in three dimensions (Wendland, Adv. Comput. Math. 4, 1995), so the
    mobility tapered by it stays positive semi-definite (Schur's product theorem), over 8π μ."""
    q = min(math.sqrt(r2) / cutoff, 1.0)
    s = 1.0 - q
    return s * s * s * s * (4.0 * q + 1.0) / (_EIGHT_PI * viscosity)


#: The taper (:func:`taper` times 8π μ) below which a pair is left out of the near mobility:
#: single precision's unit round-off, the precision in which a step's banded elimination
#: already rounds A (:data:`.solve.BAND_PRECISION`). On a straight rod whose cutoff is 15
#: spacings the pairs 15 points apart lie at the cutoff to round-off (a taper of 1e-59): counted,
#: they widened A's band from 95 to 101 rates (docs/benchmarks.md, "Round 5, fourth session").
NEGLIGIBLE_TAPER = 2.0 ** -24


@functools.cache
def support(cutoff: float) -> float:
    """The distance within ``cutoff`` beyond which :func:`taper` (times 8π μ) is below
    :data:`NEGLIGIBLE_TAPER` (about 0.9895 ``cutoff``): the near mobility's pairs are those at
    most this far apart. (1 - q)⁴ (4q + 1) decreases on [0, 1]: bisection to double's
    round-off (remembered per cutoff)."""
    low, high = 0.0, 1.0
    for _ in range(64):
        middle = 0.5 * (low + high)
        if (1.0 - middle) ** 4 * (4.0 * middle + 1.0) >= NEGLIGIBLE_TAPER:
            low = middle
        else:
            high = middle
    return cutoff * low


@njit(cache=True, error_model="numpy")
def _pair_blocks(r, eps, angular, cutoff, viscosity, out):  # pragma: no cover - compiled
    e2 = eps * eps
    for p in range(r.shape[0]):
        x, y, z = r[p, 0], r[p, 1], r[p, 2]
        pair_block(x, y, z, e2, angular, out[p])
        if cutoff > 0.0:
            scale = taper(x * x + y * y + z * z, cutoff, viscosity)
            for a in range(out.shape[1]):
                for b in range(out.shape[2]):
                    out[p, a, b] *= scale


def pair_blocks(r: np.ndarray, eps: float, angular: bool) -> np.ndarray:
    """8π μ × the mobility blocks of pairs with separations ``r`` (P, 3): (P, 3, 3) force ->
    velocity, or with ``angular`` (P, 6, 6) of ``[u, w]`` from ``[f, n]``: the Stokeslet
    (r² + 2ε²)/r_ε³ I + r rᵀ/r_ε³, the rotlet -[r]ₓ/r_ε³, ½ the Stokeslet's curl
    -½ (2r² + 5ε²)/r_ε⁵ [r]ₓ and the potential dipole -¼ (p₁ I + p₂ r rᵀ)."""
    r = np.ascontiguousarray(r, dtype=float)
    size = 6 if angular else 3
    out = np.empty((len(r), size, size))
    _pair_blocks(r, float(eps), bool(angular), 0.0, 1.0, out)
    return out


@njit(cache=True)
def _swept(points, cutoff, order, axis):  # pragma: no cover - compiled
    """The pairs of distinct points at most ``cutoff`` apart, each once, as two rows ``(i, j)``
    (2, pairs): sort and sweep, the points in ``order`` along ``axis``, each against those that
    follow within ``cutoff`` along it."""
    n = len(points)
    c2 = cutoff * cutoff
    out = np.empty((2, 0), dtype=np.int64)
    for counting in (True, False):  # a pass that counts, one that fills
        count = 0
        for a in range(n):
            i = order[a]
            for b in range(a + 1, n):
                j = order[b]
                if points[j, axis] - points[i, axis] > cutoff:
                    break
                d0 = points[i, 0] - points[j, 0]
                d1 = points[i, 1] - points[j, 1]
                d2 = points[i, 2] - points[j, 2]
                if d0 * d0 + d1 * d1 + d2 * d2 > c2:
                    continue
                if not counting:
                    out[0, count], out[1, count] = i, j
                count += 1
        if counting:
            out = np.empty((2, count), dtype=np.int64)
    return out[:, :count]


@njit(cache=True)
def _sweep(points, cutoff, order, axis):  # pragma: no cover - compiled
    """:func:`sorted_pairs` from :func:`_swept`'s pairs and the self pairs: counted, filled,
    sorted per row."""
    n = len(points)
    pairs = _swept(points, cutoff, order, axis)
    indptr = np.zeros(n + 1, dtype=np.int64)
    indptr[1:] = 1  # self pairs
    for p in range(pairs.shape[1]):
        indptr[pairs[0, p] + 1] += 1
        indptr[pairs[1, p] + 1] += 1
    indptr[1:] = np.cumsum(indptr[1:])
    source = np.empty(indptr[n], dtype=np.int64)
    fill = indptr[:n].copy()
    for i in range(n):
        source[fill[i]] = i
        fill[i] += 1
    for p in range(pairs.shape[1]):
        i, j = pairs[0, p], pairs[1, p]
        source[fill[i]], source[fill[j]] = j, i
        fill[i] += 1
        fill[j] += 1
    for i in range(n):
        source[indptr[i]:indptr[i + 1]].sort()
    return indptr, source


def _sweep_order(points: np.ndarray) -> tuple[np.ndarray, int]:
    """The sweep's order: the points sorted along the axis of their largest extent (a rod's or
    chain's length), and that axis."""
    axis = int(np.argmax(np.ptp(points, axis=0))) if len(points) else 0
    return np.argsort(points[:, axis], kind="stable"), axis


def sorted_pairs(points: np.ndarray, cutoff: float) -> tuple[np.ndarray, np.ndarray]:
    """Every ordered pair of ``points`` at most ``cutoff`` apart, self pairs included, as
    compressed rows: ``(indptr, source)`` with the sources of target ``i`` in
    ``source[indptr[i]:indptr[i + 1]]``, ascending; compiled (:func:`_sweep`, along the axis
    of the points' largest extent: a rod's or chain's length)."""
    points = np.ascontiguousarray(points, dtype=float)
    order, axis = _sweep_order(points)
    return _sweep(points, float(cutoff), order, axis)


@njit(cache=True)
def _reach_sweep(points, cutoff, order, axis, first, last):  # pragma: no cover - compiled
    """:func:`pair_reach` from :func:`_swept`'s pairs."""
    n = len(points)
    pairs = _swept(points, cutoff, order, axis)
    most, below, above = 0, -n, -n
    for i in range(n):  # self pairs
        below, above = max(below, i - first[i]), max(above, last[i] - i)
    for p in range(pairs.shape[1]):
        i, j = pairs[0, p], pairs[1, p]
        most = max(most, abs(i - j))
        below = max(below, i - first[j], j - first[i])
        above = max(above, last[j] - i, last[i] - j)
    return most, below, above


def pair_reach(points: np.ndarray, cutoff: float, first: np.ndarray, last: np.ndarray
               ) -> tuple[int, int, int]:
    """How far the pairs of ``points`` at most ``cutoff`` apart (:func:`sorted_pairs`'s, none
    stored) reach along the points' order: ``(most, below, above)``, the largest ``|i - j|``
    of a pair (i, j) and, for the product of the near mobility with a matrix whose block row j
    spans the block columns ``first[j]..last[j]`` (an empty row: ``first[j] = j + n``,
    ``last[j] = j - n``), the most block columns that row i of the product reaches below and
    above i (negative: none)."""
    points = np.ascontiguousarray(points, dtype=float)
    order, axis = _sweep_order(points)
    most, below, above = _reach_sweep(points, float(cutoff), order, axis,
                                      np.asarray(first, dtype=np.int64),
                                      np.asarray(last, dtype=np.int64))
    return int(most), int(below), int(above)


def near_mobility(points: np.ndarray, epsilon: float, viscosity: float, angular: bool,
                  cutoff: float) -> sp.bsr_array:
    """The free-space mobility of the pairs within :func:`support` of ``cutoff`` (a taper of at
    least :data:`NEGLIGIBLE_TAPER`), tapered by :func:`taper` (support ``cutoff``):
    (n V, n V) sparse in blocks of V x V, V = 6 (``[u, w]`` from ``[f, n]``) with ``angular``,
    else 3, point-major rows and columns."""
    points = np.ascontiguousarray(points, dtype=float)
    indptr, source = sorted_pairs(points, support(cutoff))
    target = np.repeat(np.arange(len(points)), np.diff(indptr))
    n, v = len(points), 6 if angular else 3
    blocks = np.empty((len(source), v, v))
    _pair_blocks(points[target] - points[source], float(epsilon), bool(angular), float(cutoff),
                 float(viscosity), blocks)
    return sp.bsr_array((blocks, source, indptr), shape=(n * v, n * v))
