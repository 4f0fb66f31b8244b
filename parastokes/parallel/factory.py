"""``make_executor``: one entry point for the serial, process-pool and MPI executors."""

from __future__ import annotations

import pickle
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, TypeAlias

from ..values import is_integer
from .mpi import make_mpi_executor
from .processes import ProcessExecutor
from .serial import SerialExecutor

if TYPE_CHECKING:  # the GPU backend is imported on use
    from ..gpu import GPUExecutor
    from .mpi import MPIExecutor

    #: The executors :func:`make_executor` makes, each with its ``workers``.
    WorkerPool: TypeAlias = SerialExecutor | ProcessExecutor | MPIExecutor | GPUExecutor

#: The kinds accepted by :func:`make_executor`.
KINDS = ("serial", "processes", "mpi", "gpu")


def make_executor(
    kind: str,
    workers: int | None = None,
    *,
    comm: Any = None,
    root: int = 0,
    warmup: Callable[[], Any] | None = None,
    threads_per_worker: int = 1,
    start_method: str | None = None,
) -> WorkerPool | None:
    """Make an executor with the ``concurrent.futures`` shape and a ``workers`` attribute.

    Args:
        kind: ``"serial"`` (in-process reference), ``"processes"`` (one machine), ``"mpi"``, or
            ``"gpu"`` (one CUDA GPU: the solves of a sweep run as one batch, see
            :class:`parastokes.gpu.GPUExecutor`; needs ``parastokes[gpu]``).
        workers: number of workers. ``serial``: 1 (``None`` means 1). ``processes``: default the
            available cores // ``threads_per_worker``. ``mpi``: default all the launch provides;
            more than it provides is an error. ``gpu``: the most solves per batch (``None``: no
            limit).
        comm: ``mpi`` only: run an ``MPICommExecutor`` over this communicator (every rank calls
            ``make_executor``; the root gets the executor, the other ranks serve tasks and get
            ``None`` once the root shuts it down). ``None``: an ``MPIPoolExecutor``.
        root: ``mpi`` with ``comm``: the rank that submits the tasks.
        warmup: a picklable callable run once on every worker (once in-process for ``serial``)
            before this function returns, e.g. to load numba caches before timing starts.
        threads_per_worker: numba/OpenMP/BLAS threads of each worker (``processes``, ``mpi``).
        start_method: ``processes`` only: ``"forkserver"`` (default where available) or
            ``"spawn"``.

    Raises:
        ValueError: unknown kind, ``workers`` < 1, an option that does not apply to ``kind``, or
            more MPI workers than the launch provides.
        ImportError: ``mpi`` without mpi4py (the message names the ``parastokes[mpi]`` extra), or
            ``gpu`` without numba's CUDA target (naming ``parastokes[gpu]``).
        RuntimeError: ``gpu`` where no CUDA GPU is found (nor numba-cuda's simulator).
    """
    if kind not in KINDS:
        raise ValueError(f"unknown executor kind {kind!r}; valid kinds: {', '.join(KINDS)}")
    if workers is not None and not is_integer(workers, 1):
        raise ValueError(f"workers must be an integer >= 1 (or None), got {workers!r}")
    if not is_integer(threads_per_worker, 1):
        raise ValueError(f"threads_per_worker must be an integer >= 1, got {threads_per_worker!r}")
    if kind != "mpi" and (comm is not None or root != 0):
        raise ValueError(f"comm and root apply to kind='mpi' only, not {kind!r}")
    if kind != "processes" and start_method is not None:
        raise ValueError(f"start_method applies to kind='processes' only, not {kind!r}")
    if kind == "serial":
        if workers not in (None, 1):
            raise ValueError(f"the serial executor has exactly 1 worker, not {workers}")
        if threads_per_worker != 1:
            raise ValueError("threads_per_worker does not apply to kind='serial'")
        return SerialExecutor(warmup)
    if kind == "gpu":
        if threads_per_worker != 1:
            raise ValueError("threads_per_worker does not apply to kind='gpu'")
        from ..gpu.device import cuda

        cuda()  # ImportError naming the extra, before the backend is imported
        from ..gpu import GPUExecutor

        return GPUExecutor(workers, warmup)
    if warmup is not None:  # (before any worker starts: an MPI pool would hang on it)
        try:
            pickle.dumps(warmup)
        except Exception as error:
            raise ValueError(
                f"warmup must pickle to reach the workers (a module-level function, not a lambda "
                f"or closure): {error}"
            ) from None
    if kind == "processes":
        return ProcessExecutor(
            workers, threads_per_worker=threads_per_worker, warmup=warmup, start_method=start_method
        )
    return make_mpi_executor(
        workers, comm=comm, root=root, threads_per_worker=threads_per_worker, warmup=warmup
    )
