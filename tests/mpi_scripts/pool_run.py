"""Exercise make_executor("mpi") with an MPIPoolExecutor (no communicator given).

Run as ``mpiexec -n P python -m mpi4py.futures tests/mpi_scripts/pool_run.py OUT_DIR [WORKERS]``;
the warm-up writes one file per worker into OUT_DIR/warm, then see ``parallel_tasks.exercise``.
``WORKERS`` = ``failing-warmup``: all workers, with a warm-up that raises.
"""

import functools
import pathlib
import sys

import parallel_tasks

from parastokes import parallel

if __name__ == "__main__":
    out = pathlib.Path(sys.argv[1])
    option = sys.argv[2] if len(sys.argv) > 2 else None
    workers = int(option) if option and option.isdigit() else None
    (out / "warm").mkdir(parents=True, exist_ok=True)
    warmup = functools.partial(parallel_tasks.record_worker, str(out / "warm"))
    if option == "failing-warmup":
        warmup = parallel_tasks.failing_warmup
    with parallel.make_executor("mpi", workers, warmup=warmup) as executor:
        parallel_tasks.exercise(executor, str(out))
