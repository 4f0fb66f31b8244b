"""Set-up run once in every worker process (process pool and MPI ranks) before its first task."""

from __future__ import annotations

import ctypes
import multiprocessing
import os
import pickle
import signal
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
    # This worker never forks; with the default start method "fork(server)" numba would guard
    # its thread launch with a process-shared semaphore that a killed worker leaks (the
    # resource tracker's "leaked semaphore" warning).
    multiprocessing.set_start_method("spawn", force=True)
    numba_loaded = "numba" in sys.modules
    for name in THREAD_VARIABLES:
        if not (numba_loaded and name == "NUMBA_NUM_THREADS"):
            os.environ[name] = str(threads)
    import numba

    numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
    if warmup is not None:
        warmup()


# prctl(2) option: the signal this process gets when its parent thread exits (Linux).
_PR_SET_PDEATHSIG = 1


def die_with_parent(parent: int) -> None:
    """Make this worker end when its parent (process ``parent``) does, even on SIGKILL.

    A worker started by the forkserver closes the forkserver's "alive" pipe that it inherits (the
    forkserver exits when the last holder of that pipe, now the manager alone, is gone), and on
    Linux has the kernel send it SIGKILL when the forkserver exits (``prctl(PR_SET_PDEATHSIG)``);
    a forkserver already gone by then makes it exit at once. Elsewhere (spawn, whose workers'
    parent is the manager *thread* that started them: the signal would fire when that thread
    ends) nothing is done: the workers then notice the manager's end only between tasks.
    SIGINT and SIGHUP are ignored: the manager handles Ctrl-C and hang-ups and stops its workers.
    """
    from multiprocessing import forkserver

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGHUP, signal.SIG_IGN)
    server = forkserver._forkserver  # the state a forkserver child inherits (private)
    alive_fd = getattr(server, "_forkserver_alive_fd", None)
    if alive_fd is None:  # not a forkserver child
        return
    os.close(alive_fd)
    # a private attribute of ForkServer, which typeshed does not declare
    server._forkserver_alive_fd = None  # type: ignore[attr-defined]
    if not sys.platform.startswith("linux"):
        return
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    except (OSError, AttributeError):  # no prctl: as elsewhere
        return
    if os.getppid() != parent:  # the parent died before prctl took effect
        os._exit(1)


def require_picklable(warmup: Callable[[], Any] | None) -> None:
    """ValueError unless ``warmup`` pickles (it is sent to the workers); checked before any
    worker starts (an MPI pool would hang on it)."""
    if warmup is not None:
        try:
            pickle.dumps(warmup)
        except Exception as error:
            raise ValueError(
                f"warmup must pickle to reach the workers (a module-level function, not a lambda "
                f"or closure): {error}"
            ) from None
