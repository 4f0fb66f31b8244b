"""The in-process reference executor."""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Executor, Future
from typing import Any


class SerialExecutor(Executor):
    """Runs every task at once, in the calling process; the reference for the parallel executors.

    ``submit`` returns a completed :class:`~concurrent.futures.Future`; an exception raised by the
    task is stored in the future (as in a pool), not raised by ``submit``. Arguments are passed as
    they are, not copied: a task must not modify its inputs (in a pool it would modify a copy).
    """

    workers: int = 1

    def __init__(self, warmup: Callable[[], Any] | None = None) -> None:
        """Run ``warmup()`` once now (so timings that follow compare with a warmed-up pool)."""
        self._shut_down = False
        if warmup is not None:
            warmup()

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future:
        """Run ``fn(*args, **kwargs)`` now and return its completed future."""
        if self._shut_down:
            raise RuntimeError("cannot schedule new futures after shutdown")
        future: Future = Future()
        future.set_running_or_notify_cancel()
        try:
            result = fn(*args, **kwargs)
        except Exception as exc:
            future.set_exception(exc)
        else:
            future.set_result(result)
        return future

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        """Refuse further tasks (there is nothing to wait for or cancel)."""
        self._shut_down = True


def make_serial(
    workers: int | None, *, warmup: Callable[[], Any] | None = None, threads_per_worker: int = 1,
    **_: Any,
) -> SerialExecutor:
    """The executor kind ``"serial"`` (:func:`parastokes.parallel.make_executor`)."""
    if workers not in (None, 1):
        raise ValueError(f"the serial executor has exactly 1 worker, not {workers}")
    if threads_per_worker != 1:
        raise ValueError("threads_per_worker does not apply to kind='serial'")
    return SerialExecutor(warmup)
