"""The third-order Rosenbrock-W scheme ROS34PW2 (parastokes.stiff.schemes): its tableau against
its standard form, the conversion against ROS2's, fitted orders on Prothero-Robinson problems
with exact and inexact Jacobians (the W-property), of its embedded estimate, and on a rod's
rotating frames (where the dexp⁻¹ correction of its stages keeps order 3)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from rods import helix_rod
from test_stiff import Forced, _errors, _slope

from parastokes import integrate
from parastokes.integrate import SCHEMES
from parastokes.stiff import ROSENBROCK, schemes, stepper

ROS34 = ROSENBROCK["ros34pw2"]


def test_the_conversion_from_the_standard_form_gives_ros2():
    """ROS2 in the standard form (α21 = 1, γ21 = -2γ, b = (1/2, 1/2), embedded (1, 0)) converts
    to the hand-written tableau (a21 = 1, d21 = -2, b = (3/2, 1/2), g = (γ, -γ))."""
    g = 1.0 + 1.0 / math.sqrt(2.0)
    made = schemes.from_standard("ros2", 2, [[0, 0], [1, 0]], [[g, 0], [-2 * g, g]],
                                 [0.5, 0.5], [1.0, 0.0])
    ros2 = ROSENBROCK["ros2"]
    assert made.gamma == pytest.approx(ros2.gamma, rel=1e-15)
    for field in ("c", "a", "d", "b", "b_low", "g"):
        assert np.allclose(np.hstack(getattr(made, field)), np.hstack(getattr(ros2, field)),
                           rtol=1e-14, atol=1e-15), field


def test_the_tableau_is_the_published_one_converted():
    """c = α's row sums (0, 2γ, 0.73, 1), g = Γ's row sums, γ the diagonal; stiffly accurate
    (the last stage's state is the solution: b = (a_4, γ)); the embedded weights differ."""
    alpha = np.array(schemes.ROS34PW2_STANDARD["alpha"])
    gam = np.array(schemes.ROS34PW2_STANDARD["gamma"])
    assert ROS34.gamma == pytest.approx(0.4358665215084590, abs=1e-16)
    assert np.allclose(ROS34.c, alpha.sum(axis=1), atol=1e-15)
    assert ROS34.c[1] == pytest.approx(2 * ROS34.gamma, rel=1e-15)
    assert np.allclose(ROS34.g, gam.sum(axis=1), atol=1e-15)
    assert np.allclose(ROS34.b[:3], ROS34.a[3], atol=1e-14) and ROS34.b[3] == pytest.approx(
        ROS34.gamma, rel=1e-14)
    assert ROS34.order == 3 and ROS34.b_low is not None
    assert SCHEMES["ros34pw2"] is ROS34 and ROS34.implicit


def test_a_tableau_not_in_standard_form_is_refused():
    with pytest.raises(ValueError, match="lower triangular"):
        schemes.from_standard("x", 2, [[0, 0], [1, 0]], [[0.5, 0.1], [0, 0.5]], [0.5, 0.5],
                              [1, 0])


@pytest.mark.parametrize("z", [-0.5, -30.0, -1e8])
def test_one_step_on_y_prime_lambda_y_is_l_stable(z):
    """One step of size 1 on y' = z y, exact Jacobian: |R(z)| < 1, R(-∞) = 0 (stiffly accurate
    and L-stable, Rang & Angermann 2005), and R(z) ≈ e^z for small |z| (order 3)."""
    y = integrate.step(Forced(lam=(z,), forced=False), "ros34pw2", 0.0, np.array([[1.0]]), 1.0)
    assert abs(y[0, 0]) < 1.0
    if z < -1e6:
        assert abs(y[0, 0]) < 1e-7
    small = integrate.step(Forced(lam=(z,), forced=False), "ros34pw2", 0.0,
                           np.array([[1.0]]), 0.01)
    assert abs(small[0, 0] - math.exp(0.01 * z)) < 0.1 * abs(0.01 * z) ** 4 + 1e-15


@pytest.mark.parametrize("factor", [1.0, 0.5, 2.0, 0.0, None])
def test_order_three_on_a_smooth_ode_for_any_jacobian(factor):
    """Prothero-Robinson, λ = -1, -3: order 3 with the exact A = λ, a wrong one (λ/2, 2λ), A = 0
    and none: the W-property (ROS3P would fall to 2 with an inexact A)."""
    system = Forced(lam=(-1.0, -3.0), jacobian_factor=factor)
    counts = [16, 32, 64, 128]
    assert abs(_slope(counts, _errors(system, "ros34pw2", counts)) - 3.0) < 0.25


def test_order_three_at_steps_far_beyond_the_explicit_limit():
    """Prothero-Robinson with λ = -1e4 at h|λ| from 80 to 600, exact Jacobian: order 3 (the g
    terms of the stages carry f_t; without them a Rosenbrock scheme drops an order)."""
    counts = [16, 32, 64, 128]
    assert abs(_slope(counts, _errors(Forced(lam=(-1.0, -1e4)), "ros34pw2", counts)) - 3) < 0.25


def test_the_embedded_estimate_is_of_second_order():
    """The difference of the two solutions of one step from the same state (the estimate the
    step controller uses) falls like h³ (local error of the order-2 solution)."""
    system = Forced(lam=(-1.0, -3.0))
    x0 = system.initial_state()
    hs = [0.04, 0.02, 0.01, 0.005]
    diffs = []
    for h in hs:
        run = stepper.Stepper(system, ROS34, system.rates, system.advance)
        x_new, x_low = run.step_with_estimate(0.0, x0, h)
        diffs.append(float(np.abs(x_new - x_low).max()))
    assert abs(-_slope(hs, diffs) - 3.0) < 0.15


def _rod_errors(bracket: bool, scheme: str = "ros34pw2") -> list[float]:
    rod = helix_rod()
    x = rod.initial_state()
    horizon = 0.1
    reference = integrate.run(rod, x, 0.0, horizon, "rk4", horizon / 1024).state
    if not bracket:
        rod = _WithoutBracket(rod)
    return [float(np.abs(integrate.run(rod, x, 0.0, horizon, scheme, horizon / n).state
                         - reference).max()) for n in (16, 32, 64)]


class _WithoutBracket:
    """The rod with no ``bracket``: ROS34PW2's stages then miss the dexp⁻¹ correction."""

    def __init__(self, rod):
        self._rod = rod

    def __getattr__(self, name):
        if name == "bracket":
            raise AttributeError(name)
        return getattr(self._rod, name)


def test_order_three_on_rotating_frames_needs_the_dexp_correction():
    """A free rod relaxing to a helix (3D frame dynamics): order 3 with the stages' first-order
    dexp⁻¹ correction, 2 without it (the commutator terms enter at order 3)."""
    counts = [16, 32, 64]
    assert abs(_slope(counts, _rod_errors(True)) - 3.0) < 0.25
    assert abs(_slope(counts, _rod_errors(False)) - 2.0) < 0.25


def test_the_krylov_variant_is_of_order_three_on_the_rod():
    """ros34pw2-krylov (stages on the exact Jacobian by GMRES) keeps order 3 on the rod."""
    assert ROSENBROCK["ros34pw2-krylov"].krylov
    counts = [16, 32, 64]
    assert abs(_slope(counts, _rod_errors(True, "ros34pw2-krylov")) - 3.0) < 0.3
