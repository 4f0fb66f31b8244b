"""The step-size controller shared by every adaptive scheme (parastokes.integrate.controller):
acceptance at err <= 1, the step factors, the error norm, and the tolerances' checks."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from ivp import Counted

from parastokes import integrate
from parastokes.integrate import controller
from parastokes.integrate.controller import GROW, SAFETY, SHRINK, StepSizeError


class Scripted:
    """A stepper whose error norm (rtol = atol = 1, x = 0) is the next of ``errors``:
    x_new = 0, x_low = err, so (x_new - x_low) / (1 + max(|x|, |x_new|)) = -err."""

    def __init__(self, errors):
        self.errors, self.steps = list(errors), []

    def step_with_estimate(self, t, x, h):
        err = self.errors.pop(0)
        self.steps.append((t, h))
        return np.zeros(1), np.full(1, err)


def _drive(errors, q=2, t1=10.0, h0=1.0, pi=True):
    stepper = Scripted(errors)
    try:
        _, counts = controller.adaptive_steps(stepper, q, np.zeros(1), 0.0, t1, h0, 1.0, 1.0,
                                              lambda t, x, i: True, pi=pi)
    except IndexError:  # the script ran out: the steps so far are the answer
        counts = None
    return stepper.steps, counts


def test_a_step_is_accepted_at_err_one_exactly_and_rejected_just_above():
    steps, _ = _drive([1.0, 1.0 + 1e-12, 0.5])
    (t0, h0), (t1, h1), (t2, h2) = steps
    assert t1 == t0 + h0  # err = 1: accepted, the time moved on
    assert t2 == t1  # err just above 1: rejected, retried from the same time
    assert h1 == pytest.approx(h0 * SAFETY)  # accepted at err 1: SAFETY * 1
    assert h2 == pytest.approx(h1 * 0.5)  # rejected at err ~1: at most halved


@pytest.mark.parametrize("q", [1, 2, 4])
def test_the_growth_factor_is_safety_times_err_to_minus_one_over_q_plus_one(q):
    assert controller.factor(0.5, q, True) == pytest.approx(SAFETY * 0.5 ** (-1 / (q + 1)))
    steps, _ = _drive([0.5, 0.5], q=q)
    assert steps[1][1] / steps[0][1] == pytest.approx(SAFETY * 0.5 ** (-1 / (q + 1)))


@pytest.mark.parametrize("q", [1, 2, 4])
def test_after_two_accepted_steps_the_factor_is_pi_control(q):
    """err^(-0.7/(q+1)) prev^(0.4/(q+1)) (Gustafsson), prev floored at 1e-4 as in DOPRI5."""
    pi = SAFETY * 0.5 ** (-0.7 / (q + 1)) * 0.25 ** (0.4 / (q + 1))
    assert controller.factor(0.5, q, True, 0.25) == pytest.approx(pi)
    steps, _ = _drive([0.25, 0.5, 0.0, 1e-9], q=q)
    assert steps[2][1] / steps[1][1] == pytest.approx(pi)  # the second accepted step: PI
    assert steps[1][1] / steps[0][1] == pytest.approx(SAFETY * 0.25 ** (-1 / (q + 1)))
    # a rejected step is sized by the elementary controller, whatever came before
    assert controller.factor(4.0, q, False, 0.25) == controller.factor(4.0, q, False)
    steps, _ = _drive([0.0, 1e-9, 0.5], q=q, t1=1e6)  # prev = max(0, 1e-4): err 1e-9 after err 0
    assert steps[2][1] / steps[1][1] == pytest.approx(
        min(GROW, SAFETY * 1e-9 ** (-0.7 / (q + 1)) * 1e-4 ** (0.4 / (q + 1))))
    assert controller.factor(0.5, q, True, 1e-4) < GROW  # the floor keeps PI finite
    # without pi (the Rosenbrock schemes) every step is sized by the elementary controller
    steps, _ = _drive([0.25, 0.5, 0.0, 1e-9], q=q, pi=False)
    assert steps[2][1] / steps[1][1] == pytest.approx(SAFETY * 0.5 ** (-1 / (q + 1)))


def test_growth_and_shrinkage_are_clipped():
    assert controller.factor(1e-12, 2, True) == GROW
    assert controller.factor(0.0, 2, True) == GROW
    assert controller.factor(1e6, 2, False) == SHRINK
    assert controller.factor(math.inf, 2, False) == SHRINK
    # a step refused for its state (err small) shrinks by at least a half, never grows
    assert controller.factor(0.0, 2, False) == controller.REJECT_MAX == 0.5
    # just above 1: SAFETY * err^(-1/3) = 0.9 > 0.5 -> clipped to 0.5
    assert controller.factor(1.01, 2, False) == 0.5
    # err = 8, q = 2: 0.9 / 2 = 0.45
    assert controller.factor(8.0, 2, False) == pytest.approx(0.45)


def test_the_estimate_order_is_the_lower_of_the_two():
    assert controller.estimate_order(integrate.SCHEMES["rk23"]) == 2
    assert controller.estimate_order(integrate.SCHEMES["rk45"]) == 4
    assert controller.estimate_order(integrate.SCHEMES["ros2"]) == 1  # embedded Euler


def test_the_error_norm_on_a_known_vector():
    x = np.array([1.0, -2.0, 0.0, 4.0])
    x_new = np.array([1.0, -3.0, 0.5, 2.0])
    x_low = x_new - np.array([0.1, 0.2, 0.3, 0.4])
    # scales: atol + rtol * max(|x|, |x_new|) = 0.1 + 0.5 * (1, 3, 0.5, 4) = (0.6, 1.6, 0.35, 2.1)
    ratios = np.array([0.1 / 0.6, 0.2 / 1.6, 0.3 / 0.35, 0.4 / 2.1])
    by_hand = math.sqrt(float(np.mean(ratios**2)))
    assert controller.error_norm(x, x_new, x_low, 0.5, 0.1) == pytest.approx(by_hand, rel=1e-14)
    # rtol alone and atol alone each change the norm
    assert controller.error_norm(x, x_new, x_low, 0.5, 0.2) < by_hand
    assert controller.error_norm(x, x_new, x_low, 0.25, 0.1) > by_hand
    # with atol alone (rtol tiny): RMS of the differences / atol
    assert controller.error_norm(x, x_new, x_low, 1e-300, 0.1) == pytest.approx(
        math.sqrt(np.mean((np.array([0.1, 0.2, 0.3, 0.4]) / 0.1) ** 2)))


def test_steps_that_shrink_to_nothing_are_a_step_size_error():
    with pytest.raises(StepSizeError, match=r"step size .* too small at t=0"):
        _drive([1e9] * 100)
    error = StepSizeError(0.5, 1e-20)
    assert isinstance(error, RuntimeError) and (error.t, error.step) == (0.5, 1e-20)


def test_the_last_step_lands_on_the_end_and_counts_are_kept():
    steps, counts = _drive([0.0, 0.0, 0.0, 0.0], t1=3.0, h0=1.0)
    assert [h for _, h in steps] == [1.0, 2.0]  # 1, then 5 x 1 cut to end at 3
    assert (counts.accepted, counts.rejected) == (2, 0)


def test_until_sees_every_every_th_accepted_step_before_the_end():
    """``until`` after the 3rd, 6th, 9th, ... accepted step (``every`` = 3; a rejected one does
    not count); its True stops the steps there."""
    seen = []
    stepper = Scripted([0.5, 2.0] + [0.5] * 12)
    with pytest.raises(IndexError):
        controller.adaptive_steps(stepper, 2, np.zeros(1), 0.0, 1e9, 1.0, 1.0, 1.0,
                                  lambda t, x, i: True,
                                  lambda t, x, step, h: seen.append(len(stepper.steps)),
                                  every=3)
    assert seen == [4, 7, 10, 13]  # steps tried at the 3rd, 6th, ... accepted (one rejected)
    stepper = Scripted([0.5] * 10)
    _, counts = controller.adaptive_steps(stepper, 2, np.zeros(1), 0.0, 1e9, 1.0, 1.0, 1.0,
                                          lambda t, x, i: True, lambda *a: True, every=2)
    assert (counts.accepted, counts.end) == (2, stepper.steps[1][0] + stepper.steps[1][1])


def test_tolerances_are_checked_in_the_python_api():
    system = Counted()
    x0 = system.initial_state()
    with pytest.raises(ValueError, match=r"^atol: given \(0.001\) without rtol"):
        integrate.run(system, x0, 0.0, 1.0, "rk23", 0.1, atol=1e-3)
    with pytest.raises(ValueError, match=r"^atol: given \(0.001\) without rtol"):
        integrate.Propagator(system, "rk45", 0.1, atol=1e-3)
    with pytest.raises(ValueError, match=r"^rtol: the scheme 'rk4' has no error estimate"):
        integrate.Propagator(system, "rk4", 0.1, rtol=1e-3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a clear refusal, no numpy overflow on the way
        with pytest.raises(ValueError, match=r"^rtol: 1e-300 is below 2.2e-14"):
            integrate.run(system, x0, 0.0, 1.0, "rk45", 0.1, rtol=1e-300)
    integrate.Propagator(system, "rk45", 0.1, rtol=integrate.runs.RTOL_MIN)  # the boundary passes


def test_every_scheme_says_whether_it_is_adaptive():
    adaptive = {name for name, s in integrate.SCHEMES.items() if s.adaptive}
    assert adaptive == {"rk23", "rk45", "ros2", "ros2-krylov"} | {
        name for name, s in integrate.SCHEMES.items() if s.implicit and s.b_low is not None}
    assert not integrate.SCHEMES["lieuler"].adaptive and not integrate.SCHEMES["rk4"].adaptive


def test_pi_control_sizes_the_explicit_pairs_only(monkeypatch):
    """Changing the PI exponents changes an rk23 run and leaves a ros2 run alone."""
    system = Counted(lam=(-1.0, -100.0))
    x0 = system.initial_state()

    def runs():
        return [integrate.run(system, x0, 0.0, 1.0, s, 1e-3, rtol=1e-5) for s in ("ros2", "rk23")]

    (ros2, rk23) = runs()
    monkeypatch.setattr(controller, "PI_BETA", 0.0)
    (ros2_b, rk23_b) = runs()
    assert np.array_equal(ros2.state, ros2_b.state) and ros2.n_steps == ros2_b.n_steps
    assert rk23.n_steps != rk23_b.n_steps
