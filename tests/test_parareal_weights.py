"""Lagrange (eqs. 17, 22, 25) and Richardson (eqs. 26-27, Table 1) extrapolation weights."""

import itertools

import numpy as np
import pytest

from parastokes import integrate, parareal
from parastokes.parareal.weights import step_weights

RNG = np.random.default_rng(4)


@pytest.mark.parametrize("nodes", [[1.03, 1.04, 1.05, 1.06], [0.2, 0.5, 0.7], [1.5]])
def test_lagrange_exact_below_degree_n(nodes):
    theta0 = 1.0
    w = parareal.lagrange_weights(theta0, nodes)
    for degree in range(len(nodes)):
        poly = np.polynomial.Polynomial(RNG.normal(size=degree + 1))
        assert np.isclose(w @ poly(np.array(nodes)), poly(theta0), rtol=1e-9, atol=1e-9)
    # degree N is not reproduced: the error term of eq. 16 is nonzero.
    poly = np.polynomial.Polynomial([0.0] * len(nodes) + [1.0])
    assert abs(w @ poly(np.array(nodes)) - poly(theta0)) > 1e-8


def test_lagrange_matches_eq17_by_hand():
    w = parareal.lagrange_weights(0.0, [1.0, 2.0])
    # w1 = (0 - 2) / (1 - 2) = 2, w2 = (0 - 1) / (2 - 1) = -1
    np.testing.assert_allclose(w, [2.0, -1.0])


@pytest.mark.parametrize(
    ("theta0", "nodes"),
    [
        ((1.0, 2.0), ([1.1, 1.2, 1.4], [2.5, 2.6])),
        ((1.0, 0.0, -1.0), ([1.1, 1.3], [-0.2, -0.1], [0.5, 0.7, 0.8])),
    ],
)
def test_lagrange_tensor_product_exact(theta0, nodes):
    w = parareal.lagrange_weights(theta0, nodes)
    assert w.shape == tuple(len(n) for n in nodes)
    # a polynomial of degree < N_i in every parameter i, with mixed terms
    degrees = [len(n) - 1 for n in nodes]
    coeffs = RNG.normal(size=[d + 1 for d in degrees])

    def poly(theta):
        return sum(
            coeffs[idx] * np.prod([t**e for t, e in zip(theta, idx, strict=True)])
            for idx in np.ndindex(coeffs.shape)
        )

    combos = list(itertools.product(*nodes))
    approx = sum(wj * poly(c) for wj, c in zip(w.ravel(), combos, strict=True))
    assert np.isclose(approx, poly(theta0), rtol=1e-9, atol=1e-9)
    # and it is the product of the one-parameter weights (eq. 25)
    one = [parareal.lagrange_weights(t, n) for t, n in zip(theta0, nodes, strict=True)]
    assert np.isclose(w.ravel()[-1], np.prod([o[-1] for o in one]))


@pytest.mark.parametrize(
    ("theta0", "nodes", "rule"),
    [
        (1.0, [1.05, 1.04], "strictly increasing"),
        (1.0, [1.1, 1.1], "strictly increasing"),
        (1.05, [1.03, 1.06], "outside"),
        (1.03, [1.03, 1.06], "outside"),
        (1.0, [], "non-empty"),
        ((1.0, 2.0), ([1.1], [1.0, 3.0]), "outside"),
    ],
)
def test_lagrange_rejects_bad_nodes(theta0, nodes, rule):
    with pytest.raises(ValueError, match=rule):
        parareal.lagrange_weights(theta0, nodes)


def _error_terms(v, steps, order, count):
    """sum_q v_q h_q^(order + j) / h_0^(order + j) for j = 0..count-1."""
    h = np.asarray(steps) / steps[0]
    return np.array([v @ h ** (order + j) for j in range(count)])


@pytest.mark.parametrize("order", [1, 2, 4])
@pytest.mark.parametrize("m", [0, 1, 2, 3])
@pytest.mark.parametrize("r", [0.5, 0.83])
def test_richardson_weights_cancel_error_terms(m, r, order):
    v = parareal.richardson_weights(m, r, order)
    assert v.shape == (m + 1,)
    assert np.isclose(v.sum(), 1.0)  # Lemma 1
    steps = r ** np.arange(m + 1)
    np.testing.assert_allclose(_error_terms(v, steps, order, m), 0.0, atol=1e-9 * np.abs(v).max())
    # ... and not the next one: the order is exactly alpha + m
    assert abs(_error_terms(v, steps, order, m + 1)[-1]) > 1e-6


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("r", [0.5, 0.83])
def test_richardson_table1_rows_m0_m1(r, order):
    np.testing.assert_allclose(parareal.richardson_weights(0, r, order), [1.0])
    ra = r**order
    np.testing.assert_allclose(
        parareal.richardson_weights(1, r, order), [ra / (ra - 1), -1 / (ra - 1)]
    )


@pytest.mark.parametrize("r", [0.5, 0.83])
def test_table1_m2_row_is_wrong_and_ours_is_not(r):
    order = 1
    ra, rb = r**order, r ** (order + 1)
    printed = np.array([rb / (rb - 1) * ra / (ra - 1), -rb / (rb - 1) / (ra - 1), -1 / (rb - 1)])
    ours = parareal.richardson_weights(2, r, order)
    steps = r ** np.arange(3)
    assert np.abs(_error_terms(printed, steps, order, 2)).max() > 1e-2  # the printed row fails
    np.testing.assert_allclose(_error_terms(ours, steps, order, 2), 0.0, atol=1e-9)
    assert not np.allclose(printed, ours)
    assert ours[0] == pytest.approx(printed[0])  # v_0 agrees; v_1 lacks a term, v_2 a factor


@pytest.mark.parametrize("m", [0, 1, 2, 3])
def test_step_weights_agree_with_recursion_on_geometric_steps(m):
    steps = 1e-3 * 0.7 ** np.arange(m + 1)
    np.testing.assert_allclose(
        step_weights(steps, 1), parareal.richardson_weights(m, 0.7, 1), rtol=1e-9
    )


@pytest.mark.parametrize("m", [1, 2, 3])
@pytest.mark.parametrize("order", [1, 2])
def test_weights_for_rounded_steps_still_cancel(m, order):
    slice_length, tau, r = 1e-3, 1.3e-4, 0.83
    counts = [integrate.n_steps(0.0, slice_length, tau * r**q) for q in range(m + 1)]
    steps = slice_length / np.array(counts)
    assert not np.allclose(steps / steps[0], r ** np.arange(m + 1))  # rounding did change them
    v = step_weights(steps, order)
    assert np.isclose(v.sum(), 1.0)
    np.testing.assert_allclose(_error_terms(v, steps, order, m), 0.0, atol=1e-8 * np.abs(v).max())
    # the recursion's weights do not cancel for these steps
    stale = parareal.richardson_weights(m, r, order)
    assert np.abs(_error_terms(stale, steps, order, m)).max() > 1e-6


def test_step_weights_reject_coinciding_steps():
    with pytest.raises(ValueError, match="distinct"):
        step_weights([1e-3, 1e-3], 1)


@pytest.mark.parametrize(
    ("m", "r", "rule"),
    [
        (-1, 0.5, "non-negative integer"),
        (1.5, 0.5, "non-negative integer"),
        (1, 1.0, r"\(0, 1\)"),
        (1, 0.0, r"\(0, 1\)"),
        (2, -0.3, r"\(0, 1\)"),
        (True, 0.5, "non-negative integer"),
    ],
)
def test_richardson_rejects_bad_parameters(m, r, rule):
    with pytest.raises(ValueError, match=rule):
        parareal.richardson_weights(m, r, 1)
