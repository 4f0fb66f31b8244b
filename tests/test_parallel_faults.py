"""Faults and misconfigurations of a Parareal run on an executor (issue 5, item 4).

A solve that raises, a worker that dies or a Ctrl-C stops the run with an error naming the slice
and the iteration; the checkpoint holds the last completed iteration; rerunning without the fault
resumes and gives results bit-identical to a fault-free run. Misconfigurations (N_G > N_c, more
workers than slices) are caught before the first task.
"""

from __future__ import annotations

import functools
import logging
import os
import warnings
from concurrent.futures import Future

import numpy as np
import pytest
from odes import (
    CompilesInWorker,
    FailsOnSlice,
    FaultyToySystem,
    Logistic,
    Recording,
    Sleeping,
    Stepper,
    ToySystem,
)

from parastokes import integrate, parallel, parareal
from parastokes.parareal import checkpoint as ckpt

T0, T1, N_SLICES, ITERATIONS = 0.0, 1.2, 6, 4
X0 = np.array([0.1, 0.3])
FINE = Stepper(Logistic(3.0), 1e-3, order=4)
COARSE = Stepper(Logistic(3.0), 0.05, order=1)
TIMES = parareal.time_points(T0, T1, N_SLICES)
SLICE, ITERATION = 3, 2  # the fault: the fine solve of slice 3 in iteration 2


class FakeExecutor:
    """In-process executor that claims ``workers`` workers and records what it is given."""

    def __init__(self, workers: int) -> None:
        self.workers = workers
        self.submitted = []

    def submit(self, fn, *args):
        self.submitted.append(fn)
        future = Future()
        try:
            future.set_result(fn(*args))
        except Exception as exc:
            future.set_exception(exc)
        return future


def _run(fine, executor=None, checkpoint=None):
    return parareal.run(
        fine,
        COARSE,
        X0,
        T0,
        T1,
        N_SLICES,
        tol=0.0,
        max_iterations=ITERATIONS,
        executor=executor,
        reference=REFERENCE,
        checkpoint=checkpoint,
    )


REFERENCE = parareal.serial_solution(FINE, X0, T0, T1, N_SLICES)
CLEAN = _run(FINE)


def _faulty(tmp_path, mode="raise"):
    markers = tmp_path / "markers"
    markers.mkdir()
    return FailsOnSlice(FINE, TIMES[SLICE - 1], ITERATION, markers, mode)


def _assert_resumes_bit_identically(path, executor=None):
    key = ckpt.fingerprint(X0, T0, T1, N_SLICES, REFERENCE)
    assert ckpt.load(path, key).iteration == ITERATION - 1  # the completed iterations are kept
    res = _run(FINE, executor, path)  # no fault this time
    assert res.iterations == ITERATIONS
    np.testing.assert_array_equal(res.states, CLEAN.states)
    assert res.increments == CLEAN.increments and res.errors == CLEAN.errors
    assert [len(f) for f in res.timings.fine] == [6, 5, 4, 3]


@pytest.fixture(scope="module")
def pool():
    with parallel.make_executor("processes", 2) as executor:
        yield executor


@pytest.mark.parametrize("kind", ["in-process", "serial", "processes"])
def test_failing_fine_solve_names_slice_and_iteration_and_resumes(kind, tmp_path, request):
    executor = {
        "in-process": lambda: None,
        "serial": lambda: parallel.make_executor("serial"),
        "processes": lambda: request.getfixturevalue("pool"),
    }[kind]()
    path = tmp_path / "run.npz"
    with pytest.raises(parallel.TaskError) as info:
        _run(_faulty(tmp_path), executor, path)
    err = info.value
    assert err.label == f"fine solve of slice {SLICE} in iteration {ITERATION}"
    assert str(err).startswith(
        f"fine solve of slice {SLICE} in iteration {ITERATION} failed: RuntimeError: injected"
    )
    assert isinstance(err.original, RuntimeError) and err.__cause__ is err.original
    assert any("holds iteration 1" in note for note in err.__notes__)
    _assert_resumes_bit_identically(path, executor)


def test_dead_worker_names_slice_and_iteration_and_resumes(tmp_path):
    path = tmp_path / "run.npz"
    with parallel.make_executor("processes", 2) as executor:
        with pytest.raises(parallel.TaskError) as info:
            _run(_faulty(tmp_path, "exit"), executor, path)
    err = info.value
    assert err.label == f"fine solve of slice {SLICE} in iteration {ITERATION}"
    assert isinstance(err.original, parallel.WorkerDiedError) and err.original.exitcode == 3
    _assert_resumes_bit_identically(path)  # the broken pool is gone: resume in-process


def test_interrupt_leaves_a_resumable_checkpoint(tmp_path):
    path = tmp_path / "run.npz"
    with pytest.raises(KeyboardInterrupt):
        _run(_faulty(tmp_path, "interrupt"), parallel.make_executor("serial"), path)
    _assert_resumes_bit_identically(path)


def test_interrupt_while_writing_the_checkpoint_keeps_the_previous_one(tmp_path, monkeypatch):
    path = tmp_path / "run.npz"
    original = np.savez
    writes = []

    def interrupted_savez(handle, **arrays):  # the third checkpoint (iteration 2) is cut short
        writes.append("states" in arrays)  # (the solves kept as they complete are written too)
        if sum(writes) == ITERATION + 1 and writes[-1]:
            handle.write(b"PK\x03\x04 half a zip file")
            raise KeyboardInterrupt
        original(handle, **arrays)

    monkeypatch.setattr(np, "savez", interrupted_savez)
    with pytest.raises(KeyboardInterrupt):
        _run(FINE, None, path)
    monkeypatch.setattr(np, "savez", original)
    _assert_resumes_bit_identically(path)


@pytest.mark.parametrize("workers", [1, 4])
def test_failing_auxiliary_coarse_solver_is_named(workers):
    system = FaultyToySystem(fail_a=0.7, fail_after=0.5, n_points=2, decay=1.0, a=0.5)
    coarse = parareal.extrapolated(
        system, "euler", 0.1, lagrange={"a": [0.6, 0.7]}, richardson={"m": 1, "r": 0.5}
    )
    fine = integrate.Propagator(system, "rk2", 0.01)
    with pytest.raises(parallel.TaskError) as info:
        parareal.run(
            fine,
            coarse,
            system.initial_state(),
            0.0,
            1.0,
            4,
            0.0,
            2,
            executor=FakeExecutor(workers),
        )
    # slice 3 = [0.5, 0.75] is the first to reach t >= 0.5; solver 2 is (a=0.7, step 0.1)
    assert info.value.label == (
        "auxiliary coarse solver 2 (a=0.7, step 0.1) in the coarse solve of slice 3 in iteration 0"
    )
    assert "RuntimeError: injected fault at t=0.5" in str(info.value)


def test_fine_times_are_run_times_not_queue_waits():
    # 4 slices of 0.3 s on 2 workers: the 3rd and 4th tasks wait 0.3 s for a worker. The warm-up
    # imports this test's helper module on the workers, so that the first tasks do not pay for it.
    fine = Sleeping(Stepper(Logistic(3.0), 0.1, order=1), 0.3)
    warmup = functools.partial(Logistic, 3.0)
    with parallel.make_executor("processes", 2, warmup=warmup) as executor:
        res = parareal.run(fine, COARSE, X0, T0, T1, 4, 0.0, 1, executor=executor)
    assert len(res.timings.fine[0]) == 4
    assert all(0.29 < t < 0.45 for t in res.timings.fine[0]), res.timings.fine[0]
    assert 0.59 < res.timings.parallel_sweeps[0] < 0.9


# ---- misconfigurations, caught before any work -------------------------------------------------


def _extrapolated_problem(**kwargs):
    system = ToySystem(n_points=2, decay=1.0, a=0.5)
    coarse = parareal.extrapolated(
        system, "euler", 0.1, lagrange={"a": [0.6, 0.7]}, richardson={"m": 1, "r": 0.5}, **kwargs
    )
    return system, coarse, integrate.Propagator(system, "rk2", 0.01)


def test_more_auxiliary_solvers_than_workers_is_an_error_before_any_work():
    system, coarse, fine = _extrapolated_problem()
    fine = Recording(fine)
    with pytest.raises(ValueError, match=r"N_G = 4 auxiliary solvers .* only N_c = 2 workers"):
        parareal.run(fine, coarse, system.initial_state(), 0.0, 1.0, 4, 0.0, 2, FakeExecutor(2))
    assert fine.calls == []
    system = ToySystem(n_points=5, decay=1.0, a=0.5)
    fine = Recording(integrate.Propagator(system, "rk2", 0.01))
    grid = parareal.extrapolated(system, "euler", 0.1, lagrange={"a": [0.6, 0.7, 0.8]}, grid=2)
    with pytest.raises(ValueError, match=r"N_G = 3 .* N_c = 2"):  # seen through OnCoarseGrid
        parareal.run(fine, grid, system.initial_state(), 0.0, 1.0, 4, 0.0, 2, FakeExecutor(2))
    assert fine.calls == []
    with pytest.raises(ValueError, match=r"N_G = 4 .* N_c = 3 .* allow_oversubscribe=True"):
        _extrapolated_problem(executor=FakeExecutor(3))


def test_allow_oversubscribe_batches_per_worker_and_warns(caplog):
    system, coarse, fine = _extrapolated_problem()
    x0 = system.initial_state()
    plain = parareal.run(fine, coarse, x0, 0.0, 1.0, 4, 0.0, 2)
    executor = FakeExecutor(2)
    with caplog.at_level(logging.WARNING, logger="parastokes.parareal"):
        res = parareal.run(
            fine, coarse, x0, 0.0, 1.0, 4, 0.0, 2, executor=executor, allow_oversubscribe=True
        )
    assert "ceil(4/2) = 2 rounds" in caplog.text
    np.testing.assert_array_equal(res.states, plain.states)
    batches = [fn for fn in executor.submitted if fn is not fine]
    assert len(batches) == 2 * (4 + 3 + 2)  # 2 batches (of 2 solvers) per G call
    _, own, _ = _extrapolated_problem(executor=FakeExecutor(3), allow_oversubscribe=True)
    np.testing.assert_array_equal(own(0.0, 0.25, x0), coarse(0.0, 0.25, x0))


def test_one_worker_executor_is_not_checked():
    system, coarse, fine = _extrapolated_problem()
    executor = FakeExecutor(1)
    parareal.run(fine, coarse, system.initial_state(), 0.0, 1.0, 4, 0.0, 1, executor=executor)
    assert len([fn for fn in executor.submitted if fn is not fine]) == 4 * (4 + 3)


def test_more_workers_than_slices_warns_before_any_work():
    fine, coarse = Recording(FINE), Recording(COARSE)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # stop at the warning: nothing ran yet
        with pytest.raises(RuntimeWarning, match="8 workers but the run has only 6 slices"):
            parareal.run(fine, coarse, X0, T0, T1, N_SLICES, 0.0, 1, executor=FakeExecutor(8))
    assert fine.calls == [] and coarse.calls == []
    with pytest.warns(RuntimeWarning, match=r"2 workers stay idle .* n_slices=8"):
        res = parareal.run(FINE, COARSE, X0, T0, T1, N_SLICES, 0.0, 1, executor=FakeExecutor(8))
    assert res.iterations == 1


@pytest.mark.skipif(
    parallel.available_cores() < 2 or "NUMBA_NUM_THREADS" in os.environ,
    reason="needs numba's default pool (>= 2 threads) to differ from the worker's 1 thread",
)
def test_warmup_that_loads_numba_before_the_thread_limits_can_compile():
    # numba refuses to compile once NUMBA_NUM_THREADS differs from its running pool: a worker must
    # not change it after the warm-up (unpickled first) has loaded numba
    with parallel.make_executor("processes", 1, warmup=CompilesInWorker()) as executor:
        assert executor.submit(CompilesInWorker()).result() == 2


def test_aborting_with_cancelled_queued_tasks_leaves_no_traceback_in_the_pool_thread(monkeypatch):
    """Ctrl-C or SIGTERM in a parallel sweep: the queued tasks are cancelled, then the workers
    killed. CPython 3.11's pool then marks every queued task failed, the cancelled ones too,
    which raised InvalidStateError in its manager thread: a traceback under the one-line message."""
    import threading
    import time

    from parastokes.parallel import ProcessExecutor

    seen: list[BaseException] = []
    monkeypatch.setattr(threading, "excepthook", lambda args: seen.append(args.exc_value))
    executor = ProcessExecutor(2)
    futures = [executor.submit(time.sleep, 30) for _ in range(10)]
    time.sleep(0.5)  # two running, one in the call queue, the rest queued
    cancelled = [f for f in futures if f.cancel()]
    executor.abort()
    executor.shutdown()
    assert len(cancelled) >= 5
    assert not seen, seen
