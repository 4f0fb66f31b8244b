"""The fused product A = M_near K of round 5's fourth session (parastokes.stiff.banded,
.local): the pairs' reach without a pair list, K's rows' extents, and the windowed product
against the stored near mobility times K on layouts that reach every branch of the pass (a
window with gaps, the padding at both ends near the origin, asymmetric and empty rows of K,
both block sizes)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from parastokes import models
from parastokes.stiff import banded, jacobian, local, solve


def _brute_reach(points, cutoff, first, last):
    """pair_reach from all n² distances."""
    n = len(points)
    distance2 = ((points[:, None] - points[None]) ** 2).sum(axis=2)
    most, below, above = 0, -n, -n
    for i in range(n):
        for j in range(n):
            if distance2[i, j] <= cutoff * cutoff:
                most = max(most, abs(i - j))
                below, above = max(below, i - first[j]), max(above, last[j] - i)
    return most, below, above


def test_pair_reach_is_every_pair_within_the_cutoff_and_no_other():
    """Points along x 1 apart with a cutoff of exactly 2: the pair two apart counts (distance
    = cutoff, as in sorted_pairs), the pair three apart does not; a point moved next to a far
    one in index (a rod folded onto itself) reaches that far."""
    points = np.stack([np.arange(10.0), np.zeros(10), np.zeros(10)], axis=1)
    index = np.arange(10)
    assert local.pair_reach(points, 2.0, index, index) == (2, 2, 2)
    assert local.pair_reach(points, 2.0 - 1e-12, index, index) == (1, 1, 1)
    folded = points.copy()
    folded[9] = [0.0, 0.5, 0.0]  # within 2 of points 0..1: |i - j| = 9
    assert local.pair_reach(folded, 2.0, index, index) == (9, 9, 9)


@pytest.mark.parametrize("seed", [0, 1])
def test_pair_reach_with_rows_of_k_is_the_brute_force_one(seed):
    """Random K rows (first, last) around their points, empty rows among them (first = j + n,
    last = j - n, as banded._row_extents gives them), on a jittered line: the same (most,
    below, above) as the n² count; with every row empty no column is reached (negative)."""
    rng = np.random.default_rng(seed)
    n = 40
    points = np.stack([np.arange(n) * 0.5 + 0.1 * rng.standard_normal(n),
                       0.2 * rng.standard_normal(n), np.zeros(n)], axis=1)
    index = np.arange(n)
    first, last = index - rng.integers(0, 3, n), index + rng.integers(0, 4, n)
    empty = rng.uniform(size=n) < 0.2
    first[empty], last[empty] = index[empty] + n, index[empty] - n
    assert local.pair_reach(points, 1.3, first, last) == _brute_reach(points, 1.3, first, last)
    got = local.pair_reach(points, 1.3, index + n, index - n)
    assert got == _brute_reach(points, 1.3, index + n, index - n) and max(got[1:]) < 0


def test_row_extents_are_the_first_and_last_block_columns():
    """K's block rows (0: columns 0 and 2; 1: empty; 2: column 1 alone): first 0, 4, 1 and
    last 2, -2, 1 (an empty row j of n: j + n and j - n, beyond any pair's reach)."""
    k = sp.bsr_array((np.ones((3, 2, 2)), np.array([0, 2, 1]), np.array([0, 2, 2, 3])),
                     shape=(6, 6))
    first, last = banded._row_extents(k.indptr.astype(np.int64), k.indices.astype(np.int64))
    assert list(first) == [0, 4, 1] and list(last) == [2, -2, 1]


def _banded_k(rng, n, size, below, above, empty=()):
    """A random block-banded K: block row j spans j - below[j] .. j + above[j] (clipped),
    rows in ``empty`` have no block."""
    dense = np.zeros((n * size, n * size))
    for j in range(n):
        if j in empty:
            continue
        for col in range(max(0, j - below[j]), min(n, j + above[j] + 1)):
            dense[j * size:(j + 1) * size, col * size:(col + 1) * size] = \
                rng.standard_normal((size, size))
    return sp.bsr_array(dense, blocksize=(size, size)), dense


@pytest.mark.parametrize(("angular", "layout"), [
    (True, "line from the origin"), (False, "line from the origin"),
    (True, "line to the origin"), (True, "zigzag"), (False, "zigzag")])
def test_fused_product_is_the_stored_mobility_times_k(angular, layout):
    """The windowed pass against M_near (stored, pair by pair) @ K, to round-off in every band
    entry, with the reference's band, on: a line from and one to the origin (the window's
    padding past either end sits at the origin, within the cutoff of the end points: only its
    zero strips keep it out) and a zigzag whose pairs i, i + 2 are within the support but
    i, i + 1 are not, 0.995 of the cutoff apart, where the taper is below 2⁻²⁴ (gaps in the
    window); K with rows reaching 0-2 blocks below and 0-3 above, and empty rows."""
    rng = np.random.default_rng(3)
    n, size = 120, 6 if angular else 3
    if layout == "zigzag":
        height = np.sqrt(0.995 ** 2 - 0.45 ** 2)  # neighbours 0.995 apart
        points = np.stack([0.45 * np.arange(n), height * (np.arange(n) % 2), np.zeros(n)],
                          axis=1)
    else:
        points = np.stack([0.3 * np.arange(n), 0.05 * rng.standard_normal(n),
                           np.zeros(n)], axis=1)
        points[:, 0] -= points[0, 0]  # the first point at the origin (within 0.05)
        if layout == "line to the origin":
            points = points[::-1].copy()
    cutoff = 1.0
    k, dk = _banded_k(rng, n, size, rng.integers(0, 3, n), rng.integers(0, 4, n),
                      empty=(4, 17, 118))
    a = banded.near_product(points, 0.4, 1.7, angular, cutoff, k)
    m = local.near_mobility(points, 0.4, 1.7, angular, cutoff).toarray()
    expected = m @ dk
    assert isinstance(a, sp.dia_array) and a.data.flags.f_contiguous
    kl, ku = banded.bandwidth(sp.coo_array(expected))
    assert banded.bandwidth(a) == (kl, ku)
    assert np.abs(a.toarray() - expected).max() < 1e-13 * np.abs(expected).max()
    if layout == "zigzag":  # the gaps: i, i + 1 are no pair (beyond the support), i, i + 2 are
        distance = np.linalg.norm(points[1:] - points[:-1], axis=1)
        assert local.support(cutoff) < distance.min() <= distance.max() < cutoff
        assert np.linalg.norm(points[2] - points[0]) < local.support(cutoff)


def test_coefficients_are_the_kernels_scalars():
    """The scalars through a square root, against the powers of docs/kernels.md (1)-(4)."""
    r2, e2 = np.array([0.0, 0.3, 2.0, 9.0]), 0.49
    r_eps = r2 + e2
    for value, expected in zip(
            zip(*(local.coefficients(r, e2) for r in r2), strict=True),
            ((r2 + 2 * e2) * r_eps ** -1.5, r_eps ** -1.5, 0.5 * (2 * r2 + 5 * e2) * r_eps ** -2.5,
             -0.5 * (r2 - 2 * e2) * r_eps ** -2.5, 1.5 * r_eps ** -2.5), strict=True):
        np.testing.assert_allclose(value, expected, rtol=1e-15, atol=0)


def test_the_support_is_where_the_taper_falls_below_single_precision():
    """support(c) is the bisected root of (1 - q)⁴ (4q + 1) = 2⁻²⁴ times c: the taper (over
    1/(8π μ)) is at least NEGLIGIBLE_TAPER a relative 1e-12 within it, below it as far out."""
    assert local.NEGLIGIBLE_TAPER == 2.0 ** -24
    for cutoff in (1.0, 3.0, 0.7):
        reach = local.support(cutoff)
        assert 0.98 * cutoff < reach < cutoff
        within, beyond = (local.taper(r * r, cutoff, 1.0) * 8 * np.pi
                          for r in (reach * (1 - 1e-12), reach * (1 + 1e-12)))
        assert within >= local.NEGLIGIBLE_TAPER > beyond


def test_pairs_at_the_cutoff_leave_the_straight_rods_band():
    """Points 0.2 apart along a line with a cutoff of 3 (15 spacings, as the paper's rod at ε =
    5Δs and 3ε): the pairs 15 apart lie at the cutoff (a taper of 0 up to round-off) and are
    left out, 14 apart (taper 9e-5) kept: with a tridiagonal K, A's band is (14 + 1) 6 + 5 = 95
    rates, and the near mobility holds no pair 15 apart."""
    n, size = 120, 6
    points = np.stack([0.2 * np.arange(n), np.zeros(n), np.zeros(n)], axis=1)
    points[:, 0] += 1e-15 * np.random.default_rng(4).standard_normal(n)  # round-off either way
    rng = np.random.default_rng(5)
    k, _ = _banded_k(rng, n, size, np.ones(n, dtype=int), np.ones(n, dtype=int))
    a = banded.near_product(points, 1.0, 1.0, True, 3.0, k)
    assert banded.bandwidth(a) == (95, 95)
    m = local.near_mobility(points, 1.0, 1.0, True, 3.0)
    assert banded.bandwidth(m) == (14 * size + size - 1,) * 2


def test_the_elimination_width_rounds_up_to_lapacks_block_by_at_most_four():
    """95 -> 96 and 92 -> 96 (4 more), 91 stays (5), 96 and 101 stay, 30 -> 32, 0 stays."""
    assert [solve.elimination_width(kl) for kl in (95, 92, 91, 96, 101, 30, 0)] == [
        96, 96, 91, 96, 101, 32, 0]


def test_a_factorization_of_zero_diagonals_more_solves_the_same_system():
    """A rod of 161 points at ε = 5Δs (the paper's band, kl = ku = 95) factorized with kl = 96
    (its storage's extra diagonal zero, though the spare array it reuses was filled with NaN):
    the solve of I - hγA against a dense solve in double, to single precision's accuracy."""
    rod = models.rod_swimmer(n_points=161, length=32.0, n_threads=1)  # ε = 5Δs, as the paper's
    x = rod.initial_state()
    a = jacobian.local_jacobian(rod, 0.0, x, 6 * len(x))
    kl = banded.bandwidth(a)[0]
    assert kl == 95
    assert kl % solve.GBTRF_BLOCK and solve.elimination_width(kl) > kl
    for _ in range(2):  # the second takes the first's factors' memory: fill it with NaN
        lu = solve.Factorization(a, 1e-4, 0.0)
        assert lu._band[2] == solve.elimination_width(kl)
        lu._band[0][:] = np.nan
        del lu
    lu = solve.Factorization(a, 1e-4, 0.0)
    dense = np.eye(a.shape[0]) - 1e-4 * a.toarray()
    rhs = np.random.default_rng(8).standard_normal(a.shape[0])
    expected = np.linalg.solve(dense, rhs)
    assert np.abs(lu.solve(rhs) - expected).max() < 1e-5 * np.abs(expected).max()
