"""Spatial parallelization of F (Remark 1): threads and blocks of targets give the serial F.

The kernels sum every target's contributions on one thread in a fixed order, and a block of
targets sent to a worker is summed the same way, so both are bit-identical to the serial F.
"""

from __future__ import annotations

import dataclasses
import pickle

import numpy as np
import pytest
from odes import ToySystem

from parastokes import fluid, integrate, models, parallel, parareal
from parastokes.fluid import BlockedMRS
from parastokes.parallel import spatial
from parastokes.registry import loops as registry

# two interacting rods above the wall (forces, torques, images) and a small vesicle in shear
CASES = {
    "rods": (models.rod_swimmer(n_rods=2, n_points=41), 1e-6, 4e-6),
    "vesicle": (models.vesicle(subdivisions=2), 1e-3, 4e-3),
}


@pytest.fixture(scope="module", params=sorted(CASES))
def case(request):
    system, dt, t1 = CASES[request.param]
    x0 = system.initial_state()
    return system, dt, t1, x0, integrate.propagate(system, x0, 0.0, t1, "rk2", dt)


@pytest.fixture(scope="module")
def pool():
    with parallel.make_executor("processes", 2) as executor:
        yield executor


@pytest.mark.parametrize("n_threads", [1, 2, 3])
def test_threaded_fine_solver_is_bit_identical(case, n_threads):
    system, dt, t1, x0, serial = case
    fine = spatial.fine_solver(system, "rk2", dt, n_threads=n_threads)
    assert fine.system.n_threads == n_threads
    np.testing.assert_array_equal(fine(0.0, t1, x0), serial)


def test_target_blocks_on_processes_equal_serial_fine_solver(case, pool):
    system, dt, t1, x0, serial = case
    fine = spatial.fine_solver(system, "rk2", dt, executor=pool)
    assert isinstance(fine.system.fluid, BlockedMRS) and fine.system.target_blocks.n_blocks == 2
    assert registry.compiled_loop(fine.system) is None  # the compiled loop would bypass blocks
    np.testing.assert_array_equal(fine(0.0, t1, x0), serial)


def test_target_blocks_fine_solver_evaluates_its_blocks(case, monkeypatch):
    """The wrapped system's compiled loop must not bypass the blocks: every rate evaluation of
    the fine solver goes through them (each block, twice per RK2 step)."""
    system, dt, t1, x0, serial = case
    calls = []

    def counting(*args):
        calls.append(len(args[0]))
        return real(*args)

    real = spatial.block_velocity
    monkeypatch.setattr(spatial, "block_velocity", counting)
    fine = spatial.fine_solver(system, "rk2", dt, executor=parallel.make_executor("serial"))
    np.testing.assert_array_equal(fine(0.0, t1, x0), serial)
    evaluations = 2 * round(t1 / dt)
    assert len(calls) == evaluations * fine.system.target_blocks.n_blocks
    assert sum(calls) == evaluations * len(x0)  # every target, once per evaluation


@pytest.mark.parametrize("n_blocks", [1, 3, 7])
def test_target_blocks_rates_equal_system_rates(case, n_blocks):
    """The blocked fluid is a second implementation of the same fluid: the same bits."""
    system, _, _, _, moved = case
    blocks = spatial.TargetBlocks(parallel.make_executor("serial"), n_blocks)
    blocked = dataclasses.replace(system, target_blocks=blocks)
    slices = blocks.slices(len(moved))
    assert sum(b.stop - b.start for b in slices) == len(moved)  # every target, once
    np.testing.assert_array_equal(blocked.rates(2e-6, moved), system.rates(2e-6, moved))
    assert blocked.params == system.params and type(blocked.fluid) is BlockedMRS
    assert type(system.fluid) is fluid.MRS and system.fluid.viscosity == system.viscosity


def test_measure_speedup_eq35(case):
    system, dt, t1, x0, _ = case
    serial = integrate.Propagator(system, "rk2", dt)
    result = spatial.measure_speedup(
        serial, spatial.fine_solver(system, "rk2", dt, n_threads=2), 0.0, t1, x0, repeats=2
    )
    assert result.difference == 0.0 and result.repeats == 2  # the threaded F is the serial F


def test_measure_speedup_is_eq35_on_a_known_clock(monkeypatch):
    """Eq. 35, Upsilon_F / Upsilon_sp, with each the total runtime of one whole solve over
    [t0, t1] from x0: on a clock that the two propagators advance by known amounts, the result is
    the best serial time over the best parallel time, the solves alternate, every one starts from
    the same x0 over the same interval, and ``difference`` is max |x_sp - x_F| / max |x_F|."""
    clock = [0.0]
    monkeypatch.setattr(spatial.time, "perf_counter", lambda: clock[0])
    calls = []
    x0 = np.array([[1.0, -4.0, 2.0]])

    def propagator(label, durations, offset):
        def run(t0, t1, x):
            calls.append((label, t0, t1, x.copy()))
            clock[0] += durations[sum(c[0] == label for c in calls) - 1]
            return x + offset

        return run

    serial = propagator("F", [5.0, 3.0, 4.0], 0.0)
    parallel = propagator("sp", [2.0, 2.5, 1.5], 1e-3)
    result = spatial.measure_speedup(serial, parallel, 0.25, 0.75, x0, repeats=3)
    assert (result.serial_time, result.parallel_time) == (3.0, 1.5)
    assert result.speedup == 2.0
    assert [c[0] for c in calls] == ["F", "sp"] * 3
    assert all(c[1:3] == (0.25, 0.75) and np.array_equal(c[3], x0) for c in calls)
    assert result.difference == pytest.approx(1e-3 / 4.0)


def test_threaded_fine_solver_in_parareal_on_processes(pool):
    # spatial and temporal together: the threaded F pickles and runs on the workers
    system, dt, t1 = CASES["rods"]
    x0 = system.initial_state()
    coarse = integrate.Propagator(system, "euler", 2e-6)
    serial = integrate.Propagator(system, "rk2", dt)
    threaded = spatial.fine_solver(system, "rk2", dt, n_threads=2)
    assert pickle.loads(pickle.dumps(threaded)) == threaded
    reference = parareal.run(serial, coarse, x0, 0.0, t1, 2, 0.0, 2)
    res = parareal.run(threaded, coarse, x0, 0.0, t1, 2, 0.0, 2, executor=pool)
    np.testing.assert_array_equal(res.states, reference.states)


def test_a_blocked_fluid_without_blocks_says_so():
    # regression: BlockedMRS without blocks failed at its first velocity with an AttributeError
    # on None; it is now refused when made
    with pytest.raises(ValueError, match="BlockedMRS needs blocks"):
        BlockedMRS(1.0)


def test_bad_arguments():
    system = CASES["vesicle"][0]
    executor = parallel.make_executor("serial")
    with pytest.raises(ValueError, match="exactly one of n_threads"):
        spatial.fine_solver(system, "rk2", 1e-3)
    with pytest.raises(ValueError, match="exactly one of n_threads"):
        spatial.fine_solver(system, "rk2", 1e-3, n_threads=2, executor=executor)
    with pytest.raises(ValueError, match="n_threads must be an integer >= 1"):
        spatial.threaded(system, 0)
    with pytest.raises(ValueError, match="n_blocks must be an integer >= 1"):
        spatial.TargetBlocks(executor, 0)
    with pytest.raises(TypeError, match="ToySystem has no target_blocks field"):
        spatial.fine_solver(ToySystem(), "rk2", 1e-3, executor=executor)
    with pytest.raises(TypeError, match="does not pickle"):
        pickle.dumps(spatial.fine_solver(system, "rk2", 1e-3, executor=executor))
    with pytest.raises(ValueError, match="repeats"):
        spatial.measure_speedup(None, None, 0.0, 1.0, np.zeros(3), repeats=0)
