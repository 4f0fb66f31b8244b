"""Pipelined against standard Parareal: emulation, real runs, and the P = 40 comparison.

Run from the repository root::

    PYTHONPATH=. python benchmarks/pipeline.py [--sections emulation real p40] [--quick] \\
        [--fine-ms 150] [--json PATH] [--out PATH] [--figures DIR] [--records PATH ...] \\
        [--costs PATH] [--errors PATH]

Sections:

- ``emulation`` (EMULATION: sleeping propagators stand in for many cores; this tests the scheduler,
  not the physics): thread pools of W = 8, 16, 32, 64 workers, P = W slices, alpha = 0.01, 0.1,
  0.3, K = 1, 2, 4 iterations, and a few extrapolated cases (N_G = 4 auxiliary solves per coarse
  step). A fine solve sleeps ``--fine-ms`` milliseconds, a coarse (auxiliary) solve alpha times
  that, then applies the exact (fine) or forward Euler (coarse) step of dx/dt = -x, so the
  iterates of both schedules are compared too. Each run's wall time is set against the closed
  formula and against the simulation (:func:`parastokes.parareal.simulate`) fed with the task
  costs measured in that run (mean fine and coarse task durations, which include the per-task
  overhead of the thread pool) and, for the pipelined schedule, the measured hand-over latency of
  the manager per task (:func:`parastokes.parareal.handover_latency`), which the simulation adds
  to every task.
- ``real``: a rod (Table 6 coarse solver, N_G = 2) and a vesicle (Table 7's G^3 reduced to N_G = 2)
  on 2 worker processes, 4 slices, K = 2, both schedules interleaved; same iterates (asserted), wall
  time against the simulation for W = 2 with the run's measured gamma_F and gamma_G.
- ``p40``: the comparison the paper's section 6 asks for, at P = 40 slices and workers: standard vs
  pipelined, each with the plain coarse solver G_{Theta^0, tau} and with the paper's extrapolated
  solvers (Tables 4-8). gamma ratios MEASURED at full size on the first slice of each
  experiments/NAME.toml (:func:`parastokes.parareal.measure_slice_costs`: CPU time of this
  process, so that the other jobs sharing the cores do not enter the ratios; run it with
  NUMBA_NUM_THREADS=1, one core per solve as on the paper's cluster): the fine solver over
  ``--fine-steps`` n and 2n steps, every auxiliary solve over ``--coarse-steps`` steps, each
  scaled to the slice by its step count, and the combination; ``--repeats`` repeats, median of
  the per-repeat ratios. Every auxiliary solve is a task costing (max auxiliary + combination)
  (the standard schedule's gamma_G for N_G <= 40). Iteration counts: eta^k from the reproduction
  records given with ``--records`` (full-scale), else the shortened analogues' (ERRORS), each
  labelled. A table and a figure (speedup against desired error, like Fig. 6b).

  PYTHONPATH=. NUMBA_NUM_THREADS=1 python benchmarks/pipeline.py --sections p40 \\
      --records docs/reproduction \\
      --costs docs/figures/pipeline_p40_costs.json --figures docs/figures
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import time
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from parastokes import cli, config, parallel, parareal
from parastokes.output.plots import staircase
from parastokes.parallel import Task

ROOT = Path(__file__).resolve().parents[1]
SECTIONS = ("emulation", "real", "p40")

# eta^k (k = 1, 2, 3) of the shortened analogues of the paper's configurations
# (experiments/quick/NAME.toml: 4 slices; rod: 61 points over a rod of length 12; their time spans
# differ, T = 0.004 or the paper's slices T = 0.1 for the rod, T = 10 for the vesicle, and each
# curve says which), in one process:
#   parastokes run experiments/quick/NAME.toml --out DIR --set 'execution.executor="serial"' \
#       --set execution.workers=1 --set parareal.max_iterations=3
# Used for a solver only when no full-scale record (--records) has its eta^k.
ERRORS: dict[str, list[float]] = {
    "table4_g1": [3.3385e-08, 1.2685e-10, 2.8105e-11],
    "table4_g2": [9.6965e-07, 8.1847e-07, 2.7415e-07],
    "table4_g3": [5.2593e-11, 4.9989e-11, 1.6650e-11],
    "table4_g4": [7.2947e-08, 4.3220e-10, 1.0303e-12],
    "table5_g1": [2.9887e-08, 8.7302e-10, 1.6479e-10],
    "table5_g2": [1.9198e-09, 2.9823e-11, 1.0831e-11],
    "table5_g3": [2.2041e-08, 2.1586e-08, 7.1986e-09],
    "table6_eps3": [5.7430e-05, 5.1954e-06, 8.0465e-07],
    "table7_g1": [2.9484e-04, 3.0044e-05, 2.1656e-06],
    "table7_g2": [2.3551e-05, 2.4623e-06, 1.1522e-09],
}

# The paper's configurations compared at P = 40: (table, plain G_{Theta^0, tau}, extrapolated).
# Tables 5, 6 and 8 have no plain solver in the paper.
TABLES = {
    "Table 4 (rod, ε⁰ = 5σ_f)": ("table4_g4", ["table4_g1", "table4_g2", "table4_g3"]),
    "Table 5 (rod, ε⁰ = 7σ_f)": (None, ["table5_g1", "table5_g2", "table5_g3"]),
    "Table 6 (rod, ε⁰ = 3σ_f)": (None, ["table6_eps3"]),
    "Table 7 (vesicle, ε⁰ = 0.3 l_max)": (
        "table7_g4",
        ["table7_g1", "table7_g2", "table7_g3"],
    ),
    "Table 8 (vesicle, ε⁰ = 0.5 l_max)": (None, ["table8_g1", "table8_g2", "table8_g3"]),
}


def load() -> str:
    one, five, _ = os.getloadavg()
    return f"load average {one:.2f} (1 min), {five:.2f} (5 min)"


def table(headers: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    def cell(value: Any) -> str:
        return f"{value:.3g}" if isinstance(value, float) else str(value)

    lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    lines += ["| " + " | ".join(cell(v) for v in row) + " |" for row in rows]
    return "\n".join(lines)


# ---- emulation --------------------------------------------------------------------------------
class Pool(ThreadPoolExecutor):
    """A thread pool with the ``workers`` attribute of the package's executors."""

    def __init__(self, workers: int) -> None:
        super().__init__(workers)
        self.workers = workers
        for future in [self.submit(time.sleep, 0.01) for _ in range(workers)]:
            future.result()  # start every thread before timing


class SleepingStep:
    """EMULATION: sleep ``seconds``, then one step of dx/dt = -x (exact, or forward Euler)."""

    def __init__(self, seconds: float, exact: bool, rate: float = 1.0) -> None:
        self.seconds, self.exact, self.rate = seconds, exact, rate

    def __call__(self, t_start: float, t_end: float, x: np.ndarray) -> np.ndarray:
        time.sleep(self.seconds)
        h = (t_end - t_start) * self.rate
        return x * math.exp(-h) if self.exact else x * (1.0 - h)


class SleepingExtrapolated:
    """EMULATION: a coarse solver of N_G sleeping auxiliary solves combined with weights summing
    to one, with the ``split`` protocol of :class:`parastokes.parareal.Extrapolated` and, like
    it, its auxiliary solves run at once on an executor in Algorithm 1's coarse steps."""

    def __init__(self, seconds: float, n_auxiliary: int, executor: Any = None) -> None:
        rates = np.linspace(1.0, 1.3, n_auxiliary)
        self.solvers = [SleepingStep(seconds, False, r) for r in rates]
        self.weights = np.full(n_auxiliary, 1.0 / n_auxiliary)
        self.executor = executor
        self.n_auxiliary = n_auxiliary

    def with_executor(self, executor: Any) -> SleepingExtrapolated:
        return SleepingExtrapolated(self.solvers[0].seconds, self.n_auxiliary, executor)

    def split(self, t_start: float, t_end: float, x: np.ndarray):
        tasks = [Task(s, (t_start, t_end, x), f"auxiliary {i}") for i, s in enumerate(self.solvers)]
        return tasks, self.combine

    def combine(self, values: list[np.ndarray]) -> np.ndarray:
        return sum(w * v for w, v in zip(self.weights, values, strict=True))

    def __call__(self, t_start: float, t_end: float, x: np.ndarray) -> np.ndarray:
        tasks, combine = self.split(t_start, t_end, x)
        return combine(parallel.run_tasks(self.executor or parallel.SerialExecutor(), tasks))


def _mean_task(res: parareal.PararealResult, kinds: set[str]) -> float:
    durations = [t[4] - t[3] for t in res.timings.tasks if t[0] in kinds]
    return float(np.mean(durations))


def emulation_grid(quick: bool) -> list[tuple[int, float, int, int]]:
    """The emulated cases (W = P, alpha, K, N_G) of the emulation section."""
    if quick:
        return [(8, a, k, 1) for a in (0.01, 0.3) for k in (1, 2)] + [(16, 0.1, 2, 4)]
    grid = [(w, a, k, 1) for w in (8, 16, 32, 64) for a in (0.01, 0.1, 0.3) for k in (1, 2, 4)]
    return grid + [(16, 0.1, 2, 4), (32, 0.05, 2, 4), (32, 0.1, 4, 4)]


def model_speedups(
    workers: int, alpha: float, iterations: int, n_auxiliary: int = 1
) -> dict[str, dict[str, float]]:
    """Per schedule, the model's speedups of an emulated case with the nominal alpha (P = W
    slices): ``formula``, the closed formula (eq. 14 for the standard schedule, the pipelined
    one's of docs/parareal.md) with a coarse step of ceil(N_G / W) rounds of auxiliary solves,
    and ``simulated``, :func:`parastokes.parareal.simulate`."""
    step_alpha = math.ceil(n_auxiliary / workers) * alpha
    formulas = {"standard": parareal.speedup_standard, "pipelined": parareal.speedup_pipelined}
    return {
        schedule: {
            "formula": formula(step_alpha, iterations, workers),
            "simulated": parareal.simulate(
                schedule, workers, iterations, workers, alpha, 1.0, n_auxiliary
            ).speedup,
        }
        for schedule, formula in formulas.items()
    }


def emulation_case(
    workers: int, alpha: float, iterations: int, fine_s: float, n_auxiliary: int = 1
) -> dict[str, Any]:
    """Both schedules on a pool of ``workers`` threads, P = workers slices (EMULATION)."""
    fine = SleepingStep(fine_s, True)
    if n_auxiliary == 1:
        coarse = SleepingStep(alpha * fine_s, False)
    else:
        coarse = SleepingExtrapolated(alpha * fine_s, n_auxiliary)
    x0 = np.ones(3)
    row: dict[str, Any] = {"workers": workers, "alpha": alpha, "iterations": iterations}
    row["n_auxiliary"] = n_auxiliary
    states = {}
    model = model_speedups(workers, alpha, iterations, n_auxiliary)
    with Pool(workers) as pool:
        for schedule in ("standard", "pipelined"):
            start = time.perf_counter()
            res = parareal.run(
                fine,
                coarse,
                x0,
                0.0,
                1.0,
                workers,
                0.0,
                iterations,
                executor=pool,
                schedule=schedule,
                allow_oversubscribe=True,
            )
            wall = time.perf_counter() - start
            states[schedule] = res.states
            f_cost = _mean_task(res, {"fine"})
            if schedule == "standard" or n_auxiliary == 1:
                g_cost = float(np.mean(np.concatenate(res.timings.coarse)))
            else:
                g_cost = _mean_task(res, {"auxiliary"})
            if schedule == "standard" and n_auxiliary > 1:
                g_cost /= math.ceil(n_auxiliary / workers)  # a step = ceil(N_G / W) rounds
            # the standard schedule runs its coarse sweep on the manager and sends its fine
            # solves in one batch: no hand-over per task to model
            tasks = res.timings.tasks
            latency = 0.0 if schedule == "standard" else parareal.handover_latency(tasks)
            sim = parareal.simulate(
                schedule, workers, iterations, workers, g_cost / f_cost, 1.0, n_auxiliary,
                latency / f_cost,
            )
            bare = parareal.simulate(
                schedule, workers, iterations, workers, g_cost / f_cost, 1.0, n_auxiliary
            )
            row[schedule] = {
                "emulated": True,  # sleeping propagators stand in for the cores
                "wall": wall,
                "speedup": workers * fine_s / wall,
                **model[schedule],
                "simulated_wall": sim.wall * f_cost,
                "fine_task": f_cost,
                "coarse_task": g_cost,
                "latency": latency,
            }
            row[schedule]["wall_vs_simulation"] = wall / row[schedule]["simulated_wall"]
            row[schedule]["wall_vs_bare_simulation"] = wall / (bare.wall * f_cost)
    assert np.array_equal(states["standard"], states["pipelined"]), "iterates differ"
    row["pipelined_gain"] = row["standard"]["wall"] / row["pipelined"]["wall"]
    return row


def gantt_figures(fine_s: float, out: Path) -> None:
    """EMULATION Gantt charts of both schedules: W = P = 8, alpha = 0.2, K = 2."""
    from parastokes.output.gantt import gantt

    out.mkdir(parents=True, exist_ok=True)
    fine, coarse = SleepingStep(fine_s, True), SleepingStep(0.2 * fine_s, False)
    with Pool(8) as pool:
        for schedule in ("standard", "pipelined"):
            res = parareal.run(
                fine, coarse, np.ones(3), 0.0, 1.0, 8, 0.0, 2, executor=pool, schedule=schedule
            )
            title = (
                f"EMULATION (sleeping tasks): {schedule} schedule, 8 slices, 8 workers, "
                f"γ_F = {1000 * fine_s:g} ms, alpha = 0.2, K = 2, wall {res.timings.total:.2f} s"
            )
            gantt(res.timings.tasks, out / f"pipeline_gantt_{schedule}", ["png"], title)


def emulation(args: argparse.Namespace) -> tuple[str, Any]:
    fine_s = args.fine_ms / 1000.0
    if args.figures:
        gantt_figures(fine_s, Path(args.figures))
    grid = emulation_grid(args.quick)
    rows = []
    start = time.perf_counter()
    for w, a, k, n_aux in grid:
        rows.append(emulation_case(w, a, k, fine_s, n_aux))
    spent = time.perf_counter() - start
    lines = [
        f"### EMULATION: sleeping propagators on thread pools (gamma_F = {args.fine_ms:g} ms)",
        "",
        f"{len(grid)} cases, {spent:.0f} s, {load()}. Speedups are EMULATED (N_c gamma_F / wall "
        "with sleeping tasks), not speedups of the physics. 'sim' is the simulation with the "
        "nominal alpha; 'wall/sim' the measured wall over the simulation fed with the run's "
        "measured mean task durations and, for the pipelined schedule, its measured hand-over "
        "latency per task ('latency', see parareal.handover_latency); 'wall/bare' the same "
        "without it.",
        "",
    ]
    headers = [
        "W = P",
        "alpha",
        "K",
        "N_G",
        "std formula",
        "std sim",
        "std emulated",
        "std wall/sim",
        "pipe formula",
        "pipe sim",
        "pipe emulated",
        "pipe wall/sim",
        "pipe wall/bare",
        "latency ms",
        "pipe gain",
    ]
    table_rows = []
    for r in rows:
        s, p = r["standard"], r["pipelined"]
        table_rows.append(
            [
                r["workers"],
                r["alpha"],
                r["iterations"],
                r["n_auxiliary"],
                s["formula"],
                s["simulated"],
                s["speedup"],
                s["wall_vs_simulation"],
                p["formula"],
                p["simulated"],
                p["speedup"],
                p["wall_vs_simulation"],
                p["wall_vs_bare_simulation"],
                1000.0 * p["latency"],
                r["pipelined_gain"],
            ]
        )
    lines.append(table(headers, table_rows))
    ratios = [r[s]["wall_vs_simulation"] for r in rows for s in ("standard", "pipelined")]
    target = [r for r in rows if r["alpha"] >= 0.1 and r["iterations"] >= 2 and r["workers"] >= 16]
    lines += [
        "",
        f"wall / simulation: {min(ratios):.3f} - {max(ratios):.3f} (target: within 10 %); "
        f"{sum(abs(x - 1) <= 0.1 for x in ratios)} of {len(ratios)} runs within 10 %.",
    ]
    bare = [r["pipelined"]["wall_vs_bare_simulation"] for r in rows]
    lines.append(
        f"pipelined wall / simulation without the hand-over latency: {min(bare):.3f} - "
        f"{max(bare):.3f}; {sum(abs(x - 1) <= 0.1 for x in bare)} of {len(bare)} within 10 %."
    )
    if target:
        gains = [r["pipelined_gain"] for r in target]
        lines.append(
            f"pipelined / standard wall, alpha >= 0.1, K >= 2, P >= 16: {min(gains):.2f} - "
            f"{max(gains):.2f}x (target >= 1.3x)."
        )
    return "\n".join(lines), rows


# ---- real runs on this machine ----------------------------------------------------------------
def real(args: argparse.Namespace) -> tuple[str, Any]:
    from benchmarks.parareal import rod_case, vesicle_case

    n_slices, iterations, workers = 4, 2, 2
    cases = [rod_case(1, 1.5e-4 if args.quick else 4e-4), vesicle_case(0.15 if args.quick else 0.4)]
    rows = []
    for case in cases:
        with parallel.make_executor("processes", workers, warmup=case.warmup()) as pool:
            case.warmup()()
            walls: dict[str, list[float]] = {"standard": [], "pipelined": []}
            results = {}
            for _ in range(1 if args.quick else 2):
                for schedule in ("standard", "pipelined"):  # interleaved
                    start = time.perf_counter()
                    res = parareal.run(
                        case.fine,
                        case.coarse,
                        case.x0,
                        0.0,
                        n_slices * case.slice_length,
                        n_slices,
                        0.0,
                        iterations,
                        executor=pool,
                        project=case.system.project,
                        positions=case.system.positions,
                        schedule=schedule,
                    )
                    elapsed = time.perf_counter() - start
                    if not walls[schedule] or elapsed < min(walls[schedule]):
                        results[schedule] = res  # the fastest repeat: its wall and its γ's
                    walls[schedule].append(elapsed)
        std, pipe = results["standard"], results["pipelined"]
        assert np.array_equal(std.states, pipe.states), "iterates differ"
        n_aux = (
            case.coarse.propagator.n_auxiliary
            if hasattr(case.coarse, "propagator")
            else (case.coarse.n_auxiliary)
        )
        row = {"case": case.name, "n_auxiliary": n_aux, "same_iterates": True}
        for schedule, res in results.items():
            gamma_f = res.timings.gamma_f
            if schedule == "standard":
                aux = res.timings.gamma_g  # N_G <= W: one round per coarse step
            else:
                aux = _mean_task(res, {"auxiliary"})
            sim = parareal.simulate(
                schedule, n_slices, iterations, workers, aux / gamma_f, 1.0, n_aux
            )
            wall = min(walls[schedule])  # the repeat whose timings ``res`` holds
            row[schedule] = {
                "wall": wall,
                "walls": walls[schedule],
                "gamma_f": gamma_f,
                "gamma_aux": aux,
                "simulated_wall": sim.wall * gamma_f,
                "wall_vs_simulation": wall / (sim.wall * gamma_f),
            }
        row["pipelined_gain"] = row["standard"]["wall"] / row["pipelined"]["wall"]
        rows.append(row)
    headers = [
        "case",
        "N_G",
        "gamma_F (s)",
        "gamma_aux/gamma_F",
        "std wall (s)",
        "std sim (s)",
        "std wall/sim",
        "pipe wall (s)",
        "pipe sim (s)",
        "pipe wall/sim",
        "pipe gain",
    ]
    table_rows = [
        [
            r["case"],
            r["n_auxiliary"],
            r["standard"]["gamma_f"],
            r["standard"]["gamma_aux"] / r["standard"]["gamma_f"],
            r["standard"]["wall"],
            r["standard"]["simulated_wall"],
            r["standard"]["wall_vs_simulation"],
            r["pipelined"]["wall"],
            r["pipelined"]["simulated_wall"],
            r["pipelined"]["wall_vs_simulation"],
            r["pipelined_gain"],
        ]
        for r in rows
    ]
    text = "\n".join(
        [
            f"### Real runs: {n_slices} slices, K = {iterations}, {workers} worker processes",
            "",
            f"{load()}; best of the interleaved runs; iterates of both schedules bit-identical "
            "(asserted).",
            "",
            table(headers, table_rows),
        ]
    )
    return text, rows


# ---- the P = 40 comparison --------------------------------------------------------------------
CORES = 40  # the paper's cores: P = 40 slices, one worker each
FULL, RUNNING, SHORT, GIVEN = (
    "full-scale",
    "full-scale, run in progress",
    "shortened analogue",
    "given (--errors)",
)
RANK = {FULL: 0, RUNNING: 1}  # other records rank after these


@dataclass(frozen=True)
class Errors:
    """eta^1, eta^2, ... of one coarse solver, where they come from (``source``: one of FULL,
    RUNNING, SHORT, GIVEN) and the file or command behind them (``where``)."""

    values: list[float]
    source: str
    where: str


def _leading(values: Sequence[float | None]) -> list[float]:
    """eta^1, eta^2, ... up to the first missing one."""
    out = []
    for value in values:
        if value is None:
            break
        out.append(float(value))
    return out


def parse_record(path: Path) -> tuple[str, Errors] | None:
    """The solver name and eta^k of one reproduction record, or None when ``path`` holds none.

    Two formats of :mod:`validation.reproduce`: the summary of a finished run (``result.json``,
    ``docs/reproduction/NAME.json``: ``name``, ``errors``, ``problem.parareal.n_slices``),
    full-scale when it has the paper's 40 slices; and ``progress.json`` of a run still going
    (``iterations``: ``k``, ``error``), named by its directory (the reproduction runs
    experiments/NAME.toml unchanged).
    """
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict):
        return None
    if isinstance(data.get("errors"), list):
        n_slices = data.get("problem", {}).get("parareal", {}).get("n_slices")
        source = FULL if n_slices == CORES else f"record with {n_slices} slices"
        return data.get("name", path.stem), Errors(_leading(data["errors"]), source, str(path))
    rows = data.get("iterations")
    if path.name == "progress.json" and isinstance(rows, list):
        rows = sorted(rows, key=lambda r: r["k"])
        if [r["k"] for r in rows] != list(range(1, len(rows) + 1)):
            return None
        return path.parent.name, Errors(_leading([r["error"] for r in rows]), RUNNING, str(path))
    return None


def read_errors(paths: Sequence[Path]) -> dict[str, Errors]:
    """eta^k per solver from reproduction records: files, or folders holding ``NAME.json`` (as
    docs/reproduction/) or ``NAME/result.json`` and ``NAME/progress.json`` (as the runs folder of
    ``validation.reproduce``). Per solver, a finished full-scale run beats a running one, and then
    the record with more iterations wins. A file named explicitly that holds no record is an
    error; files in folders that hold none are skipped."""
    found: dict[str, Errors] = {}
    for path in map(Path, paths):
        if path.is_dir():
            files = [*sorted(path.glob("*.json")), *sorted(path.glob("*/result.json"))]
            files += sorted(path.glob("*/progress.json"))
            records = [r for r in map(parse_record, files) if r is not None]
        elif path.is_file():
            record = parse_record(path)
            if record is None:
                raise ValueError(
                    f"--records: {path} is not a reproduction record (a run's result.json or "
                    "progress.json, or docs/reproduction/NAME.json)"
                )
            records = [record]
        else:
            raise ValueError(f"--records: {path} does not exist")
        for name, errors in records:
            if not errors.values:
                continue
            old = found.get(name)
            key = (RANK.get(errors.source, 9), -len(errors.values))
            if old is None or key < (RANK.get(old.source, 9), -len(old.values)):
                found[name] = errors
    return found


def choose_errors(
    names: Sequence[str], records: dict[str, Errors], given: dict[str, list[float]]
) -> dict[str, Errors]:
    """Per solver: its reproduction record, else eta^k given with --errors, else the shortened
    analogue's (ERRORS); solvers with none are left out."""
    out = {}
    for name in names:
        if name in records:
            out[name] = records[name]
        elif name in given:
            out[name] = Errors([float(v) for v in given[name]], GIVEN, "--errors")
        elif name in ERRORS:
            quick = ROOT / "experiments" / "quick" / f"{name}.toml"
            cfg, _ = config.load(quick)
            span = f"{SHORT}, {cfg.parareal.n_slices} slices over T = {cfg.time.t1:g}"
            out[name] = Errors(ERRORS[name], span, str(quick.relative_to(ROOT)))
    return out


def measure_costs(
    names: Sequence[str], repeats: int, fine_steps: int, coarse_steps: int
) -> dict[str, dict[str, Any]]:
    """Per configuration experiments/NAME.toml at full size: :func:`parareal.measure_slice_costs`
    on its first slice (CPU time of this process, see the module docstring), and the operation
    count estimate of ``parastokes predict`` for comparison."""
    from parastokes.config import build
    from validation.reproduce import OVERRIDES

    out = {}
    for name in names:
        cfg, resolved = config.load(ROOT / "experiments" / f"{name}.toml", list(OVERRIDES))
        start = time.perf_counter()
        setup = build(cfg, resolved)
        times = parareal.time_points(cfg.time.t0, cfg.time.t1, cfg.parareal.n_slices)
        costs = parareal.measure_slice_costs(
            setup.fine,
            setup.coarse,
            float(times[0]),
            float(times[1]),
            setup.system.initial_state(),
            repeats=repeats,
            fine_steps=fine_steps,
            coarse_steps=coarse_steps,
            clock=time.process_time,
        )
        row = costs.as_dict()
        row["gamma_ratio_standard"] = costs.gamma_ratio(CORES)
        row["estimated_ratio"] = cli.estimated_gamma_ratio(cfg, resolved, CORES)
        row["probe_wall_s"] = time.perf_counter() - start
        out[name] = row
        print(
            f"{name}: gamma_F {row['gamma_F_s']:.3g} s, gamma_G/gamma_F "
            f"{row['gamma_ratio']:.4g} (estimate {row['estimated_ratio']:.4g}), "
            f"{row['probe_wall_s']:.0f} s",
            flush=True,
        )
    return out


def speedups(ratio: float, n_aux: int, ks: Sequence[int]) -> dict[str, list[float]]:
    """Simulated speedups on P = W = 40 for K in ``ks``, each auxiliary solve a task of cost
    ``ratio`` gamma_F, and the closed formulas (alpha = ratio, N_G <= 40)."""
    out: dict[str, list[float]] = {}
    for schedule in ("standard", "pipelined"):
        out[schedule] = [
            parareal.simulate(schedule, CORES, k, CORES, ratio, 1.0, n_aux).speedup for k in ks
        ]
    out["standard_formula"] = [parareal.speedup_standard(ratio, k, CORES) for k in ks]
    out["pipelined_formula"] = [parareal.speedup_pipelined(ratio, k, CORES) for k in ks]
    return out


def scale(source: str) -> str:
    """The curve a solver's eta^k belong to: full-scale (finished or running runs) or not."""
    return "full-scale" if source in (FULL, RUNNING) else source


def curve_label(kind: str, solvers: Sequence[str], errors: dict[str, Errors]) -> str:
    """The legend of a curve, e.g. ``extrapolated g1 (K <= 4), g3 (K <= 2, running): full-scale
    eta^k`` (the solvers whose best speedup it draws, and where their eta^k come from)."""
    parts = []
    for name in solvers:
        eta = errors[name]
        running = ", running" if eta.source == RUNNING else ""
        parts.append(f"{name.split('_', 1)[1]} (K ≤ {len(eta.values)}{running})")
    source = scale(errors[solvers[0]].source).replace(f"{SHORT}, ", "shortened, ")
    source = source.replace(" slices over ", " slices, ")
    return f"{kind} {', '.join(parts)}: {source} η^k"


def p40(args: argparse.Namespace) -> tuple[str, Any]:
    names = [n for plain, extra in TABLES.values() for n in ([plain] if plain else []) + extra]
    settings = {k: getattr(args, k) for k in ("repeats", "fine_steps", "coarse_steps")}
    if args.costs and Path(args.costs).exists():
        saved = json.loads(Path(args.costs).read_text())
        costs, settings = saved["costs"], saved["settings"]
        costs_note = f"γ ratios read from {args.costs} ({saved['note']})"
    else:
        before = load()
        start = time.perf_counter()
        costs = measure_costs(names, args.repeats, args.fine_steps, args.coarse_steps)
        costs_note = (
            f"γ ratios measured now: {time.perf_counter() - start:.0f} s for {len(names)} "
            f"configurations, {before} before, {load()} after"
        )
        if args.costs:
            Path(args.costs).write_text(
                json.dumps(
                    {"note": costs_note, "settings": settings, "costs": costs},
                    indent=1,
                    default=float,
                )
            )
    given = json.loads(Path(args.errors).read_text()) if args.errors else {}
    errors = choose_errors(names, read_errors(args.records or []), given)
    ks = (1, 2, 3, 4)
    rows, curves = [], {}
    desired = np.logspace(-15, -2, 500)
    for label, (plain, extrapolated) in TABLES.items():
        groups: dict[tuple[str, str], list[str]] = {}
        for name in ([plain] if plain else []) + extrapolated:
            cost = costs[name]
            ratio, n_aux = cost["gamma_ratio"], cost["n_auxiliary"]
            mean_inputs = (cost["auxiliary_slice_s"], cost["fine_slice_s"])
            speed = speedups(ratio, n_aux, ks)
            eta = errors.get(name)
            kind = "plain" if name == plain else "extrapolated"
            rows.append(
                {
                    "table": label,
                    "solver": name,
                    "kind": kind,
                    "n_auxiliary": n_aux,
                    "gamma_F_s": cost["gamma_F_s"],
                    "ratio": ratio,
                    "mean_ratio": statistics.median(
                        float(np.mean(aux)) / fine
                        for aux, fine in zip(*mean_inputs, strict=True)
                    ),
                    "estimated_ratio": cost["estimated_ratio"],
                    "overhead_s": statistics.median(cost["overhead_s"]),
                    "linearity": [min(cost["linearity"]), max(cost["linearity"])],
                    "errors": eta.values if eta else None,
                    "errors_source": eta.source if eta else None,
                    "errors_from": eta.where if eta else None,
                    **speed,
                }
            )
            if eta:
                groups.setdefault((kind, scale(eta.source)), []).append(name)
        for (kind, source), solvers in groups.items():
            text = curve_label(kind, solvers, errors)
            for schedule in ("standard", "pipelined"):
                best = np.full(len(desired), np.nan)
                for row in rows:
                    if row["solver"] in solvers and row["table"] == label:
                        values = errors[row["solver"]].values[: len(ks)]
                        best = np.fmax(best, staircase(values, row[schedule], desired))
                curves[label, kind, source, schedule] = (best, solvers, text)
    text = p40_text(rows, costs_note, settings)
    if args.figures and curves:
        draw_p40(curves, desired, Path(args.figures))
    serial = {" | ".join(k): v[0].tolist() for k, v in curves.items()}
    return text, {"rows": rows, "costs": costs, "desired": desired.tolist(), "curves": serial}


def _k_range(row: dict[str, Any]) -> list[int]:
    """The iteration counts shown for a row: those with an eta^k, else K = 1..4."""
    n = len(row["errors"] or []) or 4
    return list(range(1, min(n, 4) + 1))


def span(low: float, high: float, form: str, between: str) -> str:
    """``low`` to ``high`` formatted, one number when they read the same, no "-0"."""
    texts = map(form.format, (low, high))
    a, b = (text.lstrip("-") if float(text) == 0 else text for text in texts)
    return a if a == b else f"{a}{between}{b}"


def p40_text(rows: list[dict[str, Any]], costs_note: str, settings: dict[str, int]) -> str:
    head = [
        f"### P = {CORES}: standard vs pipelined, plain vs extrapolated coarse solvers, measured γ",
        "",
        f"{costs_note}. CPU time of this process per solve, first slice of experiments/NAME.toml "
        f"at full size; fine solver timed over {settings['fine_steps']} and "
        f"{2 * settings['fine_steps']} steps, auxiliary solves over {settings['coarse_steps']} "
        "steps, each scaled to the slice by its step count; median of "
        f"{settings['repeats']} repeats of ratios formed within one repeat.",
        "",
    ]
    cost_table = table(
        [
            "table",
            "coarse solver",
            "N_G",
            "γ_F (CPU s)",
            "(max aux + comb.)/γ_F",
            "mean aux/γ_F",
            "estimate",
            "combination (ms)",
            "t(2n)/2t(n)",
        ],
        [
            [
                r["table"],
                r["solver"] + (" (plain)" if r["kind"] == "plain" else ""),
                r["n_auxiliary"],
                r["gamma_F_s"],
                r["ratio"],
                r["mean_ratio"],
                r["estimated_ratio"],
                1000 * r["overhead_s"],
                f"{r['linearity'][0]:.3f}-{r['linearity'][1]:.3f}",
            ]
            for r in rows
        ],
    )
    speed_rows = []
    for r in rows:
        ks = _k_range(r)
        pairs = [f"{r['standard'][k - 1]:.2f} / {r['pipelined'][k - 1]:.2f}" for k in ks]
        gains = [r["pipelined"][k - 1] / r["standard"][k - 1] for k in ks]
        eta = " ".join(f"{e:.1e}" for e in r["errors"][:4]) if r["errors"] else "-"
        speed_rows.append(
            [
                r["table"],
                r["solver"] + (" (plain)" if r["kind"] == "plain" else ""),
                r["errors_source"] or "none",
                eta,
                *(pairs + [""] * (4 - len(pairs))),
                span(min(gains), max(gains), "{:.2f}", "-"),
                span(100 * (1 - 1 / min(gains)), 100 * (1 - 1 / max(gains)), "{:.0f}", " to ")
                + " %",
            ]
        )
    speed_table = table(
        [
            "table",
            "coarse solver",
            "η^k source",
            "η^1 .. η^4",
            "K = 1 std / pipe",
            "K = 2",
            "K = 3",
            "K = 4",
            "pipe / std",
            "wall time cut",
        ],
        speed_rows,
    )
    return "\n".join(
        head
        + [cost_table, "", "Simulated speedups N γ_F / wall on 40 workers (K up to the η^k known):"]
        + ["", speed_table]
    )


def draw_p40(curves: dict, desired: np.ndarray, out: Path) -> None:
    """Fig. 6b-like: speedup against desired error, one curve per (coarse solver, schedule)."""
    from matplotlib.figure import Figure

    tables = list(dict.fromkeys(key[0] for key in curves))
    columns = min(3, len(tables))
    rows = math.ceil(len(tables) / columns)
    fig = Figure(figsize=(5.4 * columns, 5.6 * rows))
    axes = np.atleast_1d(fig.subplots(rows, columns)).ravel()
    fig.subplots_adjust(hspace=0.75, wspace=0.25)
    palette = {"plain": ["C0", "C9"], "extrapolated": ["C3", "C1", "C4"]}
    for ax, label in zip(axes, tables, strict=False):
        groups = sorted(
            {k[1:3] for k in curves if k[0] == label}, key=lambda g: (g[1] != "full-scale", g)
        )
        for (table_label, kind, source, schedule), (curve, _, text) in curves.items():
            if table_label != label:
                continue
            same_kind = [g for g in groups if g[0] == kind]
            full = source == "full-scale"
            ax.semilogx(
                desired,
                curve,
                color=palette[kind][same_kind.index((kind, source)) % len(palette[kind])],
                linestyle="-" if schedule == "pipelined" else "--",
                linewidth=1.8 if full else 1.1,
                label=f"{text}, {schedule}",
            )
        ax.set_title(f"{label}, P = 40 (model, measured γ)", fontsize=8)
        ax.set_xlabel("desired relative error η")
        ax.set_ylabel("speedup (simulated)")
        ax.grid(True, alpha=0.3, which="both")
        ax.legend(fontsize=6, loc="upper center", bbox_to_anchor=(0.5, -0.15))
    for ax in axes[len(tables):]:
        ax.set_visible(False)
    out.mkdir(parents=True, exist_ok=True)
    fig.savefig(out / "pipeline_p40.png", dpi=150, bbox_inches="tight")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sections", nargs="+", choices=SECTIONS, default=list(SECTIONS))
    parser.add_argument(
        "--quick", action="store_true", help="fewer and shorter cases (p40: 1 repeat of 20 steps)"
    )
    parser.add_argument("--fine-ms", type=float, default=150.0, help="emulated gamma_F (ms)")
    parser.add_argument("--errors", help="JSON {config name: [eta^1, eta^2, ...]} for p40")
    parser.add_argument(
        "--records",
        nargs="+",
        type=Path,
        help="p40: reproduction records (files, docs/reproduction/, the runs folder) for eta^k",
    )
    parser.add_argument(
        "--costs", help="p40: JSON of measured gamma ratios: read if it exists, else written"
    )
    parser.add_argument("--repeats", type=int, default=3, help="p40: repeats of each timing")
    parser.add_argument("--fine-steps", type=int, default=200, help="p40: fine steps timed (n)")
    parser.add_argument("--coarse-steps", type=int, default=50, help="p40: coarse steps timed")
    parser.add_argument("--json", help="write every number as JSON here")
    parser.add_argument("--out", help="write the tables as Markdown here")
    parser.add_argument("--figures", help="directory for pipeline_p40.png")
    args = parser.parse_args(argv)
    if args.quick:  # p40: a smoke run of the measurement
        args.repeats, args.fine_steps, args.coarse_steps = 1, 20, 20
    functions = {"emulation": emulation, "real": real, "p40": p40}
    texts, data = [], {}
    for section in args.sections:
        text, data[section] = functions[section](args)
        print(text, "\n", flush=True)
        texts.append(text)
    if args.out:
        Path(args.out).write_text("\n\n".join(texts) + "\n")
    if args.json:
        Path(args.json).write_text(json.dumps(data, indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
