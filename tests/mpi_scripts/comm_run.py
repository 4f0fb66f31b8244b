"""Exercise make_executor("mpi", comm=...) inside an MPI program (MPICommExecutor).

Run as ``mpiexec -n P python tests/mpi_scripts/comm_run.py OUT_DIR``; rank 0 submits, the other
ranks serve. The warm-up writes one file per worker into OUT_DIR/warm, then see
``parallel_tasks.exercise``.
"""

import functools
import pathlib
import sys

import parallel_tasks
from mpi4py import MPI

from parastokes import parallel

if __name__ == "__main__":
    out = pathlib.Path(sys.argv[1])
    comm = MPI.COMM_WORLD
    if comm.Get_rank() == 0:
        (out / "warm").mkdir(parents=True, exist_ok=True)
    comm.Barrier()
    warmup = functools.partial(parallel_tasks.record_worker, str(out / "warm"))
    executor = parallel.make_executor("mpi", comm=comm, warmup=warmup)
    if executor is not None:  # the root; the other ranks served its tasks inside make_executor
        with executor:
            parallel_tasks.exercise(executor, str(out))
