"""``make_executor``: one entry point for every executor kind, found by name in a registry.

An executor kind is a callable ``make(workers, *, warmup, threads_per_worker, comm, root,
start_method)`` that checks the options of its kind and returns the executor (the
``concurrent.futures`` shape with a ``workers`` attribute). It is named by:

- a built-in name, a key of :data:`BUILTIN` whose value is its ``"module:make"`` (serial,
  processes, mpi, gpu);
- ``"package.module:make"``;
- an entry point of the group :data:`ENTRY_POINT_GROUP` (installed packages).

Its module is imported only when the kind is asked for (:mod:`parastokes.core.plugins`, as the body
and coarse-solver registries do), so this module imports no backend: the GPU's lives in
:mod:`parastokes.gpu.executor`, above the executors, and names no body kind.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any, TypeAlias

from ..core import plugins
from ..core.values import is_integer

if TYPE_CHECKING:  # names for the type checker only: a kind's module is imported when asked for
    from ..gpu import GPUExecutor
    from .mpi import MPIExecutor
    from .processes import ProcessExecutor
    from .serial import SerialExecutor

    #: The executors :func:`make_executor` makes, each with its ``workers``.
    WorkerPool: TypeAlias = SerialExecutor | ProcessExecutor | MPIExecutor | GPUExecutor

__all__ = ["BUILTIN", "ENTRY_POINT_GROUP", "KINDS", "executor_maker", "make_executor"]

#: The built-in executor kinds: name -> ``"module:make"`` (imported on first use).
BUILTIN: dict[str, str] = {
    "serial": "parastokes.parallel.serial:make_serial",
    "processes": "parastokes.parallel.processes:make_processes",
    "mpi": "parastokes.parallel.mpi:make_mpi",
    "gpu": "parastokes.gpu.executor:make_gpu",
}

#: The entry point group of installed executor kinds: ``name = "package.module:make"``.
ENTRY_POINT_GROUP = "parastokes.executors"

#: The built-in kinds accepted by :func:`make_executor` (installed ones come on top).
KINDS = tuple(BUILTIN)

#: What to install when a built-in kind's module cannot be imported.
_EXTRAS = {"gpu": 'pip install "parastokes[gpu]" (numba-cuda)'}


class UnknownExecutorError(ValueError):
    """A kind that names no built-in, importable or installed executor kind."""


def _unknown(kind: str) -> Callable[[list[str]], UnknownExecutorError]:
    def error(known: list[str]) -> UnknownExecutorError:
        names = [*BUILTIN, *sorted(set(known) - set(BUILTIN))]
        return UnknownExecutorError(
            f"unknown executor kind {kind!r}; valid kinds: {', '.join(names)}"
        )

    return error


def _target(kind: str) -> str:
    """The ``"module:make"`` of ``kind`` (nothing imported); ValueError naming the valid kinds."""
    if not isinstance(kind, str) or not kind:
        raise _unknown(kind)(sorted(plugins.entry_points(ENTRY_POINT_GROUP)))
    return plugins.target(kind, BUILTIN, ENTRY_POINT_GROUP, _unknown(kind))


def executor_maker(kind: str) -> Callable[..., WorkerPool | None]:
    """The ``make`` of executor ``kind``, its module imported now. Raises ValueError for an
    unknown kind, ImportError when its module cannot be imported (naming what to install)."""
    target = _target(kind)
    try:
        maker = plugins.import_target(target, kind, ImportError)
    except ImportError as error:
        hint = f"; {_EXTRAS[kind]}" if kind in _EXTRAS else ""
        raise ImportError(f"executor kind {error}{hint}") from error.__cause__
    if not callable(maker):
        raise TypeError(f"executor kind {kind!r}: {target} is not callable")
    return maker


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
            :class:`parastokes.gpu.GPUExecutor`; needs ``parastokes[gpu]``); or a kind of the
            registry (``"package.module:make"``, an entry point of ``parastokes.executors``).
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
    _target(kind)  # an unknown kind first, before any option
    if workers is not None and not is_integer(workers, 1):
        raise ValueError(f"workers must be an integer >= 1 (or None), got {workers!r}")
    if not is_integer(threads_per_worker, 1):
        raise ValueError(f"threads_per_worker must be an integer >= 1, got {threads_per_worker!r}")
    if kind != "mpi" and (comm is not None or root != 0):
        raise ValueError(f"comm and root apply to kind='mpi' only, not {kind!r}")
    if kind != "processes" and start_method is not None:
        raise ValueError(f"start_method applies to kind='processes' only, not {kind!r}")
    make = executor_maker(kind)
    return make(workers, warmup=warmup, threads_per_worker=threads_per_worker, comm=comm,
                root=root, start_method=start_method)
