"""MPI executors through :mod:`mpi4py.futures`, for clusters.

Two launch modes:

- ``comm=None``: an :class:`mpi4py.futures.MPIPoolExecutor`. Under
  ``mpiexec -n P python -m mpi4py.futures script.py`` it uses the P - 1 other ranks as workers
  (no process spawning); otherwise it spawns workers with ``MPI_Comm_spawn``.
- ``comm`` given: an :class:`mpi4py.futures.MPICommExecutor` over that communicator, for use inside
  an existing MPI program. Every rank of ``comm`` calls :func:`make_mpi_executor`; the root gets the
  executor, the other ranks serve its tasks and get ``None`` once the root has shut it down.

The library never reaches for ``MPI.COMM_WORLD`` itself: the communicator is the caller's choice.
"""

from __future__ import annotations

import sys
import traceback
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Executor, Future
from typing import Any

from .worker import configure_worker, require_picklable

INSTALL_HINT = 'pip install "parastokes[mpi]"'


def _require_mpi4py() -> None:
    try:
        import mpi4py  # noqa: F401  (the package only: MPI itself starts when a pool is made)
    except ImportError as exc:
        raise ImportError(
            f"kind='mpi' needs mpi4py: {INSTALL_HINT} brings mpi4py and an MPI from PyPI; on a "
            "cluster, build mpi4py against the site's MPI instead (see docs/parallel.md)"
        ) from exc


def _initialize_rank(threads: int, warmup: Callable[[], Any] | None) -> None:
    """The workers' initializer: mpi4py drops its exceptions, so print them before re-raising."""
    try:
        configure_worker(threads, warmup)
    except Exception:
        print("parastokes: MPI worker set-up failed:", file=sys.stderr)
        traceback.print_exc()
        raise


class MPIExecutor(Executor):
    """An :mod:`mpi4py.futures` executor with the ``workers`` attribute of the other executors."""

    def __init__(self, pool: Executor, workers: int) -> None:
        """Wrap a started ``MPIPoolExecutor`` that has ``workers`` worker ranks."""
        self._pool = pool
        self.workers = workers

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future:
        """Schedule ``fn(*args, **kwargs)`` on a worker rank (``fn`` and arguments must pickle)."""
        return self._pool.submit(fn, *args, **kwargs)

    def map(
        self,
        fn: Callable[..., Any],
        *iterables: Iterable[Any],
        timeout: float | None = None,
        chunksize: int = 1,
    ) -> Iterator[Any]:
        """Like :func:`map`, the calls running on the worker ranks."""
        return self._pool.map(fn, *iterables, timeout=timeout, chunksize=chunksize)

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        """Release the worker ranks (in ``comm`` mode, they return from ``make_executor``)."""
        self._pool.shutdown(wait=wait, cancel_futures=cancel_futures)

    def abort(self) -> None:
        """Stop as soon as MPI allows: cancel the queued tasks; the tasks the worker ranks are
        running finish (mpi4py has no way to stop one), and a later :meth:`shutdown` waits for
        them only. For an interrupted or failed run."""
        self._pool.shutdown(wait=False, cancel_futures=True)


def make_mpi_executor(
    workers: int | None = None,
    *,
    comm: Any = None,
    root: int = 0,
    threads_per_worker: int = 1,
    warmup: Callable[[], Any] | None = None,
) -> MPIExecutor | None:
    """Start an MPI executor whose workers are limited to their threads and warmed up.

    Raises ``ImportError`` (naming the ``mpi`` extra) without mpi4py, and ``ValueError`` when
    more workers are asked for than the launch provides; both before any task runs. Returns ``None``
    on the non-root ranks of ``comm``, after they have served the root's tasks.
    """
    _require_mpi4py()
    initargs = (threads_per_worker, warmup)
    if comm is None:
        from mpi4py.futures import MPIPoolExecutor

        pool = MPIPoolExecutor(
            max_workers=workers, initializer=_initialize_rank, initargs=initargs
        )
    else:
        size = comm.Get_size()
        # Every rank checks, so that all of them stop together.
        if workers is not None and workers > max(1, size - 1):
            raise ValueError(
                f"asked for {workers} MPI workers but the communicator has {size} ranks "
                f"(one is the root): launch with mpiexec -n {workers + 1}"
            )
        from mpi4py.futures import MPICommExecutor

        # mpi4py's stub types __enter__ as Self | None; it returns the root's MPIPoolExecutor
        pool = MPICommExecutor(  # type: ignore[assignment]
            comm, root, initializer=_initialize_rank, initargs=initargs
        ).__enter__()
        if pool is None:
            return None
    available = pool.num_workers  # waits until the workers are up and initialized
    if not available:  # None or 0: the pool is broken
        pool.shutdown()
        raise RuntimeError(
            "the MPI workers failed to start: the warm-up or the thread set-up raised on a "
            "worker rank (the traceback is on stderr)"
        )
    if workers is not None and available < workers:  # (with comm, checked above)
        pool.shutdown()
        raise ValueError(
            f"asked for {workers} MPI workers but only {available} are available: launch with "
            f"mpiexec -n {workers + 1} python -m mpi4py.futures script.py"
        )
    return MPIExecutor(pool, available)


def make_mpi(
    workers: int | None, *, warmup: Callable[[], Any] | None = None, threads_per_worker: int = 1,
    comm: Any = None, root: int = 0, **_: Any,
) -> MPIExecutor | None:
    """The executor kind ``"mpi"`` (:func:`parastokes.parallel.make_executor`)."""
    require_picklable(warmup)
    return make_mpi_executor(
        workers, comm=comm, root=root, threads_per_worker=threads_per_worker, warmup=warmup
    )
