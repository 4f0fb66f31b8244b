"""Solve the small Parareal rod problem with the pipelined schedule on MPI workers.

Run as ``mpiexec -n P python -m mpi4py.futures tests/mpi_scripts/parareal_pipelined.py OUT_DIR``;
writes states.npy, increments.npy and workers.json.
"""

import json
import pathlib
import sys

import numpy as np
import parareal_rod

from parastokes import parallel

if __name__ == "__main__":
    out = pathlib.Path(sys.argv[1])
    with parallel.make_executor("mpi") as executor:
        states, increments = parareal_rod.solve(executor, schedule="pipelined")
    np.save(out / "states.npy", states)
    np.save(out / "increments.npy", increments)
    (out / "workers.json").write_text(json.dumps(executor.workers))
