"""The embedded explicit pairs rk23 (Bogacki-Shampine) and rk45 (Dormand-Prince): tableaux,
order conditions, fitted orders (closed form, rod frames), stability boundaries, first same as
last, adaptive runs within their tolerance, frames at given times."""

from __future__ import annotations

import dataclasses
import itertools
from fractions import Fraction
from typing import NamedTuple

import numpy as np
import pytest
from ivp import Counted
from rods import helix_rod
from scipy.integrate import solve_ivp
from scipy.integrate._ivp.rk import RK23, RK45

from parastokes import integrate, models
from parastokes.integrate import SCHEMES, adaptive, controller, loop
from parastokes.integrate.schemes import real_stability_boundary
from parastokes.testing import fitted_order

PAIRS = {"rk23": 3, "rk45": 5}


def _trees(order: int) -> list[tuple]:
    """Rooted trees with ``order`` nodes, each a sorted tuple of its subtrees."""
    if order == 1:
        return [()]
    found = set()
    for split in _compositions(order - 1):
        for children in itertools.product(*(_trees(n) for n in split)):
            found.add(tuple(sorted(children)))
    return sorted(found)


def _compositions(n: int) -> list[tuple[int, ...]]:
    if n == 0:
        return [()]
    return [(k, *rest) for k in range(1, n + 1) for rest in _compositions(n - k)]


def _size(tree: tuple) -> int:
    return 1 + sum(_size(t) for t in tree)


def _gamma(tree: tuple) -> int:
    return _size(tree) * int(np.prod([_gamma(t) for t in tree]))


def _phi(tree: tuple, a: np.ndarray) -> np.ndarray:
    """The elementary weight vector of ``tree``: Π_children (A Φ_child), elementwise."""
    v = np.ones(a.shape[0])
    for child in tree:
        v = v * (a @ _phi(child, a))
    return v


def _matrix(s) -> np.ndarray:
    a = np.zeros((s.stages, s.stages))
    for i, row in enumerate(s.a):
        a[i, : len(row)] = row
    return a


def test_tree_count_matches_the_known_sequence():
    assert [len(_trees(n)) for n in range(1, 6)] == [1, 1, 2, 4, 9]


@pytest.mark.parametrize("name", PAIRS)
def test_tableaux_satisfy_their_order_conditions(name):
    s = SCHEMES[name]
    a = _matrix(s)
    assert np.allclose(a.sum(axis=1), s.c, atol=1e-15)
    assert sum(s.b) == pytest.approx(1.0) and sum(s.b_low) == pytest.approx(1.0)
    for order in range(1, s.order + 1):
        for tree in _trees(order):
            expected = float(Fraction(1, _gamma(tree)))
            assert np.dot(s.b, _phi(tree, a)) == pytest.approx(expected, abs=1e-14)
            if order <= s.order_low:
                assert np.dot(s.b_low, _phi(tree, a)) == pytest.approx(expected, abs=1e-14)
    # the embedded solution is of order order - 1 exactly: one condition of order p fails
    assert any(abs(np.dot(s.b_low, _phi(tree, a)) - 1 / _gamma(tree)) > 1e-6
               for tree in _trees(s.order))
    assert s.fsal and s.adaptive and not s.implicit


def test_stability_boundaries_on_the_negative_real_axis():
    """Hairer & Wanner II, IV.2 (Fig. 2.1): 2 (Euler, Heun), 2.51 (BS3), 2.79 (RK4), 3.31
    (DOPRI5)."""
    bounds = {n: real_stability_boundary(SCHEMES[n]) for n in ("euler", "rk2", "rk23", "rk4",
                                                                 "rk45")}
    assert bounds == pytest.approx({"euler": 2.0, "rk2": 2.0, "rk23": 2.5127, "rk4": 2.7853,
                                    "rk45": 3.3066}, abs=2e-4)


@pytest.mark.parametrize("name", PAIRS)
def test_fitted_order_on_a_closed_form(name):
    system = Counted(lam=(-1.0, -3.0))
    x0 = system.initial_state()
    errors = [float(np.abs(integrate.propagate(system, x0, 0.0, 2.0, name, 2.0 / n)
                           - system.exact(2.0)).max()) for n in (16, 32, 64)]
    slopes = -np.diff(np.log2(errors))
    assert slopes == pytest.approx([PAIRS[name]] * 2, abs=0.25)


@pytest.fixture(scope="module")
def rod_start():
    rod = helix_rod()
    return rod, integrate.propagate(rod, rod.initial_state(), 0.0, 2.0, "rk2", 0.05)


@pytest.mark.parametrize("name", PAIRS)
def test_fitted_order_on_rod_frames_with_and_without_the_rkmk_terms(rod_start, name):
    """With the first-order RKMK terms (schemes.rkmk_brackets) both pairs keep their order on
    the rod's rotating frames; without them they fall to 2."""
    rod, x0 = rod_start
    s = SCHEMES[name]
    reference = integrate.propagate(rod, x0, 0.0, 1.0, "rk45", 1 / 1024)
    assert fitted_order(rod, x0, 0.0, 1.0, name, [8, 16, 32], reference) == pytest.approx(
        PAIRS[name], abs=0.5)
    naive = dataclasses.replace(s, name=f"{name}-naive", stage_brackets=((),) * s.stages,
                                final_brackets=(), low_brackets=())
    assert fitted_order(rod, x0, 0.0, 1.0, naive, [64, 128, 256], reference) == pytest.approx(
        2.0, abs=0.3)


@pytest.mark.parametrize("name", PAIRS)
def test_fixed_steps_run_the_high_order_tableau_alike_compiled_and_in_python(rod_start, name):
    rod, x0 = rod_start
    a = integrate.run(rod, x0, 0.0, 0.05, name, 0.01, compiled=True)
    b = integrate.run(rod, x0, 0.0, 0.05, name, 0.01, compiled=False)
    assert np.array_equal(a.state, b.state) and a.n_steps == 5


@pytest.mark.parametrize("name", PAIRS)
def test_tableaux_are_scipys(name):
    """scipy's RK23 and RK45 (an independent transcription): A, B, C and E = b_low - b."""
    theirs = {"rk23": RK23, "rk45": RK45}[name]
    s = SCHEMES[name]
    n = len(theirs.B)  # scipy keeps the last (FSAL) stage out of A, B and C
    np.testing.assert_allclose(_matrix(s)[:n, : theirs.A.shape[1]], theirs.A, rtol=0, atol=1e-15)
    np.testing.assert_allclose(s.b[:n], theirs.B, rtol=0, atol=1e-15)
    np.testing.assert_allclose(s.c[:n], theirs.C, rtol=0, atol=1e-15)
    np.testing.assert_allclose(np.subtract(s.b_low, s.b), theirs.E, rtol=0, atol=1e-15)


@pytest.mark.parametrize("name", PAIRS)
def test_adaptive_runs_match_scipys_pairs_deterministically(name):
    """scipy's solve_ivp (RK23, RK45: the same tableaux and norm, the elementary controller)
    at the same tolerances and first step: an error no larger, at most 1.6 x its steps (the PI
    control here grows steps more slowly after a first step far too small). Global errors of
    rk23 reach 40 x rtol here, scipy's alike: the tolerance is per step."""
    system = Counted(lam=(-1.0, -10.0))
    x0 = system.initial_state()
    errors, steps = [], []
    for rtol in (1e-4, 1e-7):
        run = integrate.run(system, x0, 0.0, 2.0, name, 1e-3, rtol=rtol, atol=rtol)
        again = integrate.run(system, x0, 0.0, 2.0, name, 1e-3, rtol=rtol, atol=rtol)
        assert np.array_equal(run.state, again.state)
        assert (run.n_steps, run.n_rejected) == (again.n_steps, again.n_rejected)
        theirs = solve_ivp(lambda t, y: system.rates(t, y[:, None])[:, 0], (0.0, 2.0),
                           x0[:, 0], method=name.upper(), rtol=rtol, atol=rtol, first_step=1e-3)
        exact = system.exact(2.0)[:, 0]
        errors.append(float(np.abs(run.state[:, 0] - exact).max()))
        assert errors[-1] <= 1.5 * np.abs(theirs.y[:, -1] - exact).max()
        assert theirs.t.size - 1 <= run.n_steps <= 1.6 * (theirs.t.size - 1)
        steps.append(run.n_steps)
    assert errors[1] < errors[0] / 100 and steps[1] > 2 * steps[0]


def test_first_same_as_last_saves_an_evaluation_per_step():
    """Bogacki-Shampine: 1 + 3 evaluations per accepted step (4 stages, the last reused);
    Dormand-Prince: 1 + 6 per step. A rejected step reuses its first stage too."""
    for name, new in (("rk23", 3), ("rk45", 6)):
        system = Counted(lam=(-1.0,))
        run = integrate.run(system, system.initial_state(), 0.0, 1.0, name, 0.5, rtol=1e-6)
        assert run.n_rejected > 0  # a first step far too large: rejected, and retried
        assert system.calls[0] == 1 + new * (run.n_steps + run.n_rejected)


def test_too_large_a_state_is_a_rejected_step_not_a_blowup():
    """A state whose monitor exceeds the limit is a rejected step (the controller shrinks it)."""
    system = Counted(lam=(-50.0,))  # a first step of h λ = -50: |R| ~ 2e4
    run = integrate.run(system, system.initial_state(), 0.0, 1.0, "rk23", 1.0, rtol=1e3,
                        blowup_factor=3.0 / system.monitor_limit)
    assert run.n_rejected >= 1 and run.max_monitor <= 3.0


def test_frames_of_an_adaptive_run_land_on_their_times():
    """The frames of a run are the states at given times: each propagation cuts its last step
    to end there (the steps are clipped to the frame times, no interpolation)."""
    system = Counted(lam=(-1.0, -5.0))
    fine = integrate.Propagator(system, "rk45", 1e-2, rtol=1e-8, atol=1e-10)
    x = system.initial_state()
    for a, b in itertools.pairwise(np.linspace(0.0, 1.0, 8)):
        x = fine(a, b, x)
        np.testing.assert_allclose(x, system.exact(b), rtol=0, atol=2e-8)


@pytest.fixture(scope="module")
def swimmer():
    """A small rod whose explicit steps stability limits (rejections at rtol 1e-5)."""
    rod = models.rod_swimmer(n_points=41, length=8.0)
    return rod, rod.initial_state()


def _both(rod, x0, name, rtol, **kw):
    return [integrate.run(rod, x0, 0.0, 2e-3, name, 1e-5, rtol=rtol, atol=rtol / 10,
                          compiled=compiled, **kw) for compiled in (True, False)]


@pytest.mark.parametrize("name", PAIRS)
def test_compiled_adaptive_steps_are_the_python_steps(swimmer, name):
    """The compiled adaptive loop (integrate.loop.CompiledPair) takes the Python steps'
    (controller.adaptive_steps of a PairStepper) exactly: the counts, the last step, the
    worst monitor and the state to the bit, with and without rejected steps."""
    rod, x0 = swimmer
    assert isinstance(adaptive.stepper_for(rod, SCHEMES[name]), loop.CompiledPair)
    assert isinstance(adaptive.stepper_for(rod, SCHEMES[name], compiled=False),
                      integrate.explicit.PairStepper)
    rejected = []
    new = SCHEMES[name].stages - 1  # first same as last
    for rtol in (1e-3, 1e-5):
        pair = adaptive.stepper_for(rod, SCHEMES[name])
        _, counts = adaptive.segment(pair, rod.project(x0), 0.0, 2e-3, 1e-5, (rtol, rtol / 10),
                                     adaptive.Watch(rod, x0, 100.0))
        assert pair.evaluations == 1 + new * (counts.accepted + counts.rejected)
        a, b = _both(rod, x0, name, rtol)
        assert (a.n_steps, a.n_rejected, a.dt, a.max_monitor) == (
            b.n_steps, b.n_rejected, b.dt, b.max_monitor)
        assert np.array_equal(a.state, b.state)
        rejected.append(a.n_rejected)
    assert rejected[0] == 0 and rejected[1] > 0


def test_compiled_adaptive_loop_reads_the_controllers_constants(swimmer, monkeypatch):
    """The compiled loop takes the PI exponents of controller.py at each call (no copy of its
    own): without the PI term (PI_BETA = 0) its steps change, and equal the Python steps'."""
    rod, x0 = swimmer
    before, _ = _both(rod, x0, "rk23", 1e-5)
    monkeypatch.setattr(controller, "PI_BETA", 0.0)
    a, b = _both(rod, x0, "rk23", 1e-5)
    assert (a.n_steps, a.n_rejected) != (before.n_steps, before.n_rejected)
    assert (a.n_steps, a.n_rejected) == (b.n_steps, b.n_rejected)
    assert np.array_equal(a.state, b.state)


def test_compiled_adaptive_steps_do_not_depend_on_how_the_calls_are_split(swimmer):
    """Paused after every accepted step (a watch: ``until``) or in calls of CALL_SECONDS: the
    same steps (the carry keeps the time, step, PI error and first-same-as-last stage)."""
    rod, x0 = swimmer
    x0 = rod.project(x0)
    seen = []
    ends = []
    for until in (None, lambda t, x, step, h: seen.append((t, step, h)) and False):
        watch = adaptive.Watch(rod, x0, 100.0)
        ends.append(adaptive.segment(adaptive.stepper_for(rod, SCHEMES["rk23"]), x0, 0.0,
                                     2e-3, 1e-5, (1e-5, 1e-6), watch, until))
    (xa, a), (xb, b) = ends
    assert a == b and np.array_equal(xa, xb) and len(seen) == a.accepted - 1


@pytest.mark.parametrize("compiled", [True, False])
def test_steps_stopped_and_resumed_are_the_steps_run_through(swimmer, compiled):
    """A segment stopped by ``until`` and resumed with the same stepper, from the state it
    returned and with its last accepted error (PI control), takes the steps of one segment
    run through: the first stage is known (first same as last) and the controller goes on."""
    rod, x0 = swimmer
    x0 = rod.project(x0)
    tol = (1e-5, 1e-6)
    through = adaptive.stepper_for(rod, SCHEMES["rk23"], compiled)
    x_all, all_ = adaptive.segment(through, x0, 0.0, 2e-3, 1e-5, tol, adaptive.Watch(rod, x0, 100))
    pair = adaptive.stepper_for(rod, SCHEMES["rk23"], compiled)
    watch = adaptive.Watch(rod, x0, 100.0)
    x, first = adaptive.segment(pair, x0, 0.0, 2e-3, 1e-5, tol, watch, lambda *a: True, 40)
    x, second = adaptive.segment(pair, x, first.end, 2e-3, first.last_step, tol, watch,
                                 previous=first.previous)
    assert first.accepted == 40 and first.previous is not None
    assert np.array_equal(x, x_all) and second.end == all_.end
    assert first.accepted + second.accepted == all_.accepted
    assert first.rejected + second.rejected == all_.rejected
    if compiled:
        assert pair.evaluations == through.evaluations


def test_compiled_adaptive_steps_reject_a_state_beyond_the_monitors_limit(swimmer):
    """A limit below the starting monitor: every step is rejected until the steps are too
    small, in the compiled loop as in Python (the same blow-up)."""
    rod, x0 = swimmer
    factor = 0.5 * rod.monitor(x0) / rod.monitor_limit
    errors = []
    for compiled in (True, False):
        with pytest.raises(integrate.BlowUpError, match="step size") as caught:
            integrate.run(rod, x0, 0.0, 2e-3, "rk23", 1e-5, rtol=1e-3, blowup_factor=factor,
                          compiled=compiled)
        errors.append((caught.value.t, caught.value.step))
    assert errors[0] == errors[1] and errors[0][1] > 30


class _UserData(NamedTuple):
    """A compiled system's data of a type from outside the package (a user's body)."""

    values: np.ndarray


def test_a_users_data_gets_its_own_copy_of_each_compiled_loop():
    """integrate.loop._loop_for: the fixed-step and the adaptive loop each get a copy of their
    own for a user's data type (one per loop and set of modules: not the same copy twice)."""
    data = _UserData(np.zeros(1))
    fixed, pairs = loop._loop_for(data), loop._loop_for(data, loop._adaptive)
    assert fixed is not pairs and fixed is loop._loop_for(data)
    assert fixed.py_func.__qualname__ == "_run_for_test_integrate_pairs"
    assert pairs.py_func.__qualname__ == "_adaptive_for_test_integrate_pairs"
    assert loop._loop_for((1.0, np.zeros(1)), loop._adaptive) is loop._adaptive
