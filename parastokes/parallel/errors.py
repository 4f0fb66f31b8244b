"""Exceptions raised by the executors and by :func:`parastokes.parallel.run_tasks`."""

from __future__ import annotations

from concurrent.futures.process import BrokenProcessPool


class TaskError(RuntimeError):
    """A labelled task failed; ``label`` names it and ``original`` is what it raised.

    The message reads ``"<label> failed: <ExceptionType>: <message>"``, so a label such as
    ``"fine solve of slice 3 in iteration 2"`` gives a message that says what went wrong where.
    The original exception is also chained as ``__cause__`` (with the worker's traceback, when the
    task ran in another process).
    """

    def __init__(self, label: str, original: BaseException) -> None:
        super().__init__(f"{label} failed: {type(original).__name__}: {original}")
        self.label = label
        self.original = original

    def __reduce__(self):  # keep label and original across pickling
        return (type(self), (self.label, self.original))


class WorkerDiedError(BrokenProcessPool):
    """The worker process running this task died (``os._exit``, a segfault, the OOM killer...).

    Only the task that was running on the dead worker gets this error; the other tasks of the
    broken pool get a plain :class:`~concurrent.futures.process.BrokenProcessPool`.
    """

    def __init__(self, pid: int, exitcode: int) -> None:
        super().__init__(
            f"worker process {pid} died (exit code {exitcode}) while running this task"
        )
        self.pid = pid
        self.exitcode = exitcode

    def __reduce__(self):
        return (type(self), (self.pid, self.exitcode))
