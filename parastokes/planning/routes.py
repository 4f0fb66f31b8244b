"""The routes of ``parastokes plan`` and their predicted wall times (docs/planning.md).

Every route is predicted from CPU times measured on this machine, one thread, scaled to the
whole interval (:mod:`.baseline`), and the ratios measured by ``tune``'s pilot:

- serial: the fastest serial run reaching η*, Υ_best, on one core;
- spatial: that run with its kernels threaded over the cores (Remark 1 of the paper,
  :func:`parastokes.parallel.spatial.threaded`): Υ_best / S_sp(N), :func:`spatial_speedup`;
- Parareal on N slices and N workers, F the cheapest fixed-step run with error <= η*/10:
  Υ_F / S, with S eq. 14 (standard schedule, :func:`parastokes.parareal.speedup`) or the
  pipelined form 1 / ((1 + K/P) α + K/P) (:func:`parastokes.parareal.speedup_pipelined`);
- both combined: P slices of t threads each (P t <= N): Υ_F / (S_sp(t) S(α, K(P), P)).

Each row carries its predicted wall time, its speedup against the serial route and what it
rests on.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

from ..parareal.speedup import speedup, speedup_pipelined

__all__ = [
    "KERNEL_SHARE",
    "MIN_TARGETS",
    "SPATIAL_SOURCE",
    "THREAD_EFFICIENCY",
    "Route",
    "combined_route",
    "parareal_route",
    "parareal_wall",
    "serial_route",
    "spatial_route",
    "spatial_speedup",
    "table",
]

#: Share of a serial step spent in the velocity kernels, which the threads divide:
#: docs/benchmarks.md measures one RK2 step at 1.00-1.12 times its two kernel calls on one
#: thread (rod, N = 301), so the kernels are at least 1/1.12 = 0.89 of it.
KERNEL_SHARE = 0.9
#: Efficiency of the kernel on 2 threads: 1.90-1.95x (docs/benchmarks.md, tiles balanced over
#: the threads, N = 301 and 642); the lower end. Beyond 2 threads nothing was measured here.
THREAD_EFFICIENCY = 0.95
#: Fewest targets per thread assumed to keep that efficiency (an assumption, not measured: the
#: kernels' tiles are tens of targets): more threads than points / MIN_TARGETS add nothing.
MIN_TARGETS = 16
#: What the spatial route rests on, as printed.
SPATIAL_SOURCE = (f"threads over the kernels: Amdahl with kernel share {KERNEL_SHARE}, "
                  f"efficiency {THREAD_EFFICIENCY} (docs/benchmarks.md, 2 threads; not "
                  f"measured beyond), at most points/{MIN_TARGETS} threads")


@dataclass(frozen=True)
class Route:
    """One row of the table (the PLAN.json keys ``route``, ``predicted_wall_seconds``,
    ``speedup_vs_best_serial``, ``rests_on``) and how it uses the cores (``settings``)."""

    route: str
    predicted_wall_seconds: float
    speedup_vs_best_serial: float
    rests_on: str
    settings: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def spatial_speedup(threads: int, points: int) -> float:
    """S_sp = 1 / ((1 - f) + f / (e n)) of a step on ``threads`` kernel threads, f
    :data:`KERNEL_SHARE`, e :data:`THREAD_EFFICIENCY`, n = min(threads, points / MIN_TARGETS)
    threads that have work (1 thread: 1)."""
    useful = min(threads, max(1, points // MIN_TARGETS))
    if useful <= 1:
        return 1.0
    return 1.0 / ((1.0 - KERNEL_SHARE) + KERNEL_SHARE / (THREAD_EFFICIENCY * useful))


def parareal_wall(fine_seconds: float, alpha: float, iterations: int, slices: int,
                  schedule: str) -> float:
    """Υ_F / S: eq. 14 without overhead (standard) or 1 / ((1 + K/P) α + K/P) (pipelined), α =
    γ_G/γ_F, K iterations, P slices on P workers."""
    if schedule == "pipelined":
        return fine_seconds / speedup_pipelined(alpha, iterations, slices)
    if schedule == "standard":
        return fine_seconds / speedup(alpha, 1.0, iterations, slices)
    raise ValueError(f"schedule must be 'standard' or 'pipelined', got {schedule!r}")


def serial_route(best_seconds: float, best: str) -> Route:
    """The fastest serial run on one core."""
    return Route("serial", best_seconds, 1.0, f"{best}, measured (one thread, CPU time)",
                 {"threads": 1})


def spatial_route(best_seconds: float, best: str, cores: int, points: int) -> Route:
    """The fastest serial run with its kernels on ``cores`` threads."""
    wall = best_seconds / spatial_speedup(cores, points)
    return Route("spatial", wall, best_seconds / wall, f"{best}, measured; {SPATIAL_SOURCE}",
                 {"threads": cores})


def parareal_route(best_seconds: float, fine_seconds: float, alpha: float, iterations: int,
                   cores: int, schedule: str, evidence: str) -> Route:
    """Parareal on ``cores`` slices and workers, one thread each."""
    wall = parareal_wall(fine_seconds, alpha, iterations, cores, schedule)
    rule = "eq. 14" if schedule == "standard" else "1/((1+K/P)α+K/P)"
    return Route(f"parareal ({schedule})", wall, best_seconds / wall,
                 f"{rule} with α = {alpha:.3g}, K = {iterations}, P = {cores}; {evidence}",
                 {"slices": cores, "threads": 1, "schedule": schedule,
                  "iterations": iterations, "alpha": alpha})


def combined_route(best_seconds: float, fine_seconds: float, cores: int, points: int,
                   schedule: str, at: Callable[[int], tuple[float, int] | None],
                   evidence: str) -> Route | None:
    """The fastest split of ``cores`` into P >= 2 slices of t = floor(N / P) >= 2 threads;
    ``at(P)`` gives (α, K) for P slices, None where Parareal does not reach η*. None when no
    split exists or none reaches it."""
    best: Route | None = None
    for slices in range(2, cores // 2 + 1):
        threads = cores // slices  # every core of the split used: the most threads per slice
        found = at(slices)
        if found is None:
            continue
        alpha, iterations = found
        s_sp = spatial_speedup(threads, points)
        wall = parareal_wall(fine_seconds / s_sp, alpha, iterations, slices, schedule)
        if best is None or wall < best.predicted_wall_seconds:
            best = Route(
                f"combined ({schedule})", wall, best_seconds / wall,
                f"P = {slices} slices x t = {threads} threads: S_sp(t) = {s_sp:.3g} "
                f"({SPATIAL_SOURCE}) times Parareal with α = {alpha:.3g}, K = {iterations}; "
                f"{evidence}",
                {"slices": slices, "threads": threads, "schedule": schedule,
                 "iterations": iterations, "alpha": alpha})
    return best


def table(routes: list[Route], chosen: str) -> str:
    """The printed comparison: one line per route, the chosen one marked."""
    lines = [f"  {'route':24} {'predicted wall (s)':>19} {'vs best serial':>15}  rests on"]
    for r in routes:
        mark = "* " if r.route == chosen else "  "
        lines.append(f"{mark}{r.route:24} {r.predicted_wall_seconds:>19.4g} "
                     f"{r.speedup_vs_best_serial:>15.3g}  {r.rests_on}")
    return "\n".join(lines)
