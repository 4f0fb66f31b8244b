"""Serial and process-pool executors, make_executor's checks, and labelled task errors."""

from __future__ import annotations

import functools
import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from mpi_scripts import parallel_tasks as tasks

from parastokes import parallel


@pytest.fixture(scope="module")
def pool():
    """Two worker processes, shared by the tests that leave the pool healthy."""
    with parallel.make_executor("processes", 2) as executor:
        yield executor


def _labels(n: int) -> list[str]:
    return [f"slice {i}" for i in range(n)]


# --- make_executor -------------------------------------------------------------------------------


def test_unknown_kind_names_the_valid_ones():
    with pytest.raises(ValueError, match=r"kind 'threads'; valid kinds: serial, processes, mpi"):
        parallel.make_executor("threads")


@pytest.mark.parametrize("kind", parallel.KINDS)
@pytest.mark.parametrize("workers", [0, -2])
def test_fewer_than_one_worker_is_refused(kind, workers):
    with pytest.raises(ValueError, match="workers must be an integer >= 1"):
        parallel.make_executor(kind, workers)


@pytest.mark.parametrize(
    ("kind", "options", "message"),
    [
        ("serial", {"workers": 2}, "exactly 1 worker"),
        ("serial", {"threads_per_worker": 4}, "threads_per_worker does not apply"),
        ("processes", {"comm": object()}, "comm and root apply to kind='mpi' only"),
        ("processes", {"threads_per_worker": 0}, "threads_per_worker must be an integer >= 1"),
        ("processes", {"start_method": "fork"}, "numba's threading layer"),
        ("mpi", {"start_method": "spawn"}, "start_method applies to kind='processes' only"),
    ],
)
def test_options_that_do_not_apply_are_refused(kind, options, message):
    with pytest.raises(ValueError, match=message):
        parallel.make_executor(kind, **options)


def test_mpi_without_mpi4py_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "mpi4py", None)  # makes `import mpi4py` fail
    with pytest.raises(ImportError, match=r'pip install "parastokes\[mpi\]"'):
        parallel.make_executor("mpi", 2)


class _TwoRanks:
    """Stands in for a communicator of 2 ranks (only its size is read before the check)."""

    def Get_size(self) -> int:
        return 2


@pytest.mark.skipif(importlib.util.find_spec("mpi4py") is None, reason="mpi4py is not installed")
def test_mpi_comm_with_too_few_ranks_is_refused_before_starting():
    with pytest.raises(ValueError, match="asked for 3 MPI workers but the communicator has 2"):
        parallel.make_executor("mpi", 3, comm=_TwoRanks())


def test_an_executor_kind_from_outside_the_package_runs_parareal_as_the_serial_one():
    """The registry finds a kind by "module:make" (tests/user_executor.py): Parareal on it gives
    the serial executor's states bit for bit, and its tasks went through it."""
    from odes import Stepper, oscillator

    from parastokes import parareal

    problem = oscillator()
    fine, coarse = Stepper(problem, 0.01, 4), Stepper(problem, 0.1, 1)
    runs = {}
    for kind in ("serial", "user_executor:make_recording"):
        with parallel.make_executor(kind, 1) as ex:
            runs[kind] = parareal.run(fine, coarse, np.array([1.0, 0.0]), t0=0.0, t1=2.0,
                                      n_slices=4, tol=0.0, max_iterations=2, executor=ex)
    np.testing.assert_array_equal(runs["serial"].states,
                                  runs["user_executor:make_recording"].states)
    assert ex.ran and set(ex.ran) <= {"Stepper", "_Timed", "partial"}, ex.ran
    with pytest.raises(ValueError, match="has 1 worker"):
        parallel.make_executor("user_executor:make_recording", 2)
    with pytest.raises(ImportError, match="cannot import module 'no_such_module'"):
        parallel.make_executor("no_such_module:make")


def test_importing_the_executors_imports_no_backend():
    """The factory names its kinds by strings: the GPU backend (and numba.cuda) load only when
    kind="gpu" is asked for."""
    code = ("import sys; from parastokes import parallel; "
            "assert 'parastokes.gpu' not in sys.modules and 'numba.cuda' not in sys.modules, "
            "sorted(m for m in sys.modules if 'gpu' in m or 'cuda' in m)")
    root = str(Path(__file__).resolve().parents[1])
    subprocess.run([sys.executable, "-c", code], check=True, env=os.environ | {"PYTHONPATH": root})


# --- serial --------------------------------------------------------------------------------------


def test_serial_runs_at_submit_and_keeps_exceptions_in_the_future():
    calls = []
    with parallel.make_executor("serial", warmup=functools.partial(calls.append, "warm")) as ex:
        assert ex.workers == 1
        assert calls == ["warm"]
        done = ex.submit(calls.append, "task")
        assert done.done() and calls == ["warm", "task"]
        failed = ex.submit(tasks.fail_on, 3, 3)
        assert isinstance(failed.exception(), ValueError)
        assert list(ex.map(tasks.fail_on, [1, 2], [0, 0])) == [1, 2]
    with pytest.raises(RuntimeError, match="after shutdown"):
        ex.submit(calls.append, "late")


def test_serial_error_names_the_task_and_stops_the_batch():
    ran = []

    def record_then_fail(index: int) -> int:
        ran.append(index)
        return tasks.fail_on(index, 2)

    with parallel.make_executor("serial") as ex:
        with pytest.raises(parallel.TaskError) as info:
            parallel.run_labelled(ex, record_then_fail, [(i,) for i in range(5)], _labels(5))
    assert info.value.label == "slice 2"
    assert isinstance(info.value.original, ValueError)
    assert str(info.value) == "slice 2 failed: ValueError: negative length at node 2"
    assert ran == [0, 1, 2]


def test_run_labelled_needs_one_label_per_call():
    with pytest.raises(ValueError, match="3 argument tuples but 2 labels"):
        parallel.run_labelled(parallel.SerialExecutor(), tasks.fail_on, [(0, 9)] * 3, ["a", "b"])


# --- processes -----------------------------------------------------------------------------------


def test_processes_equal_serial_bit_for_bit(pool):
    args = tasks.lorenz_args()
    serial = parallel.run_labelled(parallel.SerialExecutor(), tasks.lorenz, args, _labels(5))
    parallel_ = parallel.run_labelled(pool, tasks.lorenz, args, _labels(5))
    mapped = list(pool.map(tasks.lorenz, *zip(*args, strict=True)))
    assert pool.start_method == "forkserver"
    for reference, a, b in zip(serial, parallel_, mapped, strict=True):
        assert a.dtype == np.float64 and a.shape == (tasks.LORENZ_STEPS + 1, 3)
        assert np.array_equal(a, reference) and np.array_equal(b, reference)


def test_processes_error_names_the_task(pool):
    with pytest.raises(parallel.TaskError) as info:
        parallel.run_labelled(pool, tasks.fail_on, [(i, 2) for i in range(5)], _labels(5))
    assert info.value.label == "slice 2"
    assert isinstance(info.value.original, ValueError)
    assert info.value.__cause__ is info.value.original
    # the pool is still usable, and it runs tasks on its workers only
    pids = list(pool.map(tasks.pid_after, [0.05] * 4))
    assert set(pids) <= set(pool.worker_pids)


def test_the_first_failure_in_submission_order_is_reported(pool):
    batch = [
        parallel.Task(tasks.pid_after, (0.05,), "slice 0"),
        parallel.Task(tasks.fail_after, (0.5, "slow"), "slice 1"),
        parallel.Task(tasks.pid_after, (0.0,), "slice 2"),
        parallel.Task(tasks.fail_after, (0.0, "fast"), "slice 3"),
    ]
    with pytest.raises(parallel.TaskError, match="slice 1 failed: RuntimeError: slow"):
        parallel.run_tasks(pool, batch)


def test_warmup_and_thread_limit_run_on_every_worker(tmp_path):
    threads = parallel.available_cores()  # 2 workers x all cores: oversubscribed everywhere
    warmup = functools.partial(tasks.record_worker, str(tmp_path))
    with pytest.warns(RuntimeWarning, match="oversubscribe"):
        ex = parallel.make_executor("processes", 2, warmup=warmup, threads_per_worker=threads)
    with ex:
        records = [json.loads(p.read_text()) for p in tmp_path.glob("*.json")]
        assert sorted(r["pid"] for r in records) == sorted(ex.worker_pids)
        assert len(set(ex.worker_pids)) == 2
        assert [r["numba_threads"] for r in records] == [threads, threads]
        assert set(ex.map(tasks.pid_after, [0.05] * 4)) <= set(ex.worker_pids)


def test_failing_warmup_is_reported_at_creation():
    with pytest.raises(RuntimeError, match=r"starting the worker processes failed.*no numba cache"):
        parallel.make_executor("processes", 2, warmup=tasks.failing_warmup)


@pytest.mark.timeout(60)
def test_dying_worker_names_its_task_instead_of_hanging():
    # slice 0 is still running on the other worker when slice 1's worker exits: the error must
    # name slice 1 (the cause), not slice 0 (the first task to lose its pool).
    args = [(i, 1, 0.3 if i == 1 else 1.0) for i in range(4)]
    with parallel.make_executor("processes", 2) as ex:
        with pytest.raises(parallel.TaskError) as info:
            parallel.run_labelled(ex, tasks.die_on, args, _labels(4))
    error = info.value
    assert error.label == "slice 1"
    assert isinstance(error.original, parallel.WorkerDiedError)
    assert error.original.exitcode == 7 and error.original.pid in ex.worker_pids
    assert str(error).startswith("slice 1 failed: WorkerDiedError: worker process")


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


@pytest.mark.timeout(60)
def test_no_worker_outlives_a_pool_that_a_dying_worker_broke():
    """The first task's worker dies while the others run: after the error and shutdown, every
    worker process is gone (regression: cancelling the pending tasks raced with the pool marking
    them failed, its manager thread crashed and the surviving worker was left running)."""
    args = [(i, 0, 0.1 if i == 0 else 1.0) for i in range(8)]
    with parallel.make_executor("processes", 2) as ex:
        with pytest.raises(parallel.TaskError, match="slice 0 failed: WorkerDiedError"):
            parallel.run_labelled(ex, tasks.die_on, args, _labels(8))
    assert not [pid for pid in ex.worker_pids if _alive(pid)]


@pytest.mark.parametrize(
    ("options", "named"),
    [({"workers": "2"}, "workers"), ({"workers": 2.0}, "workers"), ({"workers": True}, "workers"),
     ({"threads_per_worker": 1.5}, "threads_per_worker"),
     ({"threads_per_worker": "2"}, "threads_per_worker"),
     ({"warmup": lambda: None}, "warmup must pickle")],
)
def test_bad_executor_options_are_named_before_any_worker_starts(options, named):
    with pytest.raises(ValueError, match=named):
        parallel.make_executor("processes", **options)


@pytest.mark.timeout(60)
def test_ctrl_c_during_start_up_does_not_wait_for_the_warm_ups():
    """Workers ignore SIGINT: an interrupt while they warm up kills them at once (regression: it
    waited for every warm-up, up to a minute of first compilations)."""
    import os
    import signal
    import threading
    import time

    # a real SIGINT (it interrupts a blocking wait), handled as Ctrl-C even where this suite runs
    # with SIGINT ignored (a background job)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        threading.Timer(1.0, os.kill, (os.getpid(), signal.SIGINT)).start()
        start = time.monotonic()
        with pytest.raises(KeyboardInterrupt):
            parallel.make_executor("processes", 2, warmup=tasks.slow_warmup)
        assert time.monotonic() - start < 15.0  # the warm-ups alone take 20 s
    finally:
        signal.signal(signal.SIGINT, previous)


@pytest.mark.timeout(120)
def test_spawned_workers_outlive_the_thread_that_started_them():
    """With spawn, a worker's parent is the thread that started it; the kernel's parent-death
    signal would kill the workers when that thread ends (regression: the pool broke)."""
    import os
    import threading

    made = {}
    thread = threading.Thread(
        target=lambda: made.update(ex=parallel.make_executor("processes", 2, start_method="spawn")))
    thread.start()
    thread.join()
    with made["ex"] as ex:
        workers = set(ex.worker_pids)
        assert len(workers) == 2 and os.getpid() not in workers
        ran_on = set(ex.map(tasks.pid_after, [0.05] * 4))
        assert ran_on and ran_on <= workers  # the tasks ran on the pool's own workers
        assert list(ex.map(abs, [-1, -2])) == [1, 2]
        for pid in workers:  # both still alive after the starting thread ended and the tasks ran
            os.kill(pid, 0)
        assert set(ex.worker_pids) == workers  # none replaced
