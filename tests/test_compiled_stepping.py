"""The compiled loop of steps (parastokes.stepping) against the Python loop of integrate, for
rods and vesicles: the same tableaux through the same parts, so the same bits, outcomes and
errors."""

import dataclasses
import functools
import math
import os
import signal
import threading
import time

import numba
import numpy as np
import pytest
from kernels_signatures import per_system
from rods import helix_rod

from parastokes import integrate, models
from parastokes.fluid import MRS
from parastokes.integrate import SCHEMES, BlowUpError, loop
from parastokes.kinds.rod.compiled import rod_data
from parastokes.registry import loops as registry


def swimmers(**kw):
    """Two short swimmers side by side above the wall (travelling wave of eq. 36)."""
    return models.rod_swimmer(2, 31, 1.0, length=6.0, wavelength=3.0, **kw)


def both_loops(system, scheme, x, t0, dt, n, limit=1.0, stop_above=math.inf):
    s = SCHEMES[scheme]
    return (
        system.run_steps(s, x, t0, dt, n, limit, stop_above),
        integrate._python_steps(system, s, x, t0, dt, n, limit, stop_above),
    )


def assert_same(compiled, python):
    np.testing.assert_array_equal(compiled[0], python[0])
    assert compiled[1:4] == python[1:4]
    assert compiled[4] == python[4] or (math.isnan(compiled[4]) and math.isnan(python[4]))


@pytest.mark.parametrize("scheme", ["euler", "rk2", "rk4"])
@pytest.mark.parametrize(
    ("system", "dt"),
    [
        (swimmers(), 2e-6),
        (swimmers(wall=False, frequency=-40.0), 2e-6),
        (helix_rod(), 1e-3),
        (models.vesicle(1), 5e-3),
        (models.vesicle(2, shear_rate=-0.3, stiffness=0.2), 1e-3),
    ],
    ids=["swimmers-wall", "swimmers-free", "helix", "vesicle-1", "vesicle-2"],
)
def test_compiled_loop_equals_the_python_loop(system, dt, scheme):
    x0 = system.initial_state()
    if isinstance(system, models.VesicleSystem):  # start deformed, so the springs pull
        x0 = x0 * [1.1, 1.0, 0.9]
    compiled, python = both_loops(system, scheme, x0, 0.3, dt, 12)
    assert compiled[3] == integrate.DONE and compiled[2] == 12
    assert np.abs(compiled[0] - x0).max() > 1e-6  # it moved
    assert_same(compiled, python)


@dataclasses.dataclass(frozen=True)
class DriftingSwimmers(models.RodSystem):
    """A user's model on top of the rod: the same rods carried by a uniform flow along y."""

    def rates(self, t, state):
        rates = super().rates(t, state)
        rates[:, 1] += 50.0
        return rates


def test_a_subclass_with_its_own_rates_is_not_stepped_by_the_parent_loop():
    base = swimmers()
    drifting = DriftingSwimmers(**{f.name: getattr(base, f.name)
                                   for f in dataclasses.fields(base)})
    assert drifting.run_steps is None and base.run_steps is not None
    x0 = base.initial_state()
    moved = integrate.propagate(drifting, x0, 0.0, 1e-5, "rk2", 1e-6)
    plain = integrate.run(drifting, x0, 0.0, 1e-5, "rk2", 1e-6, compiled=False).state
    np.testing.assert_array_equal(moved, plain)
    still = integrate.propagate(base, x0, 0.0, 1e-5, "rk2", 1e-6)
    np.testing.assert_allclose(moved[:, 1] - still[:, 1], 50.0 * 1e-5, rtol=1e-9)


@dataclasses.dataclass(frozen=True)
class RenamedSwimmers(models.RodSystem):
    """A subclass with the rod's physics unchanged."""


class Forwarding:
    """A wrapper that forwards every attribute to a system (as spatial.TargetBlocks does)."""

    def __init__(self, system):
        self.system = system

    def __getattr__(self, name):
        return getattr(self.system, name)


def test_the_compiled_loop_is_chosen_by_exact_type_never_inherited():
    base = swimmers()
    assert registry.compiled_loop(Forwarding(base)) is None
    renamed = RenamedSwimmers(**{f.name: getattr(base, f.name) for f in dataclasses.fields(base)})
    assert renamed.run_steps is None  # not inherited, even with the same physics
    registry.register(RenamedSwimmers, lambda s: functools.partial(loop.run_steps, s, rod_data),
                      fluid=MRS)
    assert (RenamedSwimmers, MRS) in registry.registered()
    compiled, python = both_loops(renamed, "rk2", base.initial_state(), 0.0, 2e-6, 5)
    assert_same(compiled, python)


@pytest.mark.parametrize("call_seconds", [0.0, 1e-4])
def test_splitting_a_run_into_compiled_calls_changes_nothing(monkeypatch, call_seconds):
    """A long run goes back to Python every ~CALL_SECONDS (Ctrl-C); one step per call, or a few,
    gives the bits of the Python loop (step i starts at t0 + i dt in every call)."""
    monkeypatch.setattr(loop, "CALL_SECONDS", call_seconds)
    system = swimmers()
    x0 = system.initial_state()
    compiled, python = both_loops(system, "rk2", x0, 0.3, 1e-6, 40)
    assert compiled[2] == 40 and compiled[3] == integrate.DONE
    assert_same(compiled, python)


@pytest.fixture
def python_sigint():
    """Python's own SIGINT handler, even when the suite was started with SIGINT ignored (a
    background job of a shell without job control): the handler a user's Ctrl-C meets."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


def test_a_long_compiled_run_answers_ctrl_c_promptly(python_sigint):
    """The compiled loop returns to Python about every CALL_SECONDS: a SIGINT 0.5 s into a run
    of ~20 s raises KeyboardInterrupt (not a SystemError) well before the run would end."""
    system = models.rod_swimmer()
    x0 = system.initial_state()
    integrate.propagate(system, x0, 0.0, 2e-6, "rk2", 1e-6)  # compiled and warm
    timer = threading.Timer(0.5, os.kill, (os.getpid(), signal.SIGINT))
    start = time.perf_counter()
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            integrate.propagate(system, x0, 0.0, 0.03, "rk2", 1e-6)
    finally:
        timer.cancel()
    assert time.perf_counter() - start < 0.5 + 4 * loop.CALL_SECONDS + 1.0


def test_run_uses_the_compiled_loop_and_threads_do_not_change_it():
    system = swimmers()
    x0 = system.initial_state()
    plain = integrate.run(system, x0, 0.0, 2e-5, "rk2", 1e-6, compiled=False)
    before = numba.get_num_threads()
    for threads in (1, 2):
        res = integrate.run(dataclasses.replace(system, n_threads=threads), x0, 0.0, 2e-5, "rk2",
                            1e-6)
        np.testing.assert_array_equal(res.state, plain.state)
        assert (res.max_monitor, res.n_steps, res.completed) == (
            plain.max_monitor, plain.n_steps, plain.completed)
        assert numba.get_num_threads() == before  # the thread count is restored


def test_stop_above_ends_both_loops_after_the_same_step():
    system = helix_rod()
    x0 = system.initial_state()
    limit = integrate.BLOWUP_FACTOR * system.monitor_limit
    compiled, python = both_loops(system, "euler", x0, 0.0, 0.2, 200, limit, 1e-3)
    assert compiled[3] == integrate.ABOVE and 0 < compiled[2] < 200 and compiled[4] > 1e-3
    assert_same(compiled, python)


def blowup_from_both_loops(system, x0, t1, scheme, dt):
    """The BlowUpError of each loop (compiled, Python) on the same run."""
    errors = []
    for compiled in (True, False):
        with np.errstate(invalid="ignore", divide="ignore"), pytest.raises(BlowUpError) as info:
            integrate.run(system, x0, 0.0, t1, scheme, dt, compiled=compiled)
        errors.append(info.value)
    a, b = errors
    assert str(a) == str(b) and a.step == b.step and a.t == b.t
    np.testing.assert_array_equal(a.last_state, b.last_state)
    assert np.isfinite(a.last_state).all()
    return a, b


@pytest.mark.parametrize(
    ("system", "deform", "dt"),
    [(helix_rod(), 1.0, 5.0), (models.vesicle(1, stiffness=50.0), [1.2, 1.0, 0.8], 0.5)],
    ids=["rod", "vesicle"],
)
def test_monitor_blowup_is_the_same_error_from_both_loops(system, deform, dt):
    a, b = blowup_from_both_loops(system, system.initial_state() * deform, 200 * dt, "euler", dt)
    assert "monitor beyond" in str(a) and a.monitor == b.monitor > 100 * system.monitor_limit


def test_non_finite_state_is_the_same_error_from_both_loops():
    system = swimmers()
    x0 = system.initial_state()
    x0[10, 3:12] = [0, -1, 0, 0, 0, -1, 1, 0, 0]  # D1, D2 turned by π about D3 = e_x
    a, b = blowup_from_both_loops(system, x0, 1e-5, "rk2", 1e-6)
    assert "non-finite" in str(a) and a.step == 0
    assert math.isnan(a.monitor) and math.isnan(b.monitor)


def test_the_loops_call_the_kernels_mrs_velocity_calls():
    """The compiled loop passes the kernels the same argument types as mrs.velocity (no literal
    flags, no read-only copies), so each kernel is compiled once, not once per caller."""
    from parastokes import mrs
    from parastokes.mrs import compiled

    rod, ves = swimmers(), models.vesicle(1)
    for system, dt in ((rod, 1e-6), (ves, 1e-3)):
        integrate.propagate(system, system.initial_state(), 0.0, 2 * dt, "rk2", dt)
        integrate.run(system, system.initial_state(), 0.0, 2 * dt, "rk2", dt, compiled=False)
    x = rod.initial_state()[:, :3]
    mrs.velocity(x, x, x, epsilon=1.0, mu=1.0, torques=x, wall=True, angular=True)
    mrs.velocity(x, x, x, epsilon=1.0, mu=1.0)
    assert len(per_system(compiled.full, 4)) == 1
    assert len(per_system(compiled.free_u_f, 3)) == 1
