"""An interrupted run's abort on an MPI pool: queued tasks are cancelled, not run.

Run as ``mpiexec -n 2 python -m mpi4py.futures tests/mpi_scripts/abort_run.py OUT_DIR``: six tasks
of 0.5 s on one worker rank; once the first runs, ``Session.abort`` (what the runner calls on
Ctrl-C or SIGTERM) then ``Session.close``. Each task that starts writes a file to
OUT_DIR/started; ``OUT_DIR/report.json`` has the number of cancelled futures.
"""

import json
import pathlib
import sys
import time

import parallel_tasks

from parastokes import parallel
from parastokes.run.session import Session

if __name__ == "__main__":
    out = pathlib.Path(sys.argv[1])
    (out / "started").mkdir(parents=True, exist_ok=True)
    executor = parallel.make_executor("mpi", 1)
    futures = [executor.submit(parallel_tasks.mark_and_sleep, str(out / "started"), i, 0.5)
               for i in range(6)]
    while not any(f.running() or f.done() for f in futures):
        time.sleep(0.01)
    running = Session(setup=None, executor=executor)  # type: ignore[arg-type]
    running.abort()
    running.close()
    report = {"cancelled": sum(f.cancelled() for f in futures)}
    (out / "report.json").write_text(json.dumps(report))
