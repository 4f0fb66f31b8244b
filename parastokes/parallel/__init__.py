"""Executors for Parareal's parallel sweeps: serial (reference), process pool, MPI (and the GPU's,
:mod:`parastokes.gpu`), each a kind of the registry of :mod:`.factory`, found by name by
:func:`make_executor` and imported only when asked for.

All have the ``concurrent.futures`` shape (``submit``, ``map``, ``shutdown``, context manager) and
a ``workers`` attribute. :func:`run_tasks` / :func:`run_labelled` run a batch of labelled tasks and
raise :class:`TaskError` naming the one that failed. See docs/parallel.md.
"""

from .errors import TaskError, WorkerDiedError
from .factory import KINDS, make_executor
from .mpi import MPIExecutor
from .processes import ProcessExecutor
from .serial import SerialExecutor
from .tasks import Task, run_labelled, run_tasks
from .worker import available_cores

__all__ = [
    "KINDS",
    "MPIExecutor",
    "ProcessExecutor",
    "SerialExecutor",
    "Task",
    "TaskError",
    "WorkerDiedError",
    "available_cores",
    "make_executor",
    "run_labelled",
    "run_tasks",
]
