"""Labelled tasks: run a batch on any executor and name the task that failed.

The Parareal engine submits one batch per sweep (one fine solve per slice, or one auxiliary coarse
solve per solver). :func:`run_tasks` returns the results in order, or raises :class:`TaskError`
naming the first failed task in submission order, so serial and parallel runs report the same task.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import FIRST_EXCEPTION, BrokenExecutor, Future, wait
from dataclasses import dataclass
from typing import Any, Protocol

from ..core import signals
from .errors import TaskError, WorkerDiedError


class Submitter(Protocol):
    """What :func:`run_tasks` needs of an executor: ``submit`` (any ``concurrent.futures``
    executor, or a proxy of one)."""

    def submit(self, fn: Callable[..., Any], /, *args: Any) -> Future: ...


@dataclass(frozen=True)
class Task:
    """One call ``fn(*args)`` and the label that names it in errors.

    ``fn`` and ``args`` travel to the worker (they must pickle); the label stays on the manager.
    """

    fn: Callable[..., Any]
    args: tuple[Any, ...] = ()
    label: str = "task"


def run_tasks(executor: Submitter, tasks: Iterable[Task]) -> list[Any]:
    """Run ``tasks`` on ``executor`` and return their results in order.

    All tasks are submitted at once. On a failure, the tasks not yet started are cancelled and
    :class:`TaskError` is raised for the first failed task in submission order (tasks before it are
    waited for, so the same task is named whatever the executor). When a worker process dies, the
    task it was running is named (its error is a :class:`WorkerDiedError`), not the tasks that
    merely lost their pool. On ``KeyboardInterrupt`` the tasks not yet started are cancelled.

    An executor that can run many calls as one batch (``executor.batch()``, a context manager:
    the GPU executor of :mod:`parastokes.gpu`) gets all the tasks inside one ``batch()``; it
    runs them when the context closes.
    """
    tasks = list(tasks)
    futures: list[Future] = []
    try:
        with _batched(executor):
            for task in tasks:
                future = executor.submit(task.fn, *task.args)
                futures.append(future)
                if future.done() and future.exception() is not None:
                    break  # an in-process executor already failed: do not run the rest
        index = _first_failure(futures)
        signals.honour()  # a stop lost while waiting (docs: core.signals)
    except BaseException:
        for future in futures:
            future.cancel()
        raise
    if index is None:
        return [future.result() for future in futures]
    for future in futures:
        future.cancel()
    original = futures[index].exception()
    assert original is not None  # futures[index] failed (_first_failure)
    raise TaskError(tasks[index].label, original) from original


def run_labelled(
    executor: Submitter,
    fn: Callable[..., Any],
    args_list: Sequence[Sequence[Any]],
    labels: Sequence[str],
) -> list[Any]:
    """Run ``fn(*args)`` for every ``args`` in ``args_list``; see :func:`run_tasks`.

    ``labels[i]`` names call ``i`` in a :class:`TaskError`.
    """
    if len(args_list) != len(labels):
        raise ValueError(f"{len(args_list)} argument tuples but {len(labels)} labels")
    tasks = [Task(fn, tuple(args), label) for args, label in zip(args_list, labels, strict=True)]
    return run_tasks(executor, tasks)


def _batched(executor: Submitter) -> contextlib.AbstractContextManager:
    """``executor.batch()`` where the executor has it, else a context that does nothing."""
    batch = getattr(executor, "batch", None)
    return contextlib.nullcontext() if batch is None else batch()


def _error(future: Future) -> BaseException | None:
    if not future.done() or future.cancelled():
        return None
    return future.exception()


def _is_bystander(exc: BaseException | None) -> bool:
    """A task that failed only because another task broke the pool."""
    return isinstance(exc, BrokenExecutor) and not isinstance(exc, WorkerDiedError)


def _first_failure(futures: list[Future]) -> int | None:
    """Index of the failed task to report, or None when every task succeeded."""
    wait(futures, return_when=FIRST_EXCEPTION)
    while True:
        failed = [i for i, f in enumerate(futures) if _error(f) is not None]
        if not failed:
            return None
        if any(isinstance(_error(futures[i]), BrokenExecutor) for i in failed):
            # a broken pool (a worker died) fails every pending task at once: collect them all
            # before anything is cancelled, which would race with the pool marking them failed
            wait(futures)
            break
        earlier = [f for f in futures[: min(failed)] if not f.done()]
        if not earlier:
            break
        wait(earlier, return_when=FIRST_EXCEPTION)
    failed = [i for i, f in enumerate(futures) if _error(f) is not None]
    causes = [i for i in failed if not _is_bystander(_error(futures[i]))]
    return min(causes or failed)
