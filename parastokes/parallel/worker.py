"""Set-up run once in every worker process (process pool and MPI ranks) before its first task."""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from typing import Any

#: Environment variables that size the thread pools of numba, OpenMP and the BLAS libraries.
THREAD_VARIABLES = (
    "NUMBA_NUM_THREADS",
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
)


def available_cores() -> int:
    """Number of cores this process may run on (its CPU affinity where the OS reports one)."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def configure_worker(threads: int, warmup: Callable[[], Any] | None) -> None:
    """Limit this worker to ``threads`` threads, then run ``warmup()`` once.

    The thread variables are set in the environment for the libraries that are not loaded yet;
    numba, whatever its state, is limited with :func:`numba.set_num_threads` (to at most the size of
    its pool, fixed when numba was first imported). ``NUMBA_NUM_THREADS`` is left alone when numba
    is already loaded (e.g. by unpickling a warm-up that holds a system): numba re-reads it when it
    compiles and refuses a value that differs from its running pool. A BLAS that is already loaded
    keeps its pool: set ``OMP_NUM_THREADS`` before starting Python to limit it too (see
    docs/parallel.md).
    """
    numba_loaded = "numba" in sys.modules
    for name in THREAD_VARIABLES:
        if not (numba_loaded and name == "NUMBA_NUM_THREADS"):
            os.environ[name] = str(threads)
    import numba

    numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
    if warmup is not None:
        warmup()
