"""Process-pool executor for one machine, with workers started by ``forkserver`` (or ``spawn``).

Workers are never forked from the caller: numba's threading layers are not all safe in a child
forked from a process that already started their threads (GNU OpenMP aborts or hangs). Every
worker is started, limited to its threads and warmed up before the executor is returned, so timings
that follow measure work.
"""

from __future__ import annotations

import functools
import itertools
import multiprocessing
import os
import sys
import time
import warnings
from collections.abc import Callable
from concurrent.futures import Executor, Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any

from .errors import WorkerDiedError
from .worker import available_cores, configure_worker, die_with_parent, require_picklable

#: Start methods that do not fork the caller.
START_METHODS = ("forkserver", "spawn")

# Seconds to wait for a worker that the pool saw die to be reaped, so that its exit code is known.
_REAP_SECONDS = 0.05

# Seconds to wait for each killed worker to exit in abort().
_ABORT_SECONDS = 5.0

# Seconds between looks at the slots while the workers check in.
_CHECK_IN_POLL = 0.001

# State of a worker process, set by _initialize. The shared array ``slots`` holds, for worker i,
# its pid (2i) and the id of the task it runs (2i + 1, -1 between tasks), then one abort flag; the
# parent reads it to tell which task was running on a worker that died.
_WORKER: dict[str, Any] = {}


def _initialize(slots, threads: int, warmup: Callable[[], Any] | None) -> None:
    die_with_parent(os.getppid())  # the forkserver, which ends with the manager
    _WORKER.update(slots=slots, error=None)
    try:
        configure_worker(threads, warmup)
    except Exception as exc:  # re-raised by _check_in, so that the caller sees it
        _WORKER["error"] = exc


def _check_in(index: int, workers: int) -> int:
    """First task of every worker: claim slot ``index``, wait for the others, report errors.

    A worker waiting here takes no other task, and the pool starts a new worker for each task
    submitted while none is idle: so the ``workers`` check-ins start ``workers`` processes and
    each runs exactly one of them.
    """
    slots = _WORKER["slots"]
    _WORKER["index"] = index
    slots[2 * index : 2 * index + 2] = [os.getpid(), -1]
    while not all(slots[2 * i] for i in range(workers)):
        if slots[2 * workers]:
            raise RuntimeError("start-up aborted")
        time.sleep(_CHECK_IN_POLL)
    if _WORKER["error"] is not None:
        raise _WORKER["error"]
    return os.getpid()


def _tracked(task_id: int, fn: Callable[..., Any], args: tuple, kwargs: dict) -> Any:
    slot = 2 * _WORKER["index"] + 1
    _WORKER["slots"][slot] = task_id
    try:
        return fn(*args, **kwargs)
    finally:
        _WORKER["slots"][slot] = -1


class _Forgotten(Future):
    """A cancelled task's stand-in in the pool's table (:meth:`ProcessExecutor.abort`): cancelled,
    so the pool never runs it, and deaf to the failure the pool reports for it."""

    def __init__(self) -> None:
        super().__init__()
        self.cancel()

    def set_exception(self, exception: BaseException | None) -> None:
        """Nothing: the task was cancelled before the pool broke."""

    def set_result(self, result: Any) -> None:
        """Nothing: the task was cancelled."""


class _PoolFuture(Future):
    """The caller's view of a pool future: cancels through to the pool, explains broken pools."""

    def __init__(self, inner: Future, explain: Callable[[BaseException], BaseException]) -> None:
        super().__init__()
        self._inner = inner
        inner.add_done_callback(functools.partial(self._copy, explain))

    def _copy(self, explain: Callable[[BaseException], BaseException], inner: Future) -> None:
        if inner.cancelled():
            Future.cancel(self)
            return
        exc = inner.exception()
        if exc is None:
            self.set_result(inner.result())
        else:
            self.set_exception(explain(exc))

    def cancel(self) -> bool:
        """Cancel the task if it has not started (the pool's own rule)."""
        return self._inner.cancel()

    def running(self) -> bool:
        """Whether a worker is running the task now."""
        return self._inner.running()


def _context(start_method: str | None) -> multiprocessing.context.BaseContext:
    if start_method is None:
        available = multiprocessing.get_all_start_methods()
        start_method = "forkserver" if "forkserver" in available else "spawn"
    elif start_method not in START_METHODS:
        raise ValueError(
            f"start_method must be one of {START_METHODS}, not {start_method!r}: "
            "numba's threading layer is not safe in a forked child"
        )
    return multiprocessing.get_context(start_method)


def _guard_hint(exc: BaseException) -> str:
    """The likely cause of workers that broke while starting, in one line: a script (the main
    module, which every new worker imports again) that starts them without the
    ``if __name__ == "__main__":`` guard."""
    main = sys.modules.get("__main__")
    script = getattr(main, "__file__", None) if main is not None else None
    if not isinstance(exc, BrokenProcessPool) or script is None or getattr(main, "__spec__", None):
        return ""
    return (
        f". If {script} starts the run, put its code under `if __name__ == \"__main__\":` "
        "(each worker imports that script again; without the guard it starts the run again)"
    )


class ProcessExecutor(Executor):
    """A :class:`~concurrent.futures.ProcessPoolExecutor` whose workers are ready when it returns.

    Attributes: ``workers`` (number of worker processes), ``threads_per_worker``, ``start_method``
    and ``worker_pids`` (one per worker, in no particular order).

    A task that raises fails its future with that exception. :meth:`abort` stops the workers at
    once (an interrupted run); on Linux they also die with the manager, even when it is killed
    (:func:`~.worker.die_with_parent`). When a worker process dies, the pool is broken: the task
    it was running fails with :class:`WorkerDiedError` (pid and exit code), the
    other unfinished tasks with :class:`~concurrent.futures.process.BrokenProcessPool`.
    """

    def __init__(
        self,
        workers: int | None = None,
        *,
        threads_per_worker: int = 1,
        warmup: Callable[[], Any] | None = None,
        start_method: str | None = None,
    ) -> None:
        """Start the workers, limit their threads, run ``warmup()`` once on each.

        ``workers`` defaults to the available cores divided by ``threads_per_worker``; a
        ``RuntimeWarning`` says when ``workers * threads_per_worker`` exceeds the cores. A warm-up
        that raises makes this constructor raise ``RuntimeError`` (after stopping the workers).
        """
        if threads_per_worker < 1:
            raise ValueError(f"threads_per_worker must be >= 1, got {threads_per_worker}")
        cores = available_cores()
        if workers is None:
            workers = max(1, cores // threads_per_worker)
        if workers < 1:
            raise ValueError(f"workers must be >= 1, got {workers}")
        if workers * threads_per_worker > cores:
            warnings.warn(
                f"{workers} workers x {threads_per_worker} threads oversubscribe the {cores} "
                "available cores: timings will suffer",
                RuntimeWarning,
                stacklevel=2,
            )
        context = _context(start_method)
        self.workers = workers
        self.threads_per_worker = threads_per_worker
        self.start_method = context.get_start_method()
        self._slots = context.Array("q", 2 * workers + 1, lock=False)
        self._task_ids = itertools.count()
        self._pool = ProcessPoolExecutor(
            workers,
            mp_context=context,
            initializer=_initialize,
            initargs=(self._slots, threads_per_worker, warmup),
        )
        self.worker_pids = self._start()
        # The pool's own record of its processes (private, but the only handle on their exit
        # codes): copied now, while it holds exactly the workers that were just started.
        self._processes = dict(self._pool._processes)

    def _start(self) -> tuple[int, ...]:
        futures = [self._pool.submit(_check_in, i, self.workers) for i in range(self.workers)]
        try:
            return tuple(future.result() for future in futures)
        except BaseException as exc:
            self._slots[2 * self.workers] = 1  # release the workers still waiting to check in
            if not isinstance(exc, Exception):  # Ctrl-C, SIGTERM: do not wait for the warm-ups
                for process in list(self._pool._processes.values()):
                    process.kill()
            self._pool.shutdown(wait=True, cancel_futures=True)
            if isinstance(exc, Exception):
                raise RuntimeError(
                    f"starting the worker processes failed: {exc!r}{_guard_hint(exc)}"
                ) from exc
            raise

    def _explain(self, task_id: int, exc: BaseException) -> BaseException:
        """The error of ``task_id``: WorkerDiedError if its worker died while running it."""
        if not isinstance(exc, BrokenProcessPool):
            return exc
        for index in range(self.workers):
            if self._slots[2 * index + 1] != task_id:
                continue
            pid = self._slots[2 * index]
            process = self._processes[pid]
            # Called when the pool notices the death, before it stops the other workers: the worker
            # that has exited is the one that died.
            process.join(_REAP_SECONDS)
            if process.exitcode is not None:
                error = WorkerDiedError(pid, process.exitcode)
                error.__cause__ = exc
                return error
        return exc

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future:
        """Schedule ``fn(*args, **kwargs)`` on a worker (``fn`` and arguments must pickle)."""
        task_id = next(self._task_ids)
        inner = self._pool.submit(_tracked, task_id, fn, args, kwargs)
        return _PoolFuture(inner, functools.partial(self._explain, task_id))

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        """Stop the workers once the submitted tasks are done (see ProcessPoolExecutor); with
        ``wait``, no worker outlives the call (a pool that a dead worker broke may leave some)."""
        self._pool.shutdown(wait=wait, cancel_futures=cancel_futures)
        if wait:
            for process in self._processes.values():
                if process.is_alive():
                    process.kill()
                    process.join(_ABORT_SECONDS)

    def abort(self) -> None:
        """Stop now: kill the workers (running tasks are lost; the queued ones fail with a broken
        pool) and release the pool. For an interrupted or failed run; :meth:`shutdown` may
        follow."""
        self._slots[2 * self.workers] = 1
        # When a worker dies, CPython 3.11's pool marks every queued task failed, a cancelled one
        # too, which raises InvalidStateError in its manager thread (a traceback under the run's
        # message; 3.12 ignores it): the cancelled tasks leave its table first, and nothing is
        # cancelled after the kill.
        pending = getattr(self._pool, "_pending_work_items", {})
        for item in list(pending.values()):
            if item.future.cancelled():
                item.future = _Forgotten()
        for process in self._processes.values():
            if process.is_alive():
                process.kill()
        for process in self._processes.values():
            process.join(_ABORT_SECONDS)
        self._pool.shutdown(wait=True)


def make_processes(
    workers: int | None, *, warmup: Callable[[], Any] | None = None, threads_per_worker: int = 1,
    start_method: str | None = None, **_: Any,
) -> ProcessExecutor:
    """The executor kind ``"processes"`` (:func:`parastokes.parallel.make_executor`)."""
    require_picklable(warmup)
    return ProcessExecutor(
        workers, threads_per_worker=threads_per_worker, warmup=warmup, start_method=start_method
    )
