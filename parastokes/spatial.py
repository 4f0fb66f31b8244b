"""Spatial parallelization of the fine solver F (Remark 1 of the paper) and its speedup (eq. 35).

Remark 1: within one time step, the velocities u_i of the N_sigma grid points (eq. 6) are
independent of one another once the forces are known, so they can be computed in parallel over
the *target* points. Two ways are offered, for comparison with Parareal's temporal
parallelization (section 5.1.4, Fig. 10):

- **threads** (:func:`threaded`): the regularized-Stokeslet kernels split the targets into tiles
  over numba threads (``n_threads`` of :func:`parastokes.mrs.velocity`, carried by the system).
  Each target's sum runs on one thread in a fixed order, so the result is bit-identical to the
  serial F for any thread count.
- **processes** (:class:`TargetBlocks`): every velocity evaluation is split into contiguous blocks
  of targets, one task per block on an executor (a process pool or MPI ranks), the results
  concatenated on the manager. The forces (and torques) are computed once on the manager and
  shipped with all source points to every block, as a distributed-memory code would broadcast
  them; each target's sum is still the same sum in the same order.

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

from . import integrate, mrs
from .contracts import PropagatorLike
from .parallel import Task, run_tasks
from .system import RodSystem, VesicleSystem

__all__ = ["SpatialSpeedup", "TargetBlocks", "fine_solver", "measure_speedup", "threaded"]


def threaded(system: RodSystem | VesicleSystem, n_threads: int) -> RodSystem | VesicleSystem:
    """A copy of ``system`` whose kernels run on ``n_threads`` threads over target tiles."""
    if isinstance(n_threads, bool) or not isinstance(n_threads, int) or n_threads < 1:
        raise ValueError(f"n_threads must be an integer >= 1, got {n_threads!r}")
    return dataclasses.replace(system, n_threads=n_threads)


def _block_velocity(
    targets: np.ndarray,
    sources: np.ndarray,
    forces: np.ndarray,
    torques: np.ndarray | None,
    options: dict[str, Any],
) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Eq. 6 at one block of targets from all sources (runs on a worker, one thread)."""
    return mrs.velocity(targets, sources, forces, torques=torques, check=False, **options)


class TargetBlocks:
    """``system`` whose velocity evaluations run by blocks of target points on ``executor``.

    ``rates(t, state)`` equals ``system.rates(t, state)`` (rods: forces and torques of eq. 12, then
    u and w from all points, wall images included; vesicles: spring forces, Stokeslet velocities
    of eq. 6 plus the shear flow), with the O(N^2) kernel sums split into ``n_blocks`` contiguous
    blocks of targets (default ``executor.workers``), one labelled task each. Every other attribute
    (``advance``, ``project``, ``monitor``, ``params``...) is the wrapped system's, so
    :class:`parastokes.integrate.Propagator` runs it like any system; it has no compiled loop (those
    are registered per exact type, :mod:`parastokes.stepping.registry`), so ``integrate.run``
    steps through these blocks.
    It lives on the manager (it holds the executor) and does not pickle.
    """

    def __init__(
        self, system: RodSystem | VesicleSystem, executor: Executor, n_blocks: int | None = None
    ) -> None:
        if not isinstance(system, RodSystem | VesicleSystem):
            raise TypeError(
                f"TargetBlocks supports RodSystem and VesicleSystem, not {type(system).__name__}"
            )
        n_blocks = getattr(executor, "workers", 1) if n_blocks is None else n_blocks
        if isinstance(n_blocks, bool) or not isinstance(n_blocks, int) or n_blocks < 1:
            raise ValueError(f"n_blocks must be an integer >= 1, got {n_blocks!r}")
        n_points = len(system.initial_state())
        self.system = system
        self.executor = executor
        self.blocks = [
            slice(int(b[0]), int(b[-1]) + 1)
            for b in np.array_split(np.arange(n_points), min(n_blocks, n_points))
        ]

    def __getattr__(self, name: str) -> Any:
        if name in ("system", "executor", "blocks"):  # not set yet: do not recurse
            raise AttributeError(name)
        return getattr(self.system, name)

    def __reduce__(self) -> tuple:
        raise TypeError("TargetBlocks holds an executor (manager only): it does not pickle")

    def _velocity(
        self,
        points: np.ndarray,
        forces: np.ndarray,
        torques: np.ndarray | None,
        options: dict[str, Any],
        t: float,
    ) -> list[Any]:
        tasks = [
            Task(
                _block_velocity,
                (points[block], points, forces, torques, options),
                f"velocity of targets {block.start}-{block.stop - 1} at t={t:.9g}",
            )
            for block in self.blocks
        ]
        return run_tasks(self.executor, tasks)

    def rates(self, t: float, state: np.ndarray) -> np.ndarray:
        """``system.rates(t, state)`` with the kernel sums computed by blocks of targets."""
        system = self.system
        if isinstance(system, RodSystem):
            forces, torques = system.loads(t, state)
            options = {
                "epsilon": system.epsilon,
                "mu": system.viscosity,
                "wall": system.wall,
                "angular": True,
            }
            parts = self._velocity(state[:, :3], forces, torques, options, t)
            u = np.concatenate([part[0] for part in parts])
            w = np.concatenate([part[1] for part in parts])
            return np.concatenate([u, w], axis=1)
        options = {"epsilon": system.epsilon, "mu": system.viscosity}
        parts = self._velocity(state, system.forces(state), None, options, t)
        u = np.concatenate(parts)
        u[:, 0] += system.shear_rate * state[:, 2]
        return u


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
    ``executor`` (targets split into ``n_blocks`` blocks, default one per worker,
    :class:`TargetBlocks`). The result is an :class:`parastokes.integrate.Propagator`; with threads
    it pickles and can itself be the fine solver of a Parareal run (spatial and temporal
    parallelization together), with an executor it runs on the manager only.
    """
    if (n_threads is None) == (executor is None):
        raise ValueError("give exactly one of n_threads (threads) and executor (process blocks)")
    if n_threads is not None:
        return integrate.Propagator(threaded(system, n_threads), scheme, dt)
    return integrate.Propagator(TargetBlocks(system, executor, n_blocks), scheme, dt)


@dataclass(frozen=True)
class SpatialSpeedup:
    """Eq. 35 measured: ``serial_time`` (Upsilon_F), ``parallel_time`` (Upsilon_sp), both the
    best of ``repeats`` runs, and ``difference``, the largest |x_sp - x_F| over the largest |x_F|
    of the final states (0 when bit-identical)."""

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
