"""``GPUExecutor``: the executor that runs a batch of submitted solves as one GPU batch.

It has the ``concurrent.futures`` shape of the other executors (:mod:`parastokes.parallel`), plus
``batch()``: a context manager inside which submitted calls are held, and run together when it
closes. :func:`parastokes.parallel.run_tasks` opens one around every batch of tasks it submits, so
a parallel sweep of Parareal (one fine solve per slice) and a coarse step of the extrapolated
solver (its N_G auxiliary solvers) each become one GPU batch (:mod:`parastokes.gpu.batch`), with no
GPU-specific code in the Parareal engine. Outside ``batch()``, ``submit`` runs the call at once,
as the serial executor does.

Everything runs in the calling thread (no pool): the result of each call is set on its future when
the batch ends; a failed member (e.g. a blow-up) fails its own future only.
"""

from __future__ import annotations

import contextlib
import pickle
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import Executor, Future
from typing import Any

from . import batch, device, stepping

__all__ = ["GPUExecutor", "make_gpu"]


class _HeldFuture(Future):
    """A future whose call waits in a batch: asking for its result runs the batch first (so that
    waiting inside ``batch()`` cannot deadlock)."""

    def __init__(self, executor: GPUExecutor) -> None:
        super().__init__()
        self._executor = executor

    def result(self, timeout: float | None = None) -> Any:
        self._executor._run_held(self)
        return super().result(timeout)

    def exception(self, timeout: float | None = None) -> BaseException | None:
        self._executor._run_held(self)
        return super().exception(timeout)


class GPUExecutor(Executor):
    """Runs submitted solves in GPU batches (see the module docstring).

    Args:
        workers: the most calls one batch holds (a larger batch is run in consecutive parts);
            ``None``: no limit. Parareal reads it as the number of solves that run at once.
        warmup: a callable run once now; when it is a :class:`parastokes.run.warmup.WarmUp`, the GPU
            kernels of its system are compiled too (:func:`parastokes.gpu.batch.warm_up`).
        launch: the thread-block shapes (:class:`parastokes.gpu.stepping.Launch`).

    Raises RuntimeError when no CUDA GPU (or simulator) is available.
    """

    def __init__(
        self,
        workers: int | None = None,
        warmup: Callable[[], Any] | None = None,
        launch: stepping.Launch | None = None,
    ) -> None:
        device.require()
        if workers is not None and workers < 1:
            raise ValueError(f"workers must be >= 1, got {workers}")
        self.workers = workers
        self.launch = launch
        self.batches: list[int] = []  # how many GPU solves each batch held, so far
        #: how many products each launch of the hosted solves' products held, so far
        self.launches: list[int] = []
        self._held: list[tuple[_HeldFuture, Callable[..., Any], tuple, dict]] = []
        self._depth = 0
        self._lock = threading.RLock()
        self._shut_down = False
        if warmup is not None:
            warmup()
            system = getattr(warmup, "system", None)
            if isinstance(system, bytes):
                batch.warm_up(pickle.loads(system), launch)

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future:
        """Hold ``fn(*args, **kwargs)`` for the current batch, or run it now outside ``batch()``."""
        with self._lock:
            if self._shut_down:
                raise RuntimeError("cannot schedule new futures after shutdown")
            future = _HeldFuture(self)
            self._held.append((future, fn, args, kwargs))
            if self._depth == 0:
                self._run()
            return future

    def map(
        self,
        fn: Callable[..., Any],
        *iterables: Any,
        timeout: float | None = None,
        chunksize: int = 1,
    ) -> Iterator[Any]:
        """Like :func:`map`, all calls in one batch."""
        with self.batch():
            futures = [self.submit(fn, *args) for args in zip(*iterables, strict=False)]
        return (future.result(timeout) for future in futures)

    @contextlib.contextmanager
    def batch(self) -> Iterator[GPUExecutor]:
        """Hold the calls submitted inside; run them as one batch when the block ends (and drop
        them, cancelled, when it ends with an exception)."""
        with self._lock:
            self._depth += 1
        try:
            yield self
        except BaseException:
            with self._lock:
                self._depth -= 1
                if self._depth == 0:
                    self._cancel_held()
            raise
        with self._lock:
            self._depth -= 1
            if self._depth == 0:
                self._run()

    def _run_held(self, future: _HeldFuture) -> None:
        with self._lock:
            if any(held[0] is future for held in self._held):
                self._run()

    def _cancel_held(self) -> None:
        for future, *_ in self._held:
            future.cancel()
        self._held = []

    def _run(self) -> None:
        """Run every held call: GPU batches of at most ``workers`` calls."""
        held = [h for h in self._held if h[0].set_running_or_notify_cancel()]
        self._held = []
        size = self.workers or max(len(held), 1)
        for start in range(0, len(held), size):
            part = held[start : start + size]
            try:
                outcomes = batch.run_calls([h[1:] for h in part], self.launch, self.launches)
            except BaseException as exc:  # e.g. Ctrl-C: fail what has not finished, re-raise
                for h in held[start:]:
                    h[0].set_exception(exc)
                raise
            gpu_calls = sum(batch.gpu_call(fn, args, kwargs) for _, fn, args, kwargs in part)
            if gpu_calls:
                self.batches.append(gpu_calls)
            for (future, *_), (ok, value) in zip(part, outcomes, strict=True):
                if ok:
                    future.set_result(value)
                else:
                    future.set_exception(value)

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        """Refuse further calls; held calls are run (or cancelled with ``cancel_futures``)."""
        with self._lock:
            self._shut_down = True
            if cancel_futures:
                self._cancel_held()
            elif self._held:
                self._run()


def make_gpu(
    workers: int | None, *, warmup: Callable[[], Any] | None = None, threads_per_worker: int = 1,
    **_: Any,
) -> GPUExecutor:
    """The executor kind ``"gpu"`` (:func:`parastokes.parallel.make_executor`)."""
    if threads_per_worker != 1:
        raise ValueError("threads_per_worker does not apply to kind='gpu'")
    device.cuda()  # ImportError naming the extra
    return GPUExecutor(workers, warmup)
