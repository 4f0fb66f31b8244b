"""The run layer's start-up: a built configuration with its executor started and warmed up.

:func:`parastokes.config.build` only constructs values (system, F, G). Starting the workers of
``execution.executor`` and loading (or compiling) the kernels in them and in this process happen
here, when a run begins, so that reading, checking or building a configuration starts nothing.

>>> cfg, resolved = config.load("experiments/quick/table4_g3.toml")      # doctest: +SKIP
>>> with session.start(config.build(cfg, resolved)) as running:          # doctest: +SKIP
...     parareal.run(running.setup.fine, running.setup.coarse, ..., executor=running.executor)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from .. import parallel
from ..config import ConfigError, Setup
from ..core.contracts import oversubscription
from .warmup import WarmUp

if TYPE_CHECKING:
    from ..parallel.factory import WorkerPool

__all__ = ["Session", "start"]


@dataclass
class Session:
    """A built configuration and the executor started for it; a context manager that shuts the
    executor down on exit."""

    setup: Setup
    executor: WorkerPool | None

    def __enter__(self) -> Session:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def close(self) -> None:
        """Shut the executor down (idempotent)."""
        if self.executor is not None:
            self.executor.shutdown()
            self.executor = None

    def abort(self) -> None:
        """After a failure or an interrupt: stop the workers now, without waiting for the tasks
        they run (their results would be discarded; a checkpoint is consistent)."""
        abort = getattr(self.executor, "abort", None)
        if abort is not None:
            abort()


def _executor(setup: Setup) -> WorkerPool:
    """The executor of ``execution`` with its workers warmed up; a ConfigError when an MPI launch
    provides fewer workers than the coarse solver needs and oversubscription is not allowed."""
    cfg, resolved = setup.config, setup.resolved
    ex = cfg.execution
    threads = 1 if ex.executor in ("serial", "gpu") else ex.threads
    pool = parallel.make_executor(
        ex.executor, resolved.workers, warmup=WarmUp(setup.system), threads_per_worker=threads
    )
    assert pool is not None  # None only on the serving ranks of an MPI comm, not used here
    problem = oversubscription(resolved.n_auxiliary, pool.workers, cfg.parareal.schedule)
    if resolved.workers is None and problem and not ex.allow_oversubscribe:
        pool.shutdown()
        raise ConfigError(
            [
                (
                    "execution.workers",
                    f"{problem} in this MPI launch; start more ranks or set "
                    "execution.allow_oversubscribe = true",
                )
            ]
        )
    return pool


def start(setup: Setup) -> Session:
    """Start the run of ``setup``: the executor of ``execution.executor`` (none when
    ``run.mode = "serial"``), its workers warmed up, and this process warmed up too (its serial
    fine run is timed, and must not include loading or, on a fresh install, compiling the kernels
    and the compiled loop of steps).

    Raises :class:`~parastokes.config.ConfigError` when an MPI launch provides fewer workers than
    the coarse solver needs and ``execution.allow_oversubscribe`` is false.
    """
    pool = None if setup.config.run.mode == "serial" else _executor(setup)
    try:
        WarmUp(setup.system)()
    except BaseException:
        if pool is not None:
            pool.shutdown()
        raise
    return Session(setup, pool)
