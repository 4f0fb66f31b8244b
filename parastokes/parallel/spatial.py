"""Spatial parallelization of the fine solver F (Remark 1 of the paper) and its speedup (eq. 35).

Remark 1: within one time step, the velocities u_i of the N_sigma grid points (eq. 6) are
independent of one another once the forces are known, so they can be computed in parallel over
the *target* points. Two ways are offered, for comparison with Parareal's temporal
parallelization (section 5.1.4, Fig. 10):

- **threads** (:func:`threaded`): the regularized-Stokeslet kernels split the targets into tiles
  over numba threads (``n_threads`` of :func:`parastokes.mrs.velocity`, carried by the system).
  Each target's sum runs on one thread in a fixed order, so the result is bit-identical to the
  serial F for any thread count.
- **processes** (:class:`parastokes.fluid.BlockedMRS`, a second implementation of the fluid, with
  :class:`TargetBlocks`): every velocity evaluation is split into contiguous blocks of targets,
  one task per block on an executor (a process pool or MPI ranks), the results concatenated on
  the manager. The forces
  (and torques) are computed once on the manager and shipped with all source points to every
  block, as a distributed-memory code would broadcast them; each target's sum is still the same
  sum in the same order. The system is the same system with ``target_blocks`` set; it has no
  compiled loop (registered for the :class:`parastokes.fluid.MRS` fluid only).

:func:`fine_solver` builds a spatially parallel F either way; :func:`measure_speedup` measures
eq. 35, Upsilon_F / Upsilon_sp: the wall time of the serial F over the wall time of the spatially
parallel F on the same interval (both from the same state, so their results can be compared).
"""

from __future__ import annotations

import dataclasses
import time
from concurrent.futures import Executor
from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import integrate
from ..core.contracts import PropagatorLike
from ..fluid import block_velocity
from ..models import RodSystem, VesicleSystem
from . import Task, run_tasks

__all__ = ["SpatialSpeedup", "TargetBlocks", "fine_solver", "measure_speedup", "threaded"]


class TargetBlocks:
    """How a :class:`parastokes.fluid.BlockedMRS` splits its targets: ``n_blocks`` contiguous
    blocks (default ``executor.workers``), one labelled task each on ``executor`` (the
    :class:`parastokes.fluid.Blocks` of the fluid). It holds the executor, so it lives on the
    manager and does not pickle."""

    def __init__(self, executor: Executor, n_blocks: int | None = None) -> None:
        n_blocks = getattr(executor, "workers", 1) if n_blocks is None else n_blocks
        if isinstance(n_blocks, bool) or not isinstance(n_blocks, int) or n_blocks < 1:
            raise ValueError(f"n_blocks must be an integer >= 1, got {n_blocks!r}")
        self.executor = executor
        self.n_blocks = n_blocks

    def __reduce__(self) -> tuple:
        raise TypeError("TargetBlocks holds an executor (manager only): it does not pickle")

    def slices(self, n_points: int) -> list[slice]:
        """The blocks of ``n_points`` targets (at most one per target)."""
        parts = np.array_split(np.arange(n_points), min(self.n_blocks, n_points))
        return [slice(int(b[0]), int(b[-1]) + 1) for b in parts]

    def run(self, points: np.ndarray, forces: np.ndarray, torques: np.ndarray | None,
            options: dict[str, Any]) -> list[Any]:
        """The velocities of every block (in order) of ``points`` from all of them."""
        tasks = [
            Task(
                block_velocity,
                (points[block], points, forces, torques, options),
                f"velocity of targets {block.start}-{block.stop - 1}",
            )
            for block in self.slices(len(points))
        ]
        return run_tasks(self.executor, tasks)


def threaded(system: RodSystem | VesicleSystem, n_threads: int) -> RodSystem | VesicleSystem:
    """A copy of ``system`` whose kernels run on ``n_threads`` threads over target tiles."""
    if isinstance(n_threads, bool) or not isinstance(n_threads, int) or n_threads < 1:
        raise ValueError(f"n_threads must be an integer >= 1, got {n_threads!r}")
    return dataclasses.replace(system, n_threads=n_threads)


def fine_solver(
    system: RodSystem | VesicleSystem,
    scheme: str,
    dt: float,
    *,
    n_threads: int | None = None,
    executor: Executor | None = None,
    n_blocks: int | None = None,
) -> integrate.Propagator:
    """The spatially parallel fine solver F (Remark 1): threads or blocks of targets on processes.

    Give exactly one of ``n_threads`` (kernels threaded over target tiles, :func:`threaded`) and
    ``executor`` (targets split into ``n_blocks`` blocks, default one per worker: the system with
    ``target_blocks``, whose fluid is a :class:`parastokes.fluid.BlockedMRS`). The result is an
    :class:`parastokes.integrate.Propagator`; with threads it pickles and can itself be the fine
    solver of a Parareal run (spatial and temporal parallelization together), with an executor it
    runs on the manager only.
    """
    if (n_threads is None) == (executor is None):
        raise ValueError("give exactly one of n_threads (threads) and executor (process blocks)")
    if n_threads is not None:
        return integrate.Propagator(threaded(system, n_threads), scheme, dt)
    if not (dataclasses.is_dataclass(system)
            and "target_blocks" in {f.name for f in dataclasses.fields(system)}):
        raise TypeError(
            f"{type(system).__name__} has no target_blocks field: its fluid cannot be split "
            "into blocks of targets"
        )
    assert executor is not None  # exactly one of the two (checked above)
    blocks = TargetBlocks(executor, n_blocks)
    return integrate.Propagator(dataclasses.replace(system, target_blocks=blocks), scheme, dt)


@dataclass(frozen=True)
class SpatialSpeedup:
    """Eq. 35 measured: ``serial_time`` (Upsilon_F), ``parallel_time`` (Upsilon_sp), both the
    best of ``repeats`` runs, and ``difference``, the largest ``|x_sp - x_F|`` over the largest
    ``|x_F|`` of the final states (0 when bit-identical)."""

    serial_time: float
    parallel_time: float
    difference: float
    repeats: int

    @property
    def speedup(self) -> float:
        """Upsilon_F / Upsilon_sp (eq. 35)."""
        return self.serial_time / self.parallel_time


def measure_speedup(
    serial: PropagatorLike,
    parallel: PropagatorLike,
    t0: float,
    t1: float,
    x0: np.ndarray,
    repeats: int = 1,
) -> SpatialSpeedup:
    """Eq. 35: time ``serial`` (F) and ``parallel`` (the spatially parallel F) over [t0, t1].

    The two are run alternately ``repeats`` times from ``x0``; the best time of each is kept (other
    load on the machine only ever adds time).
    """
    if isinstance(repeats, bool) or not isinstance(repeats, int) or repeats < 1:
        raise ValueError(f"repeats must be an integer >= 1, got {repeats!r}")
    serial_times, parallel_times = [], []
    for _ in range(repeats):
        start = time.perf_counter()
        reference = serial(t0, t1, x0)
        serial_times.append(time.perf_counter() - start)
        start = time.perf_counter()
        result = parallel(t0, t1, x0)
        parallel_times.append(time.perf_counter() - start)
    scale = float(np.abs(reference).max()) or 1.0
    return SpatialSpeedup(
        serial_time=min(serial_times),
        parallel_time=min(parallel_times),
        difference=float(np.abs(result - reference).max()) / scale,
        repeats=repeats,
    )
