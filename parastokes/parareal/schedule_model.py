"""A discrete-event simulation of Parareal's two schedules on W workers.

Every task of a run is a node of a dependency graph: the fine solves F_n^k (k = 1..K, n = k..N),
the N_G auxiliary solves of every coarse step G_n^k (k = 0..K, n = k+1..N), and zero-time nodes
for the iterates X_n^k (formed on the manager by eq. 11 as soon as F_n^k, G_n^k and G_n^{k-1}
exist). The ``"pipelined"`` schedule is this graph; the ``"standard"`` one (Algorithm 1) adds its
two barriers: the fine solves of iteration k wait for the whole serial sweep k - 1, and the coarse
steps of iteration k for the whole parallel sweep k. Tasks run by list scheduling on ``workers``
workers (unlimited when None) with the priorities of the real scheduler
(:func:`parastokes.parareal.pipelined.priority`), each taking its cost plus ``overhead``.

It answers "how long with 40, 128, 1024 cores?" for any W (W < P gives waves of fine solves,
W > P room for the auxiliary solves), where the closed formulas of
:mod:`~parastokes.parareal.speedup` assume W = P and N_G = 1.
"""

from __future__ import annotations

import heapq
import math
import statistics
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from ..core.contracts import rounds
from ..core.values import is_integer, is_real
from .pipelined import AUXILIARY, FINE, priority

__all__ = [
    "MAX_SIMULATED_TASKS", "Simulation", "handover_latency", "predict_schedules", "simulate",
    "simulated_tasks",
]


@dataclass(frozen=True)
class Simulation:
    """The outcome of :func:`simulate`.

    ``wall`` is the simulated run time, ``serial`` the serial fine time N gamma_F (eq. 13),
    ``speedup`` their ratio, ``tasks`` one ``(kind, slice, iteration, start, end, worker)`` per
    task run on a worker (the layout of ``Timings.tasks``).
    """

    schedule: str
    wall: float
    serial: float
    tasks: list[tuple[str, int, int, float, float, int]]

    @property
    def speedup(self) -> float:
        return self.serial / self.wall


class _Graph:
    """Nodes with a duration (None: a zero-time node that takes no worker), a priority and
    dependencies; :meth:`schedule` runs them by list scheduling."""

    def __init__(self) -> None:
        self.duration: list[float | None] = []
        self.key: list[tuple] = []
        self.label: list[tuple[str, int, int]] = []
        self.children: list[list[int]] = []
        self.waiting: list[int] = []

    def add(self, deps: list[int], duration=None, key=(), label=("", 0, 0)) -> int:
        node = len(self.duration)
        self.duration.append(duration)
        self.key.append(key)
        self.label.append(label)
        self.children.append([])
        self.waiting.append(len(deps))
        for dep in deps:
            self.children[dep].append(node)
        return node

    def schedule(self, workers: int | None) -> tuple[list[float], list[tuple]]:
        """Finish time of every node, and the tasks run on workers."""
        finish = [math.nan] * len(self.duration)
        ready: list[tuple[tuple, int]] = []
        running: list[tuple[float, int, int]] = []
        free: list[int] = []
        slots = 0
        tasks = []

        def release(node: int, now: float) -> None:
            stack = [node]
            while stack:
                item = stack.pop()
                if self.duration[item] is not None:
                    heapq.heappush(ready, (self.key[item], item))
                    continue
                finish[item] = now
                for child in self.children[item]:
                    self.waiting[child] -= 1
                    if self.waiting[child] == 0:
                        stack.append(child)

        now = 0.0
        for node in [node for node, count in enumerate(self.waiting) if count == 0]:
            release(node, now)
        while True:
            while ready and (workers is None or len(running) < workers):
                _, node = heapq.heappop(ready)
                if free:
                    slot = heapq.heappop(free)
                else:
                    slot, slots = slots, slots + 1
                duration = self.duration[node]
                assert duration is not None  # (only nodes with a duration are queued)
                end = now + duration
                heapq.heappush(running, (end, node, slot))
                tasks.append((*self.label[node], now, end, slot))
            if not running:
                return finish, tasks
            now = running[0][0]
            while running and running[0][0] == now:
                _, node, slot = heapq.heappop(running)
                heapq.heappush(free, slot)
                finish[node] = now
                for child in self.children[node]:
                    self.waiting[child] -= 1
                    if self.waiting[child] == 0:
                        release(child, now)


def _check_workers(workers: int | None) -> None:
    if workers is not None and not is_integer(workers, 1):
        raise ValueError(f"workers must be an integer >= 1 (or None: unlimited), got {workers!r}")


def _check(n_slices: int, iterations: int, workers: int | None, costs: dict[str, float]) -> None:
    if not is_integer(n_slices, 1):
        raise ValueError(f"n_slices must be an integer >= 1, got {n_slices!r}")
    if not is_integer(iterations, 0):
        raise ValueError(f"iterations must be an integer >= 0, got {iterations!r}")
    _check_workers(workers)
    for name, value in costs.items():
        if not (is_real(value) and math.isfinite(value) and value >= 0.0):
            raise ValueError(f"{name} must be finite and >= 0, got {value!r}")


def simulate(
    schedule: str,
    n_slices: int,
    iterations: int,
    workers: int | None,
    coarse_cost: float,
    fine_cost: float = 1.0,
    n_auxiliary: int = 1,
    overhead: float = 0.0,
) -> Simulation:
    """Simulate ``iterations`` Parareal iterations on ``n_slices`` slices and ``workers`` workers.

    ``coarse_cost`` is the time of one auxiliary solve of a coarse step (of the whole step for a
    plain coarse solver, ``n_auxiliary=1``), ``fine_cost`` that of a fine solve (gamma_F; with
    the default 1 every time is in units of gamma_F), ``overhead`` is added to every task. The
    iteration count is capped at ``n_slices`` (Parareal is exact after N iterations).
    """
    if schedule not in ("standard", "pipelined"):
        raise ValueError(f"schedule must be 'standard' or 'pipelined', got {schedule!r}")
    costs = {"coarse_cost": coarse_cost, "fine_cost": fine_cost, "overhead": overhead}
    _check(n_slices, iterations, workers, costs)
    if isinstance(n_auxiliary, bool) or not isinstance(n_auxiliary, int) or n_auxiliary < 1:
        raise ValueError(f"n_auxiliary must be an integer >= 1, got {n_auxiliary!r}")
    standard = schedule == "standard"
    big_n, big_k = n_slices, min(iterations, n_slices)
    graph = _Graph()
    x: dict[tuple[int, int], int] = {(0, 0): graph.add([])}
    coarse: dict[tuple[int, int], int] = {}

    def state(n: int, k: int) -> int:
        return x[n, min(n, k)]  # X_n^k = X_n^n for n <= k

    kind = "coarse" if n_auxiliary == 1 else AUXILIARY

    def coarse_step(n: int, k: int, deps: list[int]) -> int:
        cost = coarse_cost + overhead
        aux = [
            graph.add(deps, cost, priority(AUXILIARY, n, k, i), (kind, n, k))
            for i in range(n_auxiliary)
        ]
        return graph.add(aux)

    for n in range(1, big_n + 1):
        coarse[n, 0] = coarse_step(n, 0, [state(n - 1, 0)])
        x[n, 0] = coarse[n, 0]
    for k in range(1, big_k + 1):
        barrier = [state(big_n, k - 1)] if standard else []
        fine = {
            n: graph.add(
                [state(n - 1, k - 1), *barrier],
                fine_cost + overhead,
                priority(FINE, n, k),
                (FINE, n, k),
            )
            for n in range(k, big_n + 1)
        }
        sweep = [graph.add(list(fine.values()))] if standard else []
        x[k, k] = graph.add([fine[k]])
        for n in range(k + 1, big_n + 1):
            coarse[n, k] = coarse_step(n, k, [state(n - 1, k), *sweep])
            x[n, k] = graph.add([fine[n], coarse[n, k], coarse[n, k - 1]])
    finish, tasks = graph.schedule(workers)
    return Simulation(schedule, finish[state(big_n, big_k)], big_n * fine_cost, tasks)


#: Most tasks a prediction simulates per schedule (about a second); beyond, only the closed
#: formulas are given (the simulation's time and memory grow with N_c K N_G).
MAX_SIMULATED_TASKS = 200_000


def simulated_tasks(n_slices: int, iterations: int, n_auxiliary: int = 1) -> int:
    """The tasks of :func:`simulate` for these sizes: K fine sweeps and K + 1 coarse sweeps of
    N_G auxiliary solves (an upper bound: later iterations have fewer slices)."""
    k = min(iterations, n_slices)
    return n_slices * (k + (k + 1) * n_auxiliary)


def predict_schedules(
    coarse_cost: float,
    iterations: int,
    cores: list[int],
    n_auxiliary: int = 1,
    workers: int | None = None,
    overhead: float = 0.0,
) -> list[dict[str, float]]:
    """Both schedules' speedups for each core count P (P slices on ``workers`` workers, default P).

    ``coarse_cost`` is gamma of one auxiliary solve over gamma_F (of the whole coarse step when
    ``n_auxiliary`` is 1). Each row holds ``cores``, ``workers``, ``iterations`` (capped at P),
    ``alpha`` (gamma_G / gamma_F of a coarse step with its auxiliary solves in ceil(N_G / W)
    rounds), the closed formulas ``standard_formula`` and ``pipelined_formula`` and the simulated
    ``standard`` and ``pipelined`` speedups (:func:`simulate`; NaN, with ``simulated`` False,
    beyond :data:`MAX_SIMULATED_TASKS` tasks, so that any core count is answered at once).
    """
    from .speedup import speedup_pipelined, speedup_standard

    _check_workers(workers)
    rows = []
    for n_cores in cores:
        if not is_integer(n_cores, 1):
            raise ValueError(f"core counts must be integers >= 1, got {n_cores!r}")
        w = n_cores if workers is None else workers
        k = min(iterations, n_cores)
        alpha = rounds(n_auxiliary, w) * coarse_cost
        row = {"cores": n_cores, "workers": w, "iterations": k, "alpha": alpha}
        row["standard_formula"] = speedup_standard(alpha, k, n_cores)
        row["pipelined_formula"] = speedup_pipelined(alpha, k, n_cores)
        row["simulated"] = simulated_tasks(n_cores, k, n_auxiliary) <= MAX_SIMULATED_TASKS
        for schedule in ("standard", "pipelined"):
            if not row["simulated"]:
                row[schedule] = math.nan
                continue
            sim = simulate(schedule, n_cores, k, w, coarse_cost, 1.0, n_auxiliary, overhead)
            row[schedule] = sim.speedup
        rows.append(row)
    return rows


def handover_latency(tasks: Sequence[Sequence[Any]]) -> float:
    """The median time from a coarse step's inputs being complete to its start, in a pipelined
    run's task records (``[kind, n, k, start, end, worker]``): the manager's hand-over (the
    correction of eq. 11, queueing the step, a free thread picking it up), which the measured task
    durations do not contain and the simulation adds to every task as its ``overhead``.

    The input X_{n-1}^k of the coarse step G(n, k) is complete when G(n-1, 0) ends (k = 0), when
    F(n-1, k) ends (n - 1 = k, exact), or when F(n-1, k), G(n-1, k) and G(n-1, k-1) have all ended.
    """
    ends: dict[tuple[str, int, int], float] = {}
    starts: dict[tuple[int, int], float] = {}
    for kind, n, k, start, end, _ in tasks:
        key = ("G" if kind in ("coarse", "auxiliary") else "F", n, k)
        ends[key] = max(ends.get(key, -math.inf), end)
        if key[0] == "G":
            starts[n, k] = min(starts.get((n, k), math.inf), start)
    gaps = []
    for (n, k), start in starts.items():
        if k == 0:
            inputs = [("G", n - 1, 0)]
        elif n - 1 == k:
            inputs = [("F", n - 1, k)]
        else:
            inputs = [("F", n - 1, k), ("G", n - 1, k), ("G", n - 1, k - 1)]
        if n > 1 and all(key in ends for key in inputs):
            gaps.append(start - max(ends[key] for key in inputs))
    return float(statistics.median(gaps)) if gaps else 0.0
