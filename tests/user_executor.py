"""An executor kind defined outside the package (docs/extending.md, "A new executor"): found by
``parallel.make_executor("user_executor:make_recording")`` through the executor registry."""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Future
from typing import Any

from parastokes.parallel import SerialExecutor


class RecordingExecutor(SerialExecutor):
    """The serial executor that also records the name of every task it runs."""

    def __init__(self, warmup: Callable[[], Any] | None = None) -> None:
        super().__init__(warmup)
        self.ran: list[str] = []

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future:
        self.ran.append(type(fn).__name__)
        return super().submit(fn, *args, **kwargs)


def make_recording(workers: int | None, *, warmup: Callable[[], Any] | None = None,
                   **options: Any) -> RecordingExecutor:
    """The kind's ``make``: one worker only, no other option."""
    if workers not in (None, 1):
        raise ValueError(f"the recording executor has 1 worker, not {workers}")
    return RecordingExecutor(warmup)
