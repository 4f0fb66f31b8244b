"""The cheaper implicit coarse step (round 5): ``A`` rebuilt every N steps of a run
(``Rosenbrock.refresh``, ``coarse.jacobian_every``) and f_t taken with ``A`` and held until the next
rebuild (``hold_time_derivative``): the rebuild and evaluation counts, the held f_t's value, the
order kept (the W-property), runs that do not leak state, and the config keys."""

from __future__ import annotations

import math

import numpy as np
import pytest
from configs import small_rod
from ivp import Counted
from test_stiff import Forced

from parastokes import config, integrate
from parastokes.config import ConfigError
from parastokes.integrate.implicit import checked_stepper
from parastokes.stiff import stepper as stepper_module
from parastokes.stiff.schemes import ROSENBROCK, refreshed_every
from parastokes.testing import fitted_order

H = 0.01


def _steps(system, scheme, n, refresh=None):
    """The stepper after ``n`` steps of ``H`` from the initial state, and the states."""
    stepper = stepper_module.Stepper(system, scheme, system.rates, system.advance, refresh)
    x, states = system.initial_state(), []
    for i in range(n):
        x = stepper.step(i * H, x, H)
        states.append(x)
    return stepper, states


@pytest.mark.parametrize(("every", "builds"), [(1, 7), (3, 3), (None, 2), (7, 1), (8, 1)])
def test_a_is_rebuilt_at_the_first_step_and_every_refresh_steps_after(every, builds):
    """Steps 0, every, 2 every, ... rebuild A (None: the default REFRESH = 5: steps 0 and 5 of 7);
    a fixed step refactorizes only with a new A."""
    assert stepper_module.REFRESH == 5
    stepper, _ = _steps(Forced(), refreshed_every(ROSENBROCK["ros2"], every), 7)
    assert (stepper.refresh, stepper.jacobians, stepper.factorizations) == (
        every or 5, builds, builds)


def test_the_stepper_argument_overrides_the_schemes_refresh():
    stepper, _ = _steps(Forced(), refreshed_every(ROSENBROCK["ros2"], 3), 7, refresh=2)
    assert (stepper.refresh, stepper.jacobians) == (2, 4)


@pytest.mark.parametrize(("name", "stages"), [("ros2", 2), ("ros34pw2", 4)])
def test_a_held_time_derivative_saves_one_evaluation_per_step_between_rebuilds(name, stages):
    """Each step evaluates its stages' rates and, unless held, one more for f_t's forward
    difference; held, f_t is evaluated only at the steps that rebuild A (0, 3, 6 of 7)."""
    counts = {}
    for hold in (False, True):
        system = Counted()
        _steps(system, refreshed_every(ROSENBROCK[name], 3, hold), 7)
        counts[hold] = system.calls[0]
    assert counts == {False: 7 * (stages + 1), True: 7 * stages + 3}


def test_the_held_time_derivative_is_the_one_taken_at_the_rebuild():
    """Step 1 of a run with A every 2 steps and f_t held is step 1 of a run whose f_t at step 1
    is replaced by the f_t of step 0 (bit for bit); step 0 is the default step, and the held
    value changes step 1 (a forced problem: f_t depends on t)."""
    _, (x1, x2) = _steps(Forced(), refreshed_every(ROSENBROCK["ros34pw2"], 2, True), 2)
    _, (y1, y2) = _steps(Forced(), refreshed_every(ROSENBROCK["ros34pw2"], 2), 2)
    assert np.array_equal(x1, y1) and not np.array_equal(x2, y2)
    taken = []
    original = stepper_module.Stepper._time_derivative

    def first_only(self, t, x, h, f0):
        if not taken:
            taken.append(original(self, t, x, h, f0))
        return taken[0]

    system = Forced()
    replaced = stepper_module.Stepper(system, ROSENBROCK["ros34pw2"], system.rates,
                                      system.advance, 2)
    replaced._time_derivative = first_only.__get__(replaced)
    z1 = replaced.step(0.0, system.initial_state(), H)
    z2 = replaced.step(H, z1, H)
    assert np.array_equal(z1, x1) and np.array_equal(z2, x2)


def test_held_with_every_step_a_rebuild_is_the_default_step_bit_for_bit():
    _, held = _steps(Forced(), refreshed_every(ROSENBROCK["ros34pw2"], 1, True), 6)
    _, default = _steps(Forced(), refreshed_every(ROSENBROCK["ros34pw2"], 1), 6)
    assert all(np.array_equal(a, b) for a, b in zip(held, default, strict=True))


@pytest.mark.parametrize("name", ["ros2", "ros34pw2"])
def test_a_stale_a_and_a_held_time_derivative_keep_the_order(name):
    """A W-method keeps its order for any matrix of the autonomous form, here ``A`` and f_t
    taken every 4 steps (Prothero-Robinson, non-stiff λ = -1, -3)."""
    system = Forced(lam=(-1.0, -3.0))
    scheme = refreshed_every(ROSENBROCK[name], 4, True)
    x0 = system.initial_state()
    order = fitted_order(system, x0, 0.0, 1.0, scheme, [16, 32, 64, 128], system.exact(1.0))
    assert abs(order - ROSENBROCK[name].order) < 0.25


def test_a_run_starts_a_fresh_stepper_so_calls_do_not_leak_state():
    """A propagator's second call on the same slice, and a call on slice 2 after slice 1, give
    what a fresh propagator gives (the held f_t and A belong to one run: Parareal stays
    bit-reproducible)."""
    system = Forced()
    scheme = refreshed_every(ROSENBROCK["ros34pw2"], 3, True)
    g = integrate.Propagator(system, scheme, H)
    x0 = system.initial_state()
    first = g(0.0, 0.05, x0)
    second_slice = g(0.05, 0.1, first)
    assert np.array_equal(g(0.0, 0.05, x0), first)
    assert np.array_equal(integrate.Propagator(system, scheme, H)(0.05, 0.1, first),
                          second_slice)


@pytest.mark.parametrize("bad", [0, -1, 2.5, True])
def test_a_refresh_below_one_or_not_an_integer_is_refused(bad):
    with pytest.raises(ValueError, match="jacobian_every: must be an integer >= 1"):
        refreshed_every(ROSENBROCK["ros2"], bad)


IMPLICIT = small_rod(model="epsilon = 5").replace(
    "dt_ratio = 10\nlagrange = { epsilon = [5.6, 5.65] }\nrichardson = { m = 1, r = 0.83 }",
    'scheme = "ros34pw2"\ndt_ratio = 10')


@pytest.mark.parametrize(("keys", "refresh", "hold"), [
    (["coarse.jacobian_every=10", "coarse.hold_time_derivative=true"], 10, True),
    (["coarse.jacobian_every=10"], 10, False), (["coarse.hold_time_derivative=true"], None, True)])
def test_the_coarse_keys_reach_the_auxiliary_solvers_stepper(keys, refresh, hold):
    cfg, resolved = config.loads(IMPLICIT, overrides=keys)
    coarse = config.build(cfg, resolved).coarse
    scheme = coarse.auxiliary[0][0].scheme
    assert (scheme.name, scheme.refresh, scheme.hold_time_derivative) == ("ros34pw2", refresh,
                                                                          hold)
    assert checked_stepper(coarse.system, scheme).refresh == (refresh or 5)


def test_without_the_keys_the_auxiliary_solvers_take_the_scheme_by_name():
    cfg, resolved = config.loads(IMPLICIT)
    assert config.build(cfg, resolved).coarse.auxiliary[0][0].scheme == "ros34pw2"


def test_the_coarse_keys_with_an_explicit_scheme_or_below_one_are_refused_by_check():
    explicit = IMPLICIT.replace('scheme = "ros34pw2"', 'scheme = "euler"')
    for key, value in (("jacobian_every", "10"), ("hold_time_derivative", "true")):
        with pytest.raises(ConfigError) as info:
            config.loads(explicit, overrides=[f"coarse.{key}={value}"])
        message = dict(info.value.issues)[f"coarse.{key}"]
        assert "only for a linearly implicit scheme" in message and "'euler'" in message
    with pytest.raises(ConfigError) as info:
        config.loads(IMPLICIT, overrides=["coarse.jacobian_every=0"])
    assert "coarse.jacobian_every" in dict(info.value.issues)
    assert math.isfinite(config.loads(explicit, overrides=[
        "coarse.hold_time_derivative=false"])[1].coarse_dt)


def test_predicts_measured_step_cost_takes_the_keys_too(monkeypatch):
    """``parastokes predict`` measures an implicit G's evaluations per step with the scheme its
    auxiliary solvers run (A every 10 steps, f_t held), not the scheme's default."""
    from parastokes.coarse import extrapolated, step_cost

    timed = []
    monkeypatch.setattr(step_cost, "measured_evaluations",
                        lambda system, scheme, *args: timed.append(scheme) or 1.0)
    cfg, resolved = config.loads(IMPLICIT, overrides=["coarse.jacobian_every=10",
                                                       "coarse.hold_time_derivative=true"])
    extrapolated.operation_counts(cfg, resolved, [(cfg.coarse, resolved)])
    (scheme,) = timed  # (F, rk2 on fixed steps, is counted by its stages)
    assert (scheme.name, scheme.refresh, scheme.hold_time_derivative) == ("ros34pw2", 10, True)
