"""Time stepping: tableaux, orders, propagators, blow-up detection, stable-step search."""

import dataclasses
import logging
import pickle

import numpy as np
import pytest
from rods import helix_rod

from parastokes import integrate
from parastokes.integrate import SCHEMES, BlowUpError, Propagator
from parastokes.testing import fitted_order

ORDERS = {"euler": 1, "rk2": 2, "rk4": 4, "rk23": 3, "rk45": 5, "lieuler": 1, "ros2": 2,
          "ros2-krylov": 2, "ros34pw2": 3, "ros34pw2-krylov": 3}
IMPLICIT = {"lieuler", "ros2", "ros2-krylov", "ros34pw2", "ros34pw2-krylov"}


@pytest.fixture(scope="module")
def rod_start():
    rod = helix_rod()
    return rod, integrate.propagate(rod, rod.initial_state(), 0.0, 2.0, "rk2", 0.05)


def test_schemes_declare_their_orders():
    assert {name: SCHEMES[name].order for name in SCHEMES} == ORDERS
    assert {name for name in SCHEMES if SCHEMES[name].implicit} == IMPLICIT
    assert all(integrate.scheme_order(name) == p for name, p in ORDERS.items())
    for s in (SCHEMES[name] for name in SCHEMES if name not in IMPLICIT):
        assert sum(s.b) == pytest.approx(1.0)  # consistent explicit tableaux
        assert all(sum(row) == pytest.approx(c) for row, c in zip(s.a, s.c, strict=True))
    with pytest.raises(ValueError, match="scheme"):
        integrate.scheme_order("rk3")


def test_rk4_without_commutator_terms_is_only_second_order_on_frames(rod_start):
    """Why RK4 carries the RKMK brackets: dropping them loses two orders on rotating frames."""
    rod, x0 = rod_start
    naive = dataclasses.replace(
        SCHEMES["rk4"], name="rk4-naive", stage_brackets=((),) * 4, final_brackets=()
    )
    reference = integrate.propagate(rod, x0, 0.0, 1.0, "rk4", 1 / 1024)
    assert fitted_order(rod, x0, 0.0, 1.0, naive, [8, 16, 32, 64], reference) == pytest.approx(
        2.0, abs=0.2
    )


def test_rk2_is_heun_as_physics_md_describes(rod_start):
    """Predict with Euler, evaluate at t + dt, advance the OLD state by the averaged rates."""
    rod, x0 = rod_start
    t, dt = 0.3, 0.05
    k1 = rod.rates(t, x0)
    k2 = rod.rates(t + dt, rod.advance(x0, k1, dt))
    expected = rod.advance(x0, 0.5 * (k1 + k2), dt)
    np.testing.assert_allclose(integrate.step(rod, "rk2", t, x0, dt), expected, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(integrate.step(rod, "euler", t, x0, dt), rod.advance(x0, k1, dt))


def test_step_is_adjusted_to_divide_the_interval(rod_start, caplog):
    rod, x0 = rod_start
    p = Propagator(rod, "rk2", 0.03)
    assert p.n_steps(0.0, 1.0) == 33
    assert p.n_steps(0.0, 0.01) == 1  # never zero steps on a nonempty interval
    assert p.n_steps(0.5, 0.5) == 0
    with caplog.at_level(logging.DEBUG, logger="parastokes.integrate"):
        adjusted = p(0.0, 1.0, x0)
    assert "step adjusted" in caplog.text
    exact = integrate.propagate(rod, x0, t0=0.0, t1=1.0, scheme="rk2", dt=1 / 33)
    np.testing.assert_array_equal(adjusted, exact)


def test_propagator_is_a_picklable_value(rod_start):
    rod, x0 = rod_start
    p = Propagator(rod, "rk4", 0.1)
    q = pickle.loads(pickle.dumps(p))
    assert q == p and q.order == 4 and (q.system, q.scheme, q.dt) == (rod, "rk4", 0.1)
    np.testing.assert_array_equal(q(0.0, 0.5, x0), p(0.0, 0.5, x0))
    with pytest.raises(ValueError, match="scheme"):
        Propagator(rod, "midpoint", 0.1)
    with pytest.raises(ValueError, match="dt"):
        Propagator(rod, "rk2", 0.0)


def test_interval_validation(rod_start):
    rod, x0 = rod_start
    with pytest.raises(ValueError, match="t_end"):
        integrate.propagate(rod, x0, 1.0, 0.5, "rk2", 0.1)
    with pytest.raises(ValueError, match="dt"):
        integrate.propagate(rod, x0, 0.0, 0.5, "rk2", -0.1)


def test_propagate_projects_input_and_result(rod_start):
    rod, x0 = rod_start
    rng = np.random.default_rng(1)
    noisy = x0 + 1e-6 * rng.standard_normal(x0.shape)
    out = integrate.propagate(rod, noisy, 0.0, 0.1, "rk2", 0.05)
    projected_first = integrate.propagate(rod, rod.project(noisy), 0.0, 0.1, "rk2", 0.05)
    np.testing.assert_allclose(out, projected_first, rtol=0, atol=1e-14)
    assert np.abs(out - integrate.propagate(rod, x0, 0.0, 0.1, "rk2", 0.05)).max() > 1e-8
    d = out[:, 3:].reshape(-1, 3, 3)
    gram = np.einsum("kij,klj->kil", d, d)
    np.testing.assert_allclose(gram, np.broadcast_to(np.eye(3), gram.shape), rtol=0, atol=1e-14)


def test_run_reports_the_worst_monitor(rod_start):
    rod, x0 = rod_start
    res = integrate.run(rod, rod.initial_state(), 0.0, 2.0, "rk2", 0.05)
    assert res.n_steps == 40 and res.dt == pytest.approx(0.05)
    np.testing.assert_allclose(res.state, x0, rtol=0, atol=1e-15)
    assert res.max_monitor >= rod.monitor(res.state) > 0


def test_blowup_names_time_step_and_monitor():
    rod = helix_rod()
    x0 = rod.initial_state()
    dt = 5.0  # far beyond the stable step
    with pytest.raises(BlowUpError) as info:
        integrate.propagate(rod, x0, 0.0, 1000.0, "euler", dt)
    err = info.value
    assert isinstance(err, RuntimeError)
    assert err.monitor > 100 * rod.monitor_limit
    assert err.t == pytest.approx((err.step + 1) * dt)
    message = str(err)
    assert f"t={err.t:.10g}" in message and f"step {err.step}" in message and "monitor=" in message
    x = x0
    for i in range(err.step):  # last_state is the last good state, at t - dt
        x = integrate.step(rod, "euler", i * dt, x, dt)
    np.testing.assert_array_equal(err.last_state, x)
    assert rod.monitor(err.last_state) <= 100 * rod.monitor_limit
    again = pickle.loads(pickle.dumps(err))  # raised in a worker, re-raised in the parent
    assert (again.t, again.step, again.monitor) == (err.t, err.step, err.monitor)
    assert str(again) == message
    np.testing.assert_array_equal(again.last_state, err.last_state)


class Quadratic:
    """dx/dt = x**2: finite-time blow-up, a monitor that never complains."""

    monitor_limit = 1.0

    def rates(self, t, x):
        return x * x

    def advance(self, x, r, dt):
        return x + dt * r

    def project(self, x):
        return x

    def monitor(self, x):
        return 0.0


def test_blowup_on_non_finite_state():
    with np.errstate(over="ignore", invalid="ignore"), pytest.raises(BlowUpError) as info:
        integrate.propagate(Quadratic(), np.ones(3), 0.0, 10.0, "euler", 0.5)
    assert np.isnan(info.value.monitor) and "non-finite" in str(info.value)
    assert np.isfinite(info.value.last_state).all()


def test_largest_stable_step_passes_and_twice_it_fails():
    rod = helix_rod()
    dt = integrate.largest_stable_step(rod, "euler", 2.0, 1e-3, 2.0, rtol=0.05)
    assert integrate.is_stable(rod, "euler", dt, 2.0)
    assert not integrate.is_stable(rod, "euler", 2 * dt, 2.0)
    res = integrate.run(rod, rod.initial_state(), 0.0, 2.0, "euler", dt)
    assert res.max_monitor <= rod.monitor_limit
    with pytest.raises(ValueError, match="dt_lo"):
        integrate.largest_stable_step(rod, "euler", 2.0, 2 * dt, 4 * dt)


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "python"])
def test_a_stage_of_zero_coefficients_is_evaluated_at_the_start_state(compiled):
    """A tableau whose second stage has a zero row (c = (0, 0), b = (1/2, 1/2)) is Euler exactly:
    both loops give Euler's bits (regression: the compiled loop reused the previous stage's
    combination, the Python one raised an IndexError)."""
    from parastokes.kinds.chain import ChainSystem

    chain = ChainSystem(n_beads=6, stiffness=20.0, bending=2.0, shear_rate=1.0, stretch=1.2)
    x = chain.initial_state()
    twice = integrate.Scheme("euler twice", 1, c=(0.0, 0.0), a=((), (0.0,)), b=(0.5, 0.5),
                             stage_brackets=((), ()))
    euler = integrate.run(chain, x, 0.0, 0.05, "euler", 0.01).state
    np.testing.assert_array_equal(
        integrate.run(chain, x, 0.0, 0.05, twice, 0.01, compiled=compiled).state, euler)
