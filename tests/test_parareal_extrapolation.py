"""Extrapolated coarse solvers (eqs. 18, 25, 28, 30) and the coarse-grid combinator (eqs. 32-33)."""

import logging
import pickle
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from odes import RecordingExecutor, Stepper, ToySystem

from parastokes import integrate, parareal


def _fitted_order(system, m, r, dts, t1=1.0):
    x0 = system.initial_state()
    exact = x0 * np.exp(-system.params["decay"] * t1)
    errors = []
    for dt in dts:
        g = parareal.extrapolated(system, "euler", dt, richardson={"m": m, "r": r})
        errors.append(np.abs(g(0.0, t1, x0) - exact).max())
    return np.polyfit(np.log(dts), np.log(errors), 1)[0]


@pytest.mark.parametrize(("m", "r"), [(0, 0.5), (1, 0.5), (2, 0.5), (1, 0.83), (2, 0.83)])
def test_richardson_raises_forward_euler_order(m, r):
    system = ToySystem(n_points=2, decay=1.0)  # (decay = 2 happens to have no tau^3 error term)
    dts = 1.0 / np.array([10, 20, 40, 80])
    assert _fitted_order(system, m, r, dts) == pytest.approx(1 + m, abs=0.15)


def _drift_system():
    return ToySystem(n_points=3, a=0.7, b=-0.4, c=0.3)


@pytest.mark.parametrize(
    "lagrange",
    [
        {"a": [0.8, 0.9, 1.1]},
        {"a": [0.75, 0.8, 0.85], "b": [-0.3, -0.2]},
        {"a": [0.4, 0.5, 0.6], "b": [-0.3, -0.2], "c": [0.5, 0.6]},
    ],
)
def test_lagrange_extrapolation_is_exact_for_polynomial_dependence(lagrange):
    # the Euler solution is a polynomial of degree (2, 1, 1) in (a, b, c)
    system = _drift_system()
    x0 = system.initial_state()
    g = parareal.extrapolated(system, "euler", 0.05, lagrange=lagrange)
    assert len(g.thetas) == np.prod([len(v) for v in lagrange.values()])
    plain = integrate.Propagator(system, "euler", 0.05)
    np.testing.assert_allclose(g(0.0, 1.0, x0), plain(0.0, 1.0, x0), rtol=1e-10, atol=1e-12)
    # the auxiliary solvers really use the perturbed values
    assert all(p.system.params["a"] != system.params["a"] for row in g.auxiliary for p in row)


def test_lagrange_with_too_few_nodes_is_not_exact():
    system = _drift_system()
    x0 = system.initial_state()
    g = parareal.extrapolated(system, "euler", 0.05, lagrange={"a": [0.8, 0.9]})
    plain = integrate.Propagator(system, "euler", 0.05)
    assert np.abs(g(0.0, 1.0, x0) - plain(0.0, 1.0, x0)).max() > 1e-4


def test_lagrange_and_richardson_combined():
    # eq. 30: Lagrange in a (exact, degree 2 with 3 nodes), Richardson in the step on the decay
    system = ToySystem(n_points=2, decay=1.0, a=0.5)
    x0 = system.initial_state()
    g0 = parareal.extrapolated(system, "euler", 0.1, lagrange={"a": [0.6, 0.7, 0.8]})
    g1 = parareal.extrapolated(
        system, "euler", 0.1, lagrange={"a": [0.6, 0.7, 0.8]}, richardson={"m": 1, "r": 0.5}
    )
    assert len(g1.auxiliary) == 3 and len(g1.auxiliary[0]) == 2
    fine = integrate.Propagator(system, "rk4", 1e-3)(0.0, 1.0, x0)
    err0 = np.abs(g0(0.0, 1.0, x0) - fine).max()
    err1 = np.abs(g1(0.0, 1.0, x0) - fine).max()
    assert err1 < err0 / 10


def test_rounded_steps_are_reported_and_weights_cancel(caplog):
    system = ToySystem(n_points=2, decay=1.0)
    g = parareal.extrapolated(system, "euler", 1.3e-4, richardson={"m": 2, "r": 0.83})
    with caplog.at_level(logging.INFO, logger="parastokes.parareal"):
        g(0.0, 1e-3, system.initial_state())
    steps, v = g.plan(0.0, 1e-3)
    counts = [integrate.n_steps(0.0, 1e-3, 1.3e-4 * 0.83**q) for q in range(3)]
    np.testing.assert_allclose(steps, 1e-3 / np.array(counts))
    assert g.steps_used == tuple(steps)
    h = steps / steps[0]
    np.testing.assert_allclose([v.sum(), v @ h, v @ h**2], [1.0, 0.0, 0.0], atol=1e-9)
    assert "steps" in caplog.text and "requested" in caplog.text


def test_coinciding_rounded_steps_raise_before_work(monkeypatch):
    system = ToySystem(n_points=2, decay=1.0)
    g = parareal.extrapolated(system, "euler", 0.1, richardson={"m": 1, "r": 0.9})
    calls = []
    original = integrate.propagate

    def recording_propagate(*args, **kwargs):
        calls.append(args)
        return original(*args, **kwargs)

    # a Propagator calls the propagate of its own module (parastokes.integrate.runs)
    monkeypatch.setattr(integrate.runs, "propagate", recording_propagate)
    with pytest.raises(ValueError, match="distinct"):
        g(0.0, 0.05, system.initial_state())  # both steps round to one step of 0.05
    assert calls == []
    g(0.0, 1.0, system.initial_state())  # 10 and 11 steps: fine
    assert len(calls) == 2


@pytest.mark.parametrize(
    ("kwargs", "rule"),
    [
        ({"lagrange": {"a": [0.9, 0.8]}}, "strictly increasing"),
        ({"lagrange": {"a": [0.6, 0.8]}}, "outside"),
        ({"lagrange": {"a": [0.8, 0.9], "b": [-0.5, -0.3]}}, r"lagrange\['b'\].*outside"),
        ({"lagrange": {"viscosity": [1.1, 1.2]}}, "unknown parameter"),
        ({"richardson": {"m": 1, "r": 1.2}}, r"\(0, 1\)"),
        ({"richardson": {"m": -1, "r": 0.5}}, "non-negative integer"),
        ({"richardson": {"m": 1}}, "r is required"),
        ({"richardson": {"m": 1, "r": 0.5, "q": 2}}, "keys"),
        ({"grid": 1}, "grid"),
        ({"scheme": "leapfrog"}, "scheme"),
        ({"dt": -0.1}, "dt"),
    ],
)
def test_invalid_configuration_raises_before_any_work(kwargs, rule):
    system = ToySystem(a=0.7, b=-0.4)
    before = ToySystem.with_params_calls
    args = {"scheme": "euler", "dt": 0.1}
    args.update(kwargs)
    with pytest.raises(ValueError, match=rule):
        parareal.extrapolated(system, **args)
    assert ToySystem.with_params_calls == before


def test_executor_runs_auxiliary_solvers_and_is_dropped_on_pickle():
    system = ToySystem(n_points=2, decay=1.0, a=0.5)
    lagrange, richardson = {"a": [0.6, 0.7]}, {"m": 1, "r": 0.5}
    serial = parareal.extrapolated(system, "euler", 0.1, lagrange=lagrange, richardson=richardson)
    x0 = system.initial_state()
    with ThreadPoolExecutor(2) as pool:
        pooled = parareal.extrapolated(
            system, "euler", 0.1, lagrange=lagrange, richardson=richardson, executor=pool
        )
        np.testing.assert_array_equal(pooled(0.0, 1.0, x0), serial(0.0, 1.0, x0))
        clone = pickle.loads(pickle.dumps(pooled))
    assert pooled.executor is pool and clone.executor is None
    np.testing.assert_array_equal(clone(0.0, 1.0, x0), serial(0.0, 1.0, x0))


def test_run_sends_auxiliary_solvers_to_its_executor():
    system = ToySystem(n_points=2, decay=1.0, a=0.5)
    coarse = parareal.extrapolated(
        system, "euler", 0.1, lagrange={"a": [0.6, 0.7]}, richardson={"m": 1, "r": 0.5}
    )
    fine = integrate.Propagator(system, "rk2", 0.01)
    executor = RecordingExecutor()
    x0 = system.initial_state()
    res = parareal.run(fine, coarse, x0, 0.0, 1.0, 4, tol=0.0, max_iterations=2, executor=executor)
    plain = parareal.run(fine, coarse, x0, 0.0, 1.0, 4, tol=0.0, max_iterations=2)
    np.testing.assert_array_equal(res.states, plain.states)
    aux = [fn for fn in executor.submitted if fn is not fine]
    assert len(aux) == 4 * (4 + 3 + 2)  # 2 nodes x 2 steps per G call, N + (N-1) + (N-2) G calls
    assert sum(fn is fine for fn in executor.submitted) == 4 + 3
    assert coarse.executor is None  # the caller's combinator is not modified


def test_parareal_with_extrapolated_coarse_solver_converges():
    system = ToySystem(n_points=3, decay=1.5, a=0.5, b=0.2)
    coarse = parareal.extrapolated(
        system, "euler", 0.05, lagrange={"a": [0.6, 0.7, 0.8]}, richardson={"m": 1, "r": 0.5}
    )
    fine = integrate.Propagator(system, "rk4", 0.01)
    x0 = system.initial_state()
    reference = parareal.serial_solution(fine, x0, 0.0, 2.0, 8)
    res = parareal.run(
        fine, coarse, x0, 0.0, 2.0, 8, tol=1e-10, max_iterations=8, reference=reference
    )
    assert res.stop_reason == "tolerance" and res.iterations <= 4
    assert res.errors[-1] < 1e-10


def test_coarse_grid_combinator_eq33():
    system = ToySystem(n_points=9, a=0.7, b=-0.4)  # drift only: states stay linear along the rows
    x0 = system.initial_state()
    g = parareal.extrapolated(system, "euler", 0.05, lagrange={"a": [0.8, 0.9, 1.0]}, grid=4)
    assert isinstance(g, parareal.OnCoarseGrid)
    assert g.propagator.system.n_points == 3  # the auxiliary solvers run on the coarse grid
    assert g.propagator.auxiliary[0][0].system.n_points == 3
    same_grid = integrate.Propagator(system, "euler", 0.05)
    np.testing.assert_allclose(g(0.0, 1.0, x0), same_grid(0.0, 1.0, x0), rtol=1e-12)
    # executor binding reaches the wrapped combinator; pickling keeps the transfer
    executor = RecordingExecutor()
    bound = g.with_executor(executor)
    assert bound.executor is executor and g.executor is None
    np.testing.assert_array_equal(bound(0.0, 1.0, x0), g(0.0, 1.0, x0))
    assert len(executor.submitted) == 3
    clone = pickle.loads(pickle.dumps(bound))
    assert clone.executor is None and clone.transfer.factor == 4


def test_coarse_grid_wraps_a_plain_propagator():
    system = ToySystem(n_points=5, decay=0.0, a=1.0)
    coarse_system, transfer = system.coarsened(2)
    g = parareal.OnCoarseGrid(Stepper(_Rates(coarse_system), 0.1, order=1), transfer)
    assert g.with_executor(RecordingExecutor()) is g  # nothing to bind
    x0 = system.initial_state()
    np.testing.assert_allclose(g(0.0, 1.0, x0), x0 + 1.0)  # u = a^2 = 1 on every point


class _Rates:
    def __init__(self, system):
        self.system = system

    def rhs(self, t, x):
        return self.system.rates(t, x)
