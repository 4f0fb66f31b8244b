"""Solve the small Parareal rod problem on MPI workers; write states.npy and increments.npy.

Run as ``mpiexec -n P python -m mpi4py.futures tests/mpi_scripts/parareal_run.py OUT_DIR``.
"""

import pathlib
import sys

import numpy as np
import parareal_rod

from parastokes import parallel

if __name__ == "__main__":
    out = pathlib.Path(sys.argv[1])
    with parallel.make_executor("mpi") as executor:
        states, increments = parareal_rod.solve(executor)
    np.save(out / "states.npy", states)
    np.save(out / "increments.npy", increments)
