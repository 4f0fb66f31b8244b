"""Parareal benchmarks: speedup against eq. 14, executor overhead, Figs. 9 and 10.

Run from the repository root::

    PYTHONPATH=. python benchmarks/parareal.py [--quick] [--sections ...] [--cores C] \\
        [--out PATH] [--json PATH]
    PYTHONPATH=. mpiexec -n 3 python -m mpi4py.futures benchmarks/parareal.py --executor mpi \\
        --sections overhead speedup

Sections (all by default; ``--executor mpi`` runs ``overhead`` and ``speedup`` on the launch's
worker ranks, the other sections need pools of several sizes and use processes):

- ``overhead``: per-task cost of each executor (serial, processes, or mpi), a rod state
  (301 x 12 float64) sent to a worker and back: all tasks submitted at once (throughput) and one
  at a time (latency).
- ``speedup``: measured against theoretical speedup (eq. 14 with Upsilon_oh = 0) for a rod case
  (epsilon^0 = 3 sigma_f, the coarse solver of Table 6: tau_c = 7 tau_f, sigma_c = 6 sigma_f,
  epsilon^j / sigma_f = 4.0, 4.1) and a vesicle case (epsilon^0 = 0.3 l_max, RK2 tau_f = 1e-3;
  coarse: Euler tau_c = 5 tau_f, epsilon^j / epsilon^0 = 1.3, 1.45, i.e. Table 7's G^3 with two
  nodes and no Richardson step, so that N_G = 2), one slice
  per worker, slices of a few seconds of fine work. "measured" is eq. 14 as the paper defines it
  (Upsilon_F = N_c gamma_F, eq. 13); "vs serial run" divides the wall time of an actual serial
  fine run by Upsilon_pr instead.
- ``scaling``: Fig. 9 for the rod case on N_c = 1, 2, 4, ... <= cores: strong scaling (T fixed,
  N_it = 1..3, serial and parallel sweep times, measured and theoretical speedup) and weak scaling
  (T / N_c fixed, N_it = 1: runtime against eq. 37, 2 N_c gamma_G + gamma_F).
- ``fig10``: five rods (N_sigma = 1505), the same coarse solver, stopping at eta~ < 1e-5, T fixed:
  speedup (eq. 35) of the spatially parallel F (threads; blocks of targets on processes), of
  Parareal (temporal) and of both (N_c / 2 workers of 2 threads each, when N_c >= 4).

``--out`` writes the tables as Markdown; ``--json`` writes the same numbers as a plain dict
(:func:`benchmark_json`), which ``parastokes plot --benchmark FILE.json`` draws (Figs. 9 and 10).

Serial fine times are measured in this process with one kernel thread; workers run one thread
each (``threads_per_worker``). The load average is printed with every section: other work on the
machine shows up there, and in the measured speedups.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import math
import os
import platform
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from concurrent.futures import Executor
from pathlib import Path
from typing import Any

import numba
import numpy as np

from parastokes import integrate, models, parallel, parareal
from parastokes.parallel import spatial

SECTIONS = ("overhead", "speedup", "scaling", "fig10", "memo")
TARGET = 0.9  # measured speedup >= 90 % of the theoretical one on 2 workers


@dataclasses.dataclass(frozen=True)
class Case:
    """A Parareal problem: fine F, coarse G and the length of one slice in the speedup runs."""

    name: str
    system: Any
    fine: integrate.Propagator
    coarse: Any
    slice_length: float

    @property
    def x0(self) -> np.ndarray:
        return self.system.initial_state()

    def warmup(self) -> Callable[[], Any]:
        """A picklable warm-up: one fine step, so that workers load the kernels before timing."""
        dt = self.fine.dt
        return functools.partial(integrate.propagate, self.system, self.x0, 0.0, dt, "rk2", dt)


def rod_case(n_rods: int, slice_length: float) -> Case:
    """epsilon^0 = 3 sigma_f (sigma_f = 0.2), tau_f = 1e-6; coarse solver of Table 6."""
    rod = models.rod_swimmer(n_rods=n_rods, epsilon=0.6)
    coarse = parareal.extrapolated(rod, "euler", 7e-6, lagrange={"epsilon": [0.8, 0.82]}, grid=6)
    name = "rod" if n_rods == 1 else f"{n_rods} rods"
    return Case(name, rod, integrate.Propagator(rod, "rk2", 1e-6), coarse, slice_length)


def vesicle_case(slice_length: float) -> Case:
    """eps^0 = 0.3 l_max, RK2 tau_f = 1e-3; coarse: Euler 5 tau_f, eps^j / eps^0 = 1.3, 1.45.

    (With 10 tau_f and nodes 1.6, 1.9 the coarse solver is accurate from the sphere but near its
    stability limit from a perturbed state: eta^1 = 5e-3 instead of 3e-7 on 2 slices of 1.0.)
    """
    ves = models.vesicle()
    nodes = [1.3 * ves.epsilon, 1.45 * ves.epsilon]
    coarse = parareal.extrapolated(ves, "euler", 5e-3, lagrange={"epsilon": nodes})
    return Case("vesicle", ves, integrate.Propagator(ves, "rk2", 1e-3), coarse, slice_length)


# ---- helpers ----------------------------------------------------------------------------------


def load() -> str:
    one, five, _ = os.getloadavg()
    return f"load average {one:.2f} (1 min), {five:.2f} (5 min)"


def timed(fn: Callable[..., Any], *args: Any) -> tuple[Any, float]:
    start = time.perf_counter()
    value = fn(*args)
    return value, time.perf_counter() - start


def table(headers: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    def cell(value: Any) -> str:
        if isinstance(value, float):
            return f"{value:.3g}" if abs(value) < 1e4 else f"{value:.3e}"
        return str(value)

    lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    lines += ["| " + " | ".join(cell(v) for v in row) + " |" for row in rows]
    return "\n".join(lines)


# Keys of the JSON records of each section, in the order of the rows' columns.
RECORD_KEYS: dict[str, tuple[str, ...]] = {
    "overhead": ("executor", "workers", "ms_per_task_batch", "ms_per_task_sequential"),
    "speedup": (
        "case",
        "iterations",
        "gamma_f",
        "gamma_ratio",
        "increment",
        "error",
        "overhead",
        "theoretical",
        "measured",
        "ratio",
        "vs_serial",
        "ratio_vs_serial",
    ),
    "strong": (
        "cores",
        "iterations",
        "error",
        "serial_sweeps",
        "parallel_sweeps",
        "serial_share",
        "theoretical",
        "measured",
        "vs_serial",
    ),
    "weak": ("cores", "t1", "runtime", "parallel_sweep", "serial_sweeps", "model"),
    "fig10": (
        "cores",
        "spatial_threads",
        "spatial_blocks",
        "parareal",
        "iterations",
        "increment",
        "both",
        "both_iterations",
        "spatial_difference",
    ),
    "memo": ("case", "state_kib", "keep_ms", "read_ms", "steps_100_ms", "keep_per_100_steps"),
}


def _plain(value: Any) -> Any:
    """A JSON value: numpy scalars as Python numbers, placeholders ("n/a ...", "-") as None."""
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, str) and (value == "-" or value.startswith("n/a")):
        return None
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def records(kind: str, rows: Sequence[Sequence[Any]]) -> list[dict[str, Any]]:
    """The rows of a section's table as dicts keyed by ``RECORD_KEYS[kind]``."""
    keys = RECORD_KEYS[kind]
    return [{k: _plain(v) for k, v in zip(keys, row, strict=True)} for row in rows]


def benchmark_json(
    machine: dict[str, Any], sections: dict[str, Any], total_time: float | None = None
) -> dict[str, Any]:
    """The ``--json`` document: machine, one entry per section that ran, total time.

    ``sections`` maps a section name to the raw rows it returned: ``overhead``, ``speedup`` and
    ``fig10`` a list of rows, ``scaling`` a dict ``{"strong": rows, "weak": rows, ...}``.
    """
    out: dict[str, Any] = {"machine": dict(machine)}
    for name, data in sections.items():
        if name == "scaling":
            extra = {k: _plain(v) for k, v in data.items() if k not in ("strong", "weak")}
            out[name] = {
                "strong": records("strong", data["strong"]),
                "weak": records("weak", data["weak"]),
                **extra,
            }
        else:
            out[name] = records(name, data)
    if total_time is not None:
        out["total_time"] = total_time
    return out


def core_counts(cores: int) -> list[int]:
    """1, 2, 4, ... up to ``cores`` (powers of two, so that every count divides the largest)."""
    return [2**i for i in range(int(math.log2(cores)) + 1)]


class Pools:
    """Executors of the requested kind. MPI has one pool (the launch's ranks) for all sections."""

    def __init__(self, kind: str) -> None:
        self.kind = kind
        self._mpi: Executor | None = None

    def make(self, workers: int | None, warmup: Callable[[], Any], threads: int = 1) -> Any:
        """A fresh process pool of ``workers`` workers warmed up by ``warmup``, or the MPI pool.

        The MPI pool is warmed up once at its start; later warm-ups are sent as 2 tasks per worker
        (mpi4py cannot address a given rank; with all tasks submitted at once each idle rank takes
        some, in practice all of them).
        """
        if self.kind == "processes":
            return parallel.make_executor(
                "processes", workers, warmup=warmup, threads_per_worker=threads
            )
        if self._mpi is None:
            self._mpi = parallel.make_executor("mpi", warmup=warmup)
        else:
            tasks = [parallel.Task(warmup, (), "warm-up")] * (2 * self._mpi.workers)
            parallel.run_tasks(self._mpi, tasks)
        if workers is not None and self._mpi.workers != workers:
            raise SystemExit(
                f"--executor mpi: the launch provides {self._mpi.workers} workers, this section "
                f"needs {workers}: launch with mpiexec -n {workers + 1}, or pass --cores "
                f"{self._mpi.workers}"
            )
        return _Borrowed(self._mpi)

    def close(self) -> None:
        if self._mpi is not None:
            self._mpi.shutdown()


class _Borrowed:
    """The long-lived MPI pool in a ``with`` block that must not shut it down."""

    def __init__(self, executor: Executor) -> None:
        self.executor = executor

    def __enter__(self) -> Executor:
        return self.executor

    def __exit__(self, *exc: object) -> None:
        return None


def run_parareal(
    case: Case,
    n_slices: int,
    t1: float,
    executor: Executor | None,
    max_iterations: int,
    tol: float = 0.0,
    reference: np.ndarray | None = None,
    checkpoint: Path | None = None,
    fine: Any = None,
) -> parareal.PararealResult:
    return parareal.run(
        case.fine if fine is None else fine,
        case.coarse,
        case.x0,
        0.0,
        t1,
        n_slices,
        tol,
        max_iterations,
        executor=executor,
        reference=reference,
        project=case.system.project,
        positions=case.system.positions,
        checkpoint=checkpoint,
    )


def cumulative_runs(
    case: Case, n_slices: int, t1: float, executor: Executor, iterations: int, reference: np.ndarray
) -> list[parareal.PararealResult]:
    """The run after N_it = 1..iterations, continued through a checkpoint (wall times add up)."""
    results = []
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "run.npz"
        for n_it in range(1, iterations + 1):
            results.append(run_parareal(case, n_slices, t1, executor, n_it, 0.0, reference, path))
    return results


# ---- sections ---------------------------------------------------------------------------------


def overhead(args: argparse.Namespace, pools: Pools) -> tuple[str, Any]:
    state = models.rod_swimmer().initial_state()
    warmup = functools.partial(np.copy, state)
    executors = {
        "serial": lambda: parallel.make_executor("serial"),
        args.executor: lambda: pools.make(None if args.executor == "mpi" else args.cores, warmup),
    }
    tasks = [parallel.Task(np.copy, (state,), f"task {i}") for i in range(args.tasks)]
    sequential = tasks[: args.tasks // 3]
    rows = []
    for kind, make in executors.items():
        with make() as ex:
            parallel.run_tasks(ex, tasks[:10])  # first contact
            _, batch = timed(parallel.run_tasks, ex, tasks)
            start = time.perf_counter()
            for task in sequential:
                ex.submit(task.fn, *task.args).result()
            latency = (time.perf_counter() - start) / len(sequential)
            rows.append((kind, ex.workers, 1e3 * batch / len(tasks), 1e3 * latency))
        print(f"overhead {rows[-1]}", flush=True)
    text = "\n".join(
        [
            f"Round trip of a 301 x 12 float64 state through a worker ({len(tasks)} tasks all "
            f"submitted at once, then {len(sequential)} one at a time; {load()}):",
            "",
            table(
                ["executor", "workers", "ms per task (batch)", "ms per task (one at a time)"], rows
            ),
        ]
    )
    return text, rows


def speedup(args: argparse.Namespace, pools: Pools) -> tuple[str, Any]:
    n_c = args.cores
    iterations = max(1, min(2, n_c - 1))  # N_it = N_c is the serial cost: not worth timing
    rows = []
    for case in (rod_case(1, args.rod_slice), vesicle_case(args.vesicle_slice)):
        t1 = n_c * case.slice_length
        with pools.make(n_c, case.warmup()) as ex:
            case.warmup()()
            serial_times, runs = [], []
            for _ in range(args.repeats):  # interleaved, so that both see the same load
                reference, elapsed = timed(
                    parareal.serial_solution, case.fine, case.x0, 0.0, t1, n_c
                )
                serial_times.append(elapsed)
                runs.append(cumulative_runs(case, n_c, t1, ex, iterations, reference))
            serial_time = min(serial_times)  # other load only ever adds time
            results = min(runs, key=lambda results: results[-1].timings.total)
        for res in results:
            s = res.speedup()
            actual = res.speedup(serial_time)["measured"]
            rows.append(
                (
                    case.name,
                    res.iterations,
                    s["gamma_F"],
                    s["gamma_ratio"],
                    res.increments[-1],
                    res.errors[-1],
                    s["overhead"],
                    s["theoretical"],
                    s["measured"],
                    s["measured"] / s["theoretical"],
                    actual,
                    actual / s["theoretical"],
                )
            )
            print(f"speedup {rows[-1]}", flush=True)
    lines = [
        f"N_c = {n_c} slices on {n_c} workers ({args.executor}); best of {args.repeats} runs "
        f"each; {load()}:",
        "",
        table(
            [
                "case",
                "N_it",
                "gamma_F (s)",
                "gamma_G/gamma_F",
                "eta~",
                "eta",
                "Upsilon_oh (s)",
                "theoretical (eq. 14)",
                "measured (eq. 14)",
                "ratio",
                "vs serial run",
                "ratio",
            ],
            rows,
        ),
    ]
    if n_c == 2:
        for column, name in ((9, "measured (eq. 14)"), (11, "vs serial run")):
            worst = min(row[column] for row in rows)
            verdict = "met" if worst >= TARGET else "NOT met"
            lines += [
                "",
                f"Target {name} >= {TARGET:.0%} of theoretical on 2 workers: {verdict} "
                f"(lowest ratio {worst:.3f}).",
            ]
    return "\n".join(lines), rows


def scaling(args: argparse.Namespace, pools: Pools) -> tuple[str, Any]:
    case = rod_case(1, args.rod_slice)
    counts = core_counts(args.cores)
    t_strong = counts[-1] * case.slice_length
    strong, weak = [], []
    for n_c in counts:
        with pools.make(n_c, case.warmup()) as ex:
            case.warmup()()
            reference, serial_time = timed(
                parareal.serial_solution, case.fine, case.x0, 0.0, t_strong, n_c
            )
            for res in cumulative_runs(case, n_c, t_strong, ex, min(3, n_c), reference):
                t, s = res.timings, res.speedup()
                serial_sweeps, parallel_sweeps = sum(t.serial_sweeps), sum(t.parallel_sweeps)
                strong.append(
                    (
                        n_c,
                        res.iterations,
                        res.errors[-1],
                        serial_sweeps,
                        parallel_sweeps,
                        serial_sweeps / (serial_sweeps + parallel_sweeps),
                        s["theoretical"],
                        s["measured"],
                        res.speedup(serial_time)["measured"],
                    )
                )
                print(f"strong {strong[-1]}", flush=True)
            t_weak = n_c * case.slice_length
            res = run_parareal(case, n_c, t_weak, ex, 1)
            t = res.timings
            model = 2 * n_c * t.gamma_g + t.gamma_f  # eq. 37 with N_it = 1
            weak.append((n_c, t_weak, t.total, t.parallel_sweeps[0], sum(t.serial_sweeps), model))
            print(f"weak {weak[-1]}", flush=True)
    text = "\n".join(
        [
            f"Strong scaling (Fig. 9a-c): rod, T = {t_strong:g} fixed ({load()}):",
            "",
            table(
                [
                    "N_c",
                    "N_it",
                    "eta",
                    "serial sweeps (s)",
                    "parallel sweeps (s)",
                    "serial share",
                    "theoretical (eq. 14)",
                    "measured (eq. 14)",
                    "vs serial run",
                ],
                strong,
            ),
            "",
            f"Weak scaling (Fig. 9d): T = N_c x {case.slice_length:g}, N_it = 1:",
            "",
            table(
                [
                    "N_c",
                    "T",
                    "runtime (s)",
                    "parallel sweep (s)",
                    "serial sweeps (s)",
                    "2 N_c gamma_G + gamma_F (s)",
                ],
                weak,
            ),
        ]
    )
    data = {"strong": strong, "weak": weak, "t_strong": t_strong, "slice": case.slice_length}
    return text, data


def fig10(args: argparse.Namespace, pools: Pools) -> tuple[str, Any]:
    case = rod_case(5, 0.0)
    counts = [c for c in core_counts(args.cores) if c >= 2]
    total_steps = args.fig10_steps * counts[-1]
    t1 = total_steps * case.fine.dt
    x0 = case.x0
    case.warmup()()
    _, serial_time = timed(case.fine, 0.0, t1, x0)
    print(f"fig10 serial F over {total_steps} steps: {serial_time:.2f} s", flush=True)
    rows = []
    for c in counts:
        threaded = spatial.fine_solver(case.system, "rk2", case.fine.dt, n_threads=c)
        threads = spatial.measure_speedup(case.fine, threaded, 0.0, t1, x0)
        with parallel.make_executor("processes", c, warmup=case.warmup()) as ex:
            blocked = spatial.fine_solver(case.system, "rk2", case.fine.dt, executor=ex)
            blocks = spatial.measure_speedup(case.fine, blocked, 0.0, t1, x0)
            res = run_parareal(case, c, t1, ex, c, tol=1e-5)
        temporal = serial_time / res.timings.total
        both, both_iterations = "n/a (needs 4 cores)", "-"
        if c >= 4:
            workers = c // 2
            fine2 = spatial.fine_solver(case.system, "rk2", case.fine.dt, n_threads=2)
            with parallel.make_executor(
                "processes", workers, warmup=case.warmup(), threads_per_worker=2
            ) as ex:
                res2 = run_parareal(case, workers, t1, ex, workers, tol=1e-5, fine=fine2)
            both, both_iterations = serial_time / res2.timings.total, res2.iterations
        rows.append(
            (
                c,
                threads.speedup,
                blocks.speedup,
                temporal,
                res.iterations,
                res.increments[-1],
                both,
                both_iterations,
                max(threads.difference, blocks.difference),
            )
        )
        print(f"fig10 {rows[-1]}", flush=True)
    text = "\n".join(
        [
            f"Five rods (N_sigma = 1505), T = {t1:g} ({total_steps} fine steps, serial F "
            f"{serial_time:.2f} s), Parareal stops at eta~ < 1e-5 ({load()}). Speedup = serial "
            "F time / time of the parallel method (eq. 35 for the spatial ones):",
            "",
            table(
                [
                    "cores",
                    "spatial, threads",
                    "spatial, process blocks",
                    "temporal (Parareal)",
                    "N_it",
                    "eta~",
                    "both (N_c/2 x 2 threads)",
                    "N_it (both)",
                    "spatial F vs serial F (rel.)",
                ],
                rows,
            ),
        ]
    )
    return text, rows


def memo(args: argparse.Namespace, pools: Pools) -> tuple[str, Any]:
    """The cost of keeping one solve of the iteration in progress (parareal.solve_memo: one
    file written atomically and synced) and of reading it back, against 100 fine steps."""
    from parastokes.parareal.solve_memo import SolveMemo

    rows = []
    for case in (rod_case(1, args.rod_slice), vesicle_case(args.vesicle_slice)):
        x = case.x0
        case.warmup()()
        _, steps = timed(case.fine, 0.0, 100 * case.fine.dt, x)
        with tempfile.TemporaryDirectory() as folder:
            kept = SolveMemo(Path(folder) / "run.solves", {"problem": case.name})
            puts, gets = [], []
            for n in range(1, 21):
                puts.append(timed(kept.put, "fine", n, 1, 0.0, 1.0, x, x, 1.0)[1])
                gets.append(timed(kept.get, "fine", n, 1, 0.0, 1.0, x)[1])
        put, get = float(np.median(puts)), float(np.median(gets))
        rows.append((case.name, x.nbytes // 1024, 1e3 * put, 1e3 * get, 1e3 * steps, put / steps))
    text = table(
        ["case", "state KiB", "keep ms", "read ms", "100 fine steps ms", "keep / 100 steps"], rows
    )
    return text, rows


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sections", nargs="+", choices=SECTIONS, default=list(SECTIONS))
    parser.add_argument("--executor", choices=("processes", "mpi"), default="processes")
    parser.add_argument(
        "--cores",
        type=int,
        default=parallel.available_cores(),
        help="workers / cores to use (default: all available)",
    )
    parser.add_argument("--quick", action="store_true", help="short slices: a smoke run")
    parser.add_argument("--out", help="write the tables as markdown here")
    parser.add_argument(
        "--json", help="write the numbers as JSON here (for parastokes plot --benchmark)"
    )
    args = parser.parse_args(argv)
    if args.executor == "mpi":
        args.sections = [s for s in args.sections if s in ("overhead", "speedup")]
    args.tasks = 90 if args.quick else 300
    args.repeats = 1 if args.quick else 2
    args.rod_slice = 1e-4 if args.quick else 5e-4  # 100 / 500 fine steps
    args.vesicle_slice = 0.2 if args.quick else 1.0  # 200 / 1000 fine steps
    args.fig10_steps = 6 if args.quick else 20  # fine steps per slice at the most cores
    command = " ".join(["python", "benchmarks/parareal.py", *(argv or sys.argv[1:])])
    header = [
        "# Parareal benchmarks (`benchmarks/parareal.py`)",
        "",
        f"Command: `{command}`",
        "",
        f"Machine: {platform.processor() or platform.machine()}, "
        f"{parallel.available_cores()} available cores, numba {numba.__version__} "
        f"({numba.config.NUMBA_NUM_THREADS} threads), Python {platform.python_version()}; "
        f"{load()} at the start.",
    ]
    machine = {
        "command": command,
        "processor": platform.processor() or platform.machine(),
        "available_cores": parallel.available_cores(),
        "cores": args.cores,
        "executor": args.executor,
        "quick": args.quick,
        "numba": numba.__version__,
        "numba_threads": numba.config.NUMBA_NUM_THREADS,
        "python": platform.python_version(),
        "load_start": os.getloadavg()[:2],
    }
    print("\n".join(header), flush=True)
    pools = Pools(args.executor)
    parts = []
    results: dict[str, Any] = {}
    start = time.perf_counter()
    try:
        for name in args.sections:
            text, results[name] = globals()[name](args, pools)
            parts += ["", f"## {name}", "", text]
            print(f"\n## {name}\n\n{text}\n", flush=True)
    finally:
        pools.close()
    parts += ["", f"Total benchmark time {time.perf_counter() - start:.0f} s; {load()} at the end."]
    if args.out:
        Path(args.out).write_text("\n".join(header + parts) + "\n", encoding="utf-8")
    if args.json:
        document = benchmark_json(machine, results, time.perf_counter() - start)
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(document, indent=1) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
