"""The fluid as a linear operator (parastokes.mrs.operator): the numpy-assembled matrix equals the
compiled kernels to round-off, free space and wall ((1), (5) of docs/physics.md), one ε or one per
source, square and rectangular; the square matrix is symmetric."""

import numpy as np
import pytest

from parastokes import mrs
from parastokes.mrs.operator import StokesletOperator

RNG = np.random.default_rng(7)
SOURCES = RNG.uniform(0.05, 2.0, (40, 3))
TARGETS = RNG.uniform(0.05, 2.0, (25, 3))
EPS_EACH = RNG.uniform(0.1, 0.4, 40)


@pytest.mark.parametrize("wall", [False, True])
@pytest.mark.parametrize("eps", [0.27, EPS_EACH], ids=["one", "per-source"])
@pytest.mark.parametrize("targets", [TARGETS, None], ids=["rect", "square"])
def test_dense_equals_compiled_kernels(wall, eps, targets):
    op = StokesletOperator(targets, SOURCES, eps, 1.7, wall=wall)
    a = op.dense()
    m = 40 if targets is None else 25
    assert a.shape == op.shape == (3 * m, 120)
    for _ in range(3):
        f = RNG.normal(size=120)
        direct = mrs.velocity(
            SOURCES if targets is None else targets,
            SOURCES,
            f.reshape(-1, 3),
            epsilon=eps,
            mu=1.7,
            wall=wall,
        ).ravel()
        np.testing.assert_allclose(a @ f, direct, rtol=0, atol=1e-14 * np.abs(direct).max())
        np.testing.assert_allclose(op.matvec(f), direct, rtol=0, atol=1e-15 * np.abs(direct).max())
        np.testing.assert_allclose(op.as_linear_operator() @ f, op.matvec(f), rtol=1e-15)


def test_dense_matches_numpy_oracle_columns():
    """Column 3j + b is the oracle's velocity of a unit force e_b at source j (wall)."""
    op = StokesletOperator(TARGETS, SOURCES, 0.3, 1.1, wall=True)
    a = op.dense()
    for j, b in ((0, 0), (17, 2), (39, 1)):
        f = np.zeros((1, 3))
        f[0, b] = 1.0
        u = mrs.reference.velocity(TARGETS, SOURCES[j : j + 1], f, epsilon=0.3, mu=1.1, wall=True)
        np.testing.assert_allclose(a[:, 3 * j + b], u.ravel(), rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("wall", [False, True])
def test_square_matrix_symmetric(wall):
    a = StokesletOperator(None, SOURCES, 0.2, 1.0, wall=wall).dense()
    assert np.max(np.abs(a - a.T)) < 1e-14 * np.max(np.abs(a))


def test_tiles_do_not_change_the_result(monkeypatch):
    """Assembled a few targets at a time (tiny tiles) gives the same bits."""
    from parastokes.mrs import operator

    whole = StokesletOperator(TARGETS, SOURCES, EPS_EACH, 1.0, wall=True).dense()
    monkeypatch.setattr(operator, "_TILE_ENTRIES", 9 * 40 * 3)
    tiled = StokesletOperator(TARGETS, SOURCES, EPS_EACH, 1.0, wall=True).dense()
    np.testing.assert_array_equal(whole, tiled)


def test_bad_input_named():
    with pytest.raises(ValueError, match="targets"):
        StokesletOperator(np.ones((3, 2)), SOURCES, 0.1, 1.0)
    with pytest.raises(ValueError, match="epsilon"):
        StokesletOperator(None, SOURCES, np.ones(3), 1.0)
    with pytest.raises(ValueError, match="below the wall"):
        StokesletOperator(None, SOURCES - 1.0, 0.1, 1.0, wall=True)
    with pytest.raises(ValueError, match="3 per source"):
        StokesletOperator(None, SOURCES, 0.1, 1.0).matvec(np.ones(7))
