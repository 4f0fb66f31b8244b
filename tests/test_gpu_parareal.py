"""Parareal on the GPU executor (parallel.make_executor("gpu")) against the serial executor.

The parallel sweep of iteration k is one GPU batch of its N - k + 1 fine solves, each coarse step
one batch of its N_G auxiliary solvers, and the iterates agree with the CPU run: measured in the
simulator, max |GPU - CPU| = 8.7e-19 for states that move by 6.7e-4 (1.3e-15 relative); the
tolerance is 1e-12 relative.
"""

import subprocess
import sys

import numpy as np
import pytest
from gpu_setup import fast_simulator, gpu, small_rods, small_vesicle  # noqa: F401 (an autouse fixture)

from parastokes import config, integrate, parallel, parareal
from parastokes.run import session

pytestmark = pytest.mark.gpu


def _run(fine, coarse, x0, executor, iterations=2):
    return parareal.run(fine, coarse, x0, 0.0, 0.12, 3, 0.0, iterations, executor=executor,
                        project=fine.system.project)


def test_rod_parareal_iterates_match_the_cpu_and_sweeps_are_single_batches():
    rods = small_rods()
    x0 = rods.initial_state()
    fine = integrate.Propagator(rods, "rk2", 1e-2)
    coarse = parareal.extrapolated(rods, "euler", 0.03, lagrange={"bending": [1.1, 1.2]})
    cpu = _run(fine, coarse, x0, parallel.make_executor("serial"))
    with parallel.make_executor("gpu") as executor:
        result = _run(fine, coarse, x0, executor)
    motion = np.abs(cpu.states - x0).max()
    assert np.abs(result.states - cpu.states).max() <= 1e-12 * motion
    assert result.increments == pytest.approx(cpu.increments, rel=1e-9)
    # initial sweep: 3 coarse steps of N_G = 2; iteration 1: 3 fine solves, then 2 coarse steps;
    # iteration 2: the 2 remaining fine solves, then 1 coarse step
    assert executor.batches == [2, 2, 2, 3, 2, 2, 2, 2]


def test_vesicle_parareal_with_richardson_steps_in_one_batch():
    """Richardson's auxiliary solvers take different step counts within one batch."""
    vesicle = small_vesicle()
    x0 = vesicle.initial_state() * np.array([1.004, 1.0, 0.998])
    fine = integrate.Propagator(vesicle, "rk2", 1e-2)
    coarse = parareal.extrapolated(vesicle, "euler", 0.04, richardson={"m": 1, "r": 0.5})
    cpu = _run(fine, coarse, x0, parallel.make_executor("serial"), iterations=1)
    with parallel.make_executor("gpu") as executor:
        result = _run(fine, coarse, x0, executor, iterations=1)
    motion = np.abs(cpu.states - x0).max()
    assert np.abs(result.states - cpu.states).max() <= 1e-12 * motion


def test_coarse_grid_auxiliaries_are_batched_on_the_coarse_grid():
    rods = small_rods(n_points=5, length=4.0)  # coarsened by 2: 3 points per rod
    x0 = rods.initial_state()
    fine = integrate.Propagator(rods, "rk2", 1e-2)
    coarse = parareal.extrapolated(rods, "euler", 0.02, lagrange={"epsilon": [0.85, 0.9]}, grid=2)
    kw = dict(tol=0.0, max_iterations=1, project=rods.project)
    cpu = parareal.run(fine, coarse, x0, 0.0, 0.08, 2, executor=parallel.make_executor("serial"),
                       **kw)
    with parallel.make_executor("gpu") as executor:
        result = parareal.run(fine, coarse, x0, 0.0, 0.08, 2, executor=executor, **kw)
    assert executor.batches == [2, 2, 2, 2]
    assert np.abs(result.states - cpu.states).max() <= 1e-12 * np.abs(cpu.states - x0).max()


def test_a_failed_fine_solve_names_its_slice():
    x0 = small_rods().initial_state()
    wild = small_rods(viscosity=1e-4)  # blows up within the first slice's fine steps
    fine = integrate.Propagator(wild, "euler", 1e-2)
    coarse = integrate.Propagator(small_rods(), "euler", 5e-2)
    with parallel.make_executor("gpu") as executor, pytest.raises(parallel.TaskError) as error:
        parareal.run(fine, coarse, x0, 0.0, 0.15, 3, 0.0, 1, executor=executor)
    assert error.value.label == "fine solve of slice 1 in iteration 1"
    assert isinstance(error.value.original, integrate.BlowUpError)


def test_map_runs_one_batch():
    rods = small_rods()
    fine = integrate.Propagator(rods, "rk2", 1e-2)
    starts = [0.0, 0.02, 0.04]
    x0 = rods.initial_state()
    with parallel.make_executor("gpu") as executor:
        values = list(executor.map(fine, starts, [t + 0.02 for t in starts], [x0] * 3))
    assert executor.batches == [3]
    for t, value in zip(starts, values, strict=True):
        assert np.abs(value - fine(t, t + 0.02, x0)).max() <= 1e-15


def test_batch_holds_calls_until_it_closes_and_drops_them_on_error():
    with parallel.make_executor("gpu") as executor:
        with executor.batch():
            held = executor.submit(np.add, 1.0, 2.0)
            assert not held.done()
        assert held.result() == 3.0
        with pytest.raises(KeyError), executor.batch():
            dropped = executor.submit(np.add, 1.0, 2.0)
            raise KeyError
        assert dropped.cancelled()
        with executor.batch():
            asked = executor.submit(np.add, 2.0, 2.0)
            assert asked.result() == 4.0  # asking inside the batch runs it: no deadlock
    assert executor.batches == []  # none of these calls is a GPU solve


def test_make_executor_options_and_missing_gpu(monkeypatch):
    with pytest.raises(ValueError, match="threads_per_worker does not apply to kind='gpu'"):
        parallel.make_executor("gpu", threads_per_worker=2)
    monkeypatch.setattr(gpu.device, "available", lambda: False)
    with pytest.raises(RuntimeError, match=r"no CUDA GPU.*parastokes\[gpu\].*NUMBA_ENABLE_CUDASIM"):
        parallel.make_executor("gpu")


def test_config_gpu_executor_holds_every_solve_of_a_sweep():
    cfg = config.Config.model_validate(
        {
            "model": {"kind": "rod", "n_points": 7, "length": 6.0},
            "time": {"t1": 1e-5},
            "fine": {"dt": 1e-6},
            "coarse": {"dt_ratio": 2.0, "lagrange": {"bending": [1.1, 1.2, 1.3]}},
            "parareal": {"n_slices": 2},
            "execution": {"executor": "gpu"},
        }
    )
    resolved = config.resolve(cfg)
    assert resolved.workers == 3  # max(n_slices, N_G)
    with session.start(config.build(cfg, resolved)) as running:
        assert isinstance(running.executor, gpu.GPUExecutor)
        assert running.executor.workers == 3


def test_the_package_runs_without_importing_the_cuda_target():
    code = (
        "import sys; from parastokes import config, integrate, models, parallel, parareal; "
        "rod = models.rod(n_points=5, length=4.0, viscosity=1.0); "
        "f = integrate.Propagator(rod, 'rk2', 1e-2); "
        "parareal.run(f, f, rod.initial_state(), 0.0, 0.02, 2, 0.0, 1, "
        "executor=parallel.make_executor('serial')); "
        "assert 'numba.cuda' not in sys.modules"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=600)


@pytest.mark.parametrize(("launch", "message"), [(dict(threads=6), "power of two"),
                                                  (dict(tx=0), "tx: must be a positive")])
def test_bad_launch_shapes_are_refused(launch, message):
    with pytest.raises(ValueError, match=message):
        gpu.Launch(**launch)

