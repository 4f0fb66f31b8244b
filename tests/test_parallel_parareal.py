"""Serial, process-pool and MPI executors give bit-identical Parareal iterates on a rod problem."""

from __future__ import annotations

import numpy as np
import pytest
from mpi_scripts import parareal_rod
from mpi_scripts.launch import POOL, SCRIPTS, SKIP_REASON, mpiexec

from parastokes import parallel


@pytest.fixture(scope="module")
def serial():
    with parallel.make_executor("serial") as executor:
        return parareal_rod.solve(executor)


def test_serial_reference_iterates(serial):
    states, increments = serial
    assert states.shape[0] == parareal_rod.N_SLICES + 1 and np.all(np.isfinite(states))
    assert len(increments) == 3 and increments[-1] < increments[0]


def test_processes_equal_serial_bit_for_bit(serial):
    with parallel.make_executor("processes", 2) as executor:
        states, increments = parareal_rod.solve(executor)
    assert np.array_equal(states, serial[0])
    assert np.array_equal(increments, serial[1])


@pytest.mark.mpi
@pytest.mark.skipif(SKIP_REASON is not None, reason=str(SKIP_REASON))
def test_mpi_equals_serial_bit_for_bit(serial, tmp_path):
    run = mpiexec([*POOL, str(SCRIPTS / "parareal_run.py"), str(tmp_path)])
    assert run.returncode == 0, run.stderr
    assert np.array_equal(np.load(tmp_path / "states.npy"), serial[0])
    assert np.array_equal(np.load(tmp_path / "increments.npy"), serial[1])
