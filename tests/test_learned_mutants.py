"""Direct checks of the secant correction's arithmetic (parastokes/parareal/learned.py and its
call in eq. 11), each written for a one-line bug that the property tests of
tests/test_parareal_learned.py let through when it was planted (docs/parareal.md, "Learned
corrections"; the plant-and-catch table is in the round's report)."""

from __future__ import annotations

import numpy as np

from parastokes.parareal.algorithm import correct
from parastokes.parareal.learned import SecantHistory, secant_step


def test_the_secant_map_keeps_a_step_far_smaller_than_the_others():
    """Parareal's steps shrink by orders of magnitude from one iteration to the next: the
    latest, smallest one is the most telling and must not be cut as noise (a least-squares
    cutoff above machine precision drops it: J of it then reads 0)."""
    rng = np.random.default_rng(17)
    jacobian = rng.standard_normal((6, 6))
    dx = rng.standard_normal((6, 3)) * np.array([1.0, 1e-4, 1e-9])
    dd = jacobian @ dx
    for i in range(3):
        np.testing.assert_allclose(secant_step(dx, dd, dx[:, i]), dd[:, i], rtol=1e-8)


def _collinear_history(u: np.ndarray, x0: np.ndarray, ts: list[float], ds: list[np.ndarray]
                       ) -> SecantHistory:
    """Slice 3's pairs of iterations 0..len(ts) - 2 at the inputs x0 + t u with D = ``ds``, fed
    through the corrections of iterations 1..len(ts) - 1 as eq. 11 feeds them (the correction
    of iteration len(ts) keeps the last pair)."""
    history = SecantHistory()
    for k in range(1, len(ts)):
        history.correction(3, k, x0 + ts[k] * u, x0 + ts[k - 1] * u, ds[k - 1], np.zeros(3))
    return history


def test_on_collinear_steps_the_secant_is_the_closed_form_fit_of_consecutive_differences():
    """All inputs on one line x0 + t u: the columns are u dt_i, and the minimum-norm fit gives
    J (s u) = s sum_i dt_i dD_i / sum_i dt_i^2 with dt_i, dD_i the differences of CONSECUTIVE
    iterates (not of each against the first: the same span, another fit when D is not affine),
    the pair of each iteration its input X^(i-1) with D = F - G there."""
    rng = np.random.default_rng(19)
    u, x0 = np.array([0.6, 0.0, 0.8]), rng.standard_normal(3)
    ts = [0.0, 1.0, 3.0, 3.5]
    ds = [rng.standard_normal(3) for _ in ts]  # D at the inputs: not affine in t
    fine, previous = 2.0 * ds[3], ds[3]        # F - G = ds[3] at the last input
    history = _collinear_history(u, x0, ts, ds)
    new = x0 + 4.25 * u
    term = history.correction(3, len(ts), new, x0 + ts[-1] * u, fine, previous)
    dt = np.diff(ts)
    dd = np.diff(ds, axis=0)
    expected = (4.25 - 3.5) * (dt @ dd) / (dt @ dt)
    np.testing.assert_allclose(term, expected, rtol=1e-12, atol=1e-15)


def test_the_correction_is_eq_11_plus_the_secant_term_of_its_own_inputs():
    """correct(...) with the secant = F(X^(k-1)) + G(X^k) - G(X^(k-1)) + J (X^k - X^(k-1)):
    eq. 11's G difference kept, the new input X^k and the old X^(k-1) in that order, and
    D = F - G (not G - F) at the old one (closed form of the collinear test above)."""
    rng = np.random.default_rng(23)
    u, x0 = np.array([0.0, 1.0, 0.0]), rng.standard_normal(3)
    ts = [0.0, 2.0, 2.5]
    ds = [rng.standard_normal(3) for _ in ts]
    history = _collinear_history(u, x0, ts, ds)
    fine, previous, coarse = ds[-1] + 1.0, np.ones(3), rng.standard_normal(3)  # F - G = ds[-1]
    new, old = x0 + 3.0 * u, x0 + ts[-1] * u
    value = correct(fine, coarse, previous, None, (3, len(ts), 0.5), None, (history, new, old))
    dt, dd = np.diff(ts), np.diff(ds, axis=0)
    expected = fine + (coarse - previous) + (3.0 - 2.5) * (dt @ dd) / (dt @ dt)
    np.testing.assert_allclose(value, expected, rtol=1e-12, atol=1e-14)
