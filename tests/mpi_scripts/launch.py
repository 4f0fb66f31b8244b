"""Launch the scripts of this folder under ``mpiexec`` from the tests."""

from __future__ import annotations

import importlib.util
import os
import pathlib
import shutil
import subprocess
import sys

REPO = pathlib.Path(__file__).resolve().parents[2]
SCRIPTS = REPO / "tests" / "mpi_scripts"
MPIEXEC = shutil.which("mpiexec")

#: Why the MPI tests are skipped, or None when mpiexec and mpi4py are there.
SKIP_REASON = (
    "needs mpiexec and mpi4py: pip install 'parastokes[mpi]'"
    if MPIEXEC is None or importlib.util.find_spec("mpi4py") is None
    else None
)

#: ``python -m mpi4py.futures SCRIPT``: rank 0 runs the script, the other ranks are the pool.
POOL = ["-m", "mpi4py.futures"]


def mpiexec(args: list[str], ranks: int = 2, timeout: float = 120) -> subprocess.CompletedProcess:
    """Run ``mpiexec -n ranks python ARGS`` from the repository root, one thread per rank."""
    env = dict(os.environ, OMP_NUM_THREADS="1", NUMBA_NUM_THREADS="1")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO), env.get("PYTHONPATH")]))
    return subprocess.run(
        [MPIEXEC, "-n", str(ranks), sys.executable, *args],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
    )
