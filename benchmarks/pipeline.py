"""Pipelined against standard Parareal: emulation, real runs, and the P = 40 comparison.

Run from the repository root::

    PYTHONPATH=. python benchmarks/pipeline.py [--sections emulation real p40] [--quick] \\
        [--fine-ms 150] [--json PATH] [--out PATH] [--figures DIR]

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
  solvers (Tables 4, 5, 6, 7), from gamma ratios estimated from step counts and (points)^2 of the
  paper's configurations (``parastokes predict``'s estimate, N_G auxiliary solves as separate
  tasks) and the iteration counts needed for a desired error, from the errors eta^k in ERRORS.
  A table for K = 1..4 and a figure (speedup against desired error, like Fig. 6b).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from parastokes import cli, config, parallel, parareal
from parastokes.parallel import Task
from parastokes.plots import staircase

ROOT = Path(__file__).resolve().parents[1]
SECTIONS = ("emulation", "real", "p40")

# eta^k (k = 1, 2, 3) measured on the quick variants of the paper's configurations (4 slices,
# short T; experiments/quick/), in one process:
#   parastokes run experiments/quick/NAME.toml --out DIR --set 'execution.executor="serial"' \
#       --set execution.workers=1 --set parareal.max_iterations=3
# The paper's P = 40 runs need their own errors (the reproduction runs); pass them with --errors.
ERRORS: dict[str, list[float]] = {
    "table4_g1": [3.3385e-08, 1.2685e-10, 2.8105e-11],
    "table4_g2": [9.6965e-07, 8.1847e-07, 2.7415e-07],
    "table4_g3": [5.2593e-11, 4.9989e-11, 1.6650e-11],
    "table4_g4": [7.2947e-08, 4.3220e-10, 1.0303e-12],
}

# gamma_G / gamma_F measured by benchmarks/parareal.py (docs/benchmarks.md, "Speedup against
# eq. 14", processes) for the Table 6 coarse solver (N_G = 2, both auxiliary solves at once): the
# estimate from operation counts misses the per-call costs of the 51-point coarse grid.
MEASURED_RATIOS = {"table6_eps3": 0.0123}

# The paper's configurations compared at P = 40: (table, plain G_{Theta^0, tau}, extrapolated).
TABLES = {
    "Table 4 (rod, eps0 = 5 sigma_f)": ("table4_g4", ["table4_g1", "table4_g2", "table4_g3"]),
    "Table 5 (rod, eps0 = 7 sigma_f)": (None, ["table5_g1", "table5_g2", "table5_g3"]),
    "Table 6 (rod, eps0 = 3 sigma_f)": (None, ["table6_eps3"]),
    "Table 7 (vesicle)": ("table7_g4", ["table7_g1", "table7_g2", "table7_g3"]),
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
            nominal = parareal.simulate(
                schedule, workers, iterations, workers, alpha, 1.0, n_auxiliary
            )
            formula = {
                "standard": parareal.speedup_standard,
                "pipelined": parareal.speedup_pipelined,
            }[schedule]
            step_alpha = math.ceil(n_auxiliary / workers) * alpha
            row[schedule] = {
                "wall": wall,
                "speedup": workers * fine_s / wall,
                "formula": formula(step_alpha, iterations, workers),
                "simulated": nominal.speedup,
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
    from parastokes.plots_gantt import gantt

    out.mkdir(parents=True, exist_ok=True)
    fine, coarse = SleepingStep(fine_s, True), SleepingStep(0.2 * fine_s, False)
    with Pool(8) as pool:
        for schedule in ("standard", "pipelined"):
            res = parareal.run(
                fine, coarse, np.ones(3), 0.0, 1.0, 8, 0.0, 2, executor=pool, schedule=schedule
            )
            title = (
                f"EMULATION (sleeping tasks): {schedule} schedule, 8 slices, 8 workers, "
                f"alpha = 0.2, K = 2, wall {res.timings.total:.2f} s"
            )
            gantt(res.timings.tasks, out / f"pipeline_gantt_{schedule}", ["png"], title)


def emulation(args: argparse.Namespace) -> tuple[str, Any]:
    fine_s = args.fine_ms / 1000.0
    if args.figures:
        gantt_figures(fine_s, Path(args.figures))
    if args.quick:
        grid = [(8, a, k, 1) for a in (0.01, 0.3) for k in (1, 2)] + [(16, 0.1, 2, 4)]
    else:
        grid = [(w, a, k, 1) for w in (8, 16, 32, 64) for a in (0.01, 0.1, 0.3) for k in (1, 2, 4)]
        grid += [(16, 0.1, 2, 4), (32, 0.05, 2, 4), (32, 0.1, 4, 4)]
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
        "std measured",
        "std wall/sim",
        "pipe formula",
        "pipe sim",
        "pipe measured",
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
                    walls[schedule].append(time.perf_counter() - start)
                    results[schedule] = res
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
            wall = min(walls[schedule])
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
        "pipe wall/bare",
        "latency ms",
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
def solver_costs(name: str) -> tuple[int, float]:
    """N_G and gamma of one auxiliary solve over gamma_F, estimated for experiments/NAME.toml."""
    cfg, resolved = config.load(ROOT / "experiments" / f"{name}.toml")
    n_aux = resolved.n_auxiliary
    return n_aux, cli.estimated_gamma_ratio(cfg, resolved, n_aux)


def p40(args: argparse.Namespace) -> tuple[str, Any]:
    errors = dict(ERRORS)
    if args.errors:
        errors.update(json.loads(Path(args.errors).read_text()))
    cores, ks = 40, (1, 2, 3, 4)
    rows, curves = [], {}
    desired = np.logspace(-12, -2, 400)
    for label, (plain, extrapolated) in TABLES.items():
        variants = [(name, *solver_costs(name), "") for name in ([plain] if plain else [])]
        for name in extrapolated:
            variants.append((name, *solver_costs(name), ""))
            if name in MEASURED_RATIOS:
                variants.append((name, variants[-1][1], MEASURED_RATIOS[name], " (measured γ)"))
        for name, n_aux, aux, note in variants:
            speedups = {}
            for schedule in ("standard", "pipelined"):
                speedups[schedule] = [
                    parareal.simulate(schedule, cores, k, cores, aux, 1.0, n_aux).speedup
                    for k in ks
                ]
            alpha = math.ceil(n_aux / cores) * aux
            for i, k in enumerate(ks):
                rows.append(
                    {
                        "table": label,
                        "solver": name + note,
                        "plain": name == plain,
                        "n_auxiliary": n_aux,
                        "alpha_auxiliary": aux,
                        "iterations": k,
                        "standard_formula": parareal.speedup_standard(alpha, k, cores),
                        "standard": speedups["standard"][i],
                        "pipelined_formula": parareal.speedup_pipelined(alpha, k, cores),
                        "pipelined": speedups["pipelined"][i],
                    }
                )
            if name in errors and not note:
                eta = errors[name][: len(ks)]
                for schedule in ("standard", "pipelined"):
                    curve = staircase(eta, speedups[schedule], desired)
                    kind = "plain" if name == plain else "extrapolated"
                    key = (label, kind, schedule)
                    best = curves.get(key, np.full(len(desired), np.nan))
                    curves[key] = np.fmax(best, curve)
    headers = [
        "table",
        "coarse solver",
        "N_G",
        "gamma_aux/gamma_F",
        "K",
        "std formula",
        "std sim",
        "pipe formula",
        "pipe sim",
        "pipe/std",
    ]
    table_rows = [
        [
            r["table"],
            r["solver"] + (" (plain)" if r["plain"] else ""),
            r["n_auxiliary"],
            r["alpha_auxiliary"],
            r["iterations"],
            r["standard_formula"],
            r["standard"],
            r["pipelined_formula"],
            r["pipelined"],
            r["pipelined"] / r["standard"],
        ]
        for r in rows
    ]
    text = "\n".join(
        [
            f"### P = {cores}: standard vs pipelined, plain vs extrapolated coarse solvers (model)",
            "",
            "Simulated on 40 workers (one per slice), every auxiliary solve a task; gamma ratios "
            "estimated from step counts and (points)^2 of experiments/NAME.toml.",
            "",
            table(headers, table_rows),
        ]
    )
    if args.figures and curves:
        draw_p40(curves, desired, Path(args.figures))
    return text, {"rows": rows, "errors": errors}


def draw_p40(curves: dict, desired: np.ndarray, out: Path) -> None:
    """Fig. 6b-like: speedup against desired error, one curve per (coarse solver, schedule)."""
    from matplotlib.figure import Figure

    tables = sorted({key[0] for key in curves})
    fig = Figure(figsize=(5.5 * len(tables), 4))
    axes = np.atleast_1d(fig.subplots(1, len(tables)))
    styles = {
        ("plain", "standard"): ("C0", "--"),
        ("plain", "pipelined"): ("C0", "-"),
        ("extrapolated", "standard"): ("C3", "--"),
        ("extrapolated", "pipelined"): ("C3", "-"),
    }
    for ax, label in zip(axes, tables, strict=True):
        for (table_label, kind, schedule), curve in sorted(curves.items()):
            if table_label != label:
                continue
            color, line = styles[kind, schedule]
            ax.semilogx(desired, curve, color=color, linestyle=line, label=f"{kind}, {schedule}")
        ax.set_title(f"{label}, P = 40 (model)", fontsize=9)
        ax.set_xlabel("desired relative error eta")
        ax.set_ylabel("speedup (simulated)")
        ax.grid(True, alpha=0.3, which="both")
        ax.legend(fontsize=7)
    out.mkdir(parents=True, exist_ok=True)
    fig.savefig(out / "pipeline_p40.png", dpi=150, bbox_inches="tight")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sections", nargs="+", choices=SECTIONS, default=list(SECTIONS))
    parser.add_argument("--quick", action="store_true", help="fewer and shorter cases")
    parser.add_argument("--fine-ms", type=float, default=150.0, help="emulated gamma_F (ms)")
    parser.add_argument("--errors", help="JSON {config name: [eta^1, eta^2, ...]} for p40")
    parser.add_argument("--json", help="write every number as JSON here")
    parser.add_argument("--out", help="write the tables as Markdown here")
    parser.add_argument("--figures", help="directory for pipeline_p40.png")
    args = parser.parse_args(argv)
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
