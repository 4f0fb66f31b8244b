"""MPI executors, run for real under ``mpiexec -n 2`` (pool mode and communicator mode)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from mpi_scripts import parallel_tasks as tasks
from mpi_scripts.launch import POOL, SCRIPTS, SKIP_REASON, mpiexec

from parastokes import parallel

pytestmark = [pytest.mark.mpi, pytest.mark.skipif(SKIP_REASON is not None, reason=str(SKIP_REASON))]

LAUNCHES = {
    "pool": [*POOL, str(SCRIPTS / "pool_run.py")],
    "comm": [str(SCRIPTS / "comm_run.py")],
}


@pytest.mark.parametrize("launch", sorted(LAUNCHES))
def test_mpi_equals_serial_bit_for_bit(launch, tmp_path):
    run = mpiexec([*LAUNCHES[launch], str(tmp_path)])
    assert run.returncode == 0, run.stderr
    args = tasks.lorenz_args()
    labels = [f"case {i}" for i in range(len(args))]
    serial = np.stack(parallel.run_labelled(parallel.SerialExecutor(), tasks.lorenz, args, labels))
    assert np.array_equal(np.load(tmp_path / "results.npy"), serial)

    report = json.loads((tmp_path / "report.json").read_text())
    warm = [json.loads(p.read_text()) for p in (tmp_path / "warm").glob("*.json")]
    assert report["workers"] == 1
    # the warm-up ran on the one worker rank, which is the rank that ran the tasks
    assert len(warm) == 1 and set(report["task_pids"]) == {warm[0]["pid"]}
    assert warm[0]["numba_threads"] == 1
    assert report["error"] == {
        "label": "slice 2",
        "type": "ValueError",
        "message": "slice 2 failed: ValueError: negative length at node 2",
    }


def test_more_workers_than_ranks_fails_before_the_first_task(tmp_path):
    run = mpiexec([*LAUNCHES["pool"], str(tmp_path), "3"])
    assert run.returncode != 0
    assert "asked for 3 MPI workers but only 1 are available" in run.stderr
    assert not (tmp_path / "results.npy").exists()


def test_failing_warmup_fails_before_the_first_task(tmp_path):
    run = mpiexec([*LAUNCHES["pool"], str(tmp_path), "failing-warmup"])
    assert run.returncode != 0
    assert "the MPI workers failed to start" in run.stderr
    assert "OSError: no numba cache here" in run.stderr  # the worker's own traceback
    assert not (tmp_path / "results.npy").exists()


def test_an_aborted_run_cancels_the_queued_tasks_and_waits_for_the_running_one(tmp_path):
    # regression: MPI pools had no abort, so an interrupted run's close ran every queued task
    # of the sweep before the manager could exit
    run = mpiexec([*POOL, str(SCRIPTS / "abort_run.py"), str(tmp_path)])
    assert run.returncode == 0, run.stderr
    started = sorted(int(p.name) for p in (tmp_path / "started").iterdir())
    report = json.loads((tmp_path / "report.json").read_text())
    assert started[0] == 0 and len(started) <= 2  # the running task (and at most one sent next)
    assert report["cancelled"] == 6 - len(started)
