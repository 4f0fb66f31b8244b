"""``parastokes plan`` on shipped full-scale configurations, one record per configuration
(docs/planning.md, "Full-scale plans").

Each configuration runs ``python -m parastokes plan CONFIG --cores N --target ETA --out
out/plans/NAME/PLAN.toml --budget B`` in a child process; its record keeps the command, the exit
status, the child's CPU and wall time, the load average at start and end, and PLAN.json's
``best_serial``, ``fine``, ``routes``, ``unavailable``, ``chosen``, ``baseline`` and ``tune`` as
written (a refused run: the error line). Records are written to ``docs/figures/planning/NAME.json``;
a configuration with a record is skipped unless named in ``--redo``, so an interrupted batch
resumes where it stopped (the plan's own serial search is cached beside its configuration).

Run from the repository root::

    # the target table's problems, each at its η* (or --only table5_full rod601_full)
    PYTHONPATH=. NUMBA_NUM_THREADS=1 nice -n 10 python benchmarks/planning.py --budget 600
    # any shipped configurations
    PYTHONPATH=. python benchmarks/planning.py experiments/table8_g1.toml --target 1e-6
    # the summary table of the records only
    PYTHONPATH=. python benchmarks/planning.py --table
    # a new round of records beside the earlier ones (docs/figures/planning/NAME_plan4.json)
    PYTHONPATH=. NUMBA_NUM_THREADS=1 nice -n 10 python benchmarks/planning.py --budget 600 \
        --only rod601_full --tag plan4
"""

from __future__ import annotations

import argparse
import json
import math
import os
import pathlib
import resource
import subprocess
import sys
import time
from collections.abc import Sequence
from typing import Any

from benchmarks.frontier import load_average

ROOT = pathlib.Path(__file__).resolve().parents[1]
RECORDS = ROOT / "docs" / "figures" / "planning"
WORK = pathlib.Path("out/plans")

#: The target table's problems (docs/benchmarks.md, "The target table"): the record's name, the
#: configuration whose F is the fastest serial run, and η*.
TARGETS: dict[str, tuple[str, float]] = {
    "table4_full": ("experiments/best_serial/table4_rod301.toml", 1e-6),
    "table5_full": ("experiments/best_serial/table5_rod301_eps7.toml", 1e-6),
    "rod601_full": ("experiments/best_serial/rod601.toml", 1e-5),
    "table7_full": ("experiments/best_serial/table7_vesicle.toml", 1e-6),
}

#: PLAN.json's keys a record keeps.
PLAN_KEYS = ("best_serial", "fine", "routes", "unavailable", "chosen", "baseline", "tune",
             "coarse")


def command(config: str, cores: int, target: float, budget: float, out: pathlib.Path
            ) -> list[str]:
    """The ``plan`` command line of one configuration."""
    return [sys.executable, "-m", "parastokes", "plan", config, "--cores", str(cores),
            "--target", f"{target:g}", "--out", str(out), "--budget", f"{budget:g}", "-q"]


def last_error_line(stderr: str) -> str:
    """The error line a refused plan printed (its last non-empty line of stderr)."""
    lines = [line for line in stderr.splitlines() if line.strip()]
    return lines[-1] if lines else ""


def commit() -> str:
    """The repository's HEAD commit (the code the child ran), or "" outside a git checkout."""
    done = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
                          text=True, check=False)
    return done.stdout.strip()


def record_of(argv: Sequence[str], config: str, target: float, cores: int, status: int,
              stderr: str, plan: dict[str, Any] | None, cpu: float, wall: float,
              loads: tuple[float, float], code: str) -> dict[str, Any]:
    """One configuration's record: the run's facts (``code``: the commit it started from) and,
    when PLAN.json was written, its :data:`PLAN_KEYS`; otherwise the error line."""
    record: dict[str, Any] = {
        "command": " ".join(["parastokes", *argv[3:]]), "commit": code, "config": config,
        "target": target,
        "cores": cores, "exit_status": status, "cpu_seconds_children": cpu,
        "wall_seconds": wall, "load_average": list(loads),
    }
    if plan is None:
        record["error"] = last_error_line(stderr)
    else:
        record.update({key: plan.get(key) for key in PLAN_KEYS})
        record["tune"] = measured_only(record["tune"])
    return record


#: Statuses of tune's candidates that were never measured (kept as counts only).
UNMEASURED = ("not reached", "pruned")


def measured_only(report: dict[str, Any] | None) -> dict[str, Any] | None:
    """``tune``'s report with only its measured candidates listed (hundreds are never reached
    within a budget) and ``candidate_counts``: how many of each (scheme, status)."""
    if not report or "candidates" not in report:
        return report
    counts: dict[str, int] = {}
    for cand in report["candidates"]:
        key = f"{cand['scheme']} {cand['status']}"
        counts[key] = counts.get(key, 0) + 1
    kept = [c for c in report["candidates"] if c["status"] not in UNMEASURED]
    return {**report, "candidates": kept, "candidate_counts": counts}


def child_cpu(before: Any, after: Any) -> float:
    """User plus system CPU seconds of the children waited for between two ``getrusage``."""
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def run_one(name: str, config: str, target: float, cores: int, budget: float
            ) -> dict[str, Any]:
    """Run ``plan`` on ``config`` in a child process and return its record."""
    out = WORK / name / "PLAN.toml"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.with_suffix(".json").unlink(missing_ok=True)
    argv = command(config, cores, target, budget, out)
    code = commit()  # (the child imports the working tree as it is now)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start_load, start = load_average(), time.perf_counter()
    done = subprocess.run([*argv, "--overwrite"], capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(ROOT)}, check=False)
    wall = time.perf_counter() - start
    cpu = child_cpu(before, resource.getrusage(resource.RUSAGE_CHILDREN))
    plan_path = out.with_suffix(".json")
    plan = json.loads(plan_path.read_text()) if plan_path.exists() else None
    return record_of(argv, config, target, cores, done.returncode, done.stderr, plan, cpu, wall,
                     (start_load, load_average()), code)


def chosen_route(record: dict[str, Any]) -> dict[str, Any] | None:
    """The route the plan wrote (the row of ``routes`` named by ``chosen``), or None."""
    for route in record.get("routes") or []:
        if route["route"] == record.get("chosen"):
            return route
    return None


def summary_row(name: str, record: dict[str, Any]) -> str:
    """One markdown row: exit status, the fastest serial run, the chosen route and its speedup
    against it, whether the serial search completed, CPU and load."""
    loads = "-".join(f"{value:.1f}" for value in record.get("load_average", []))
    if record.get("exit_status") != 0:
        return (f"| {name} | {record['target']:g} | {record.get('exit_status')} | "
                f"{record.get('error', '')} | - | - | - | {loads} |")
    best = record["best_serial"]
    step = f"dt = {best['dt']:.3g}" if best.get("dt") else f"rtol = {best.get('rtol')}"
    route = chosen_route(record) or {}
    complete = (record.get("baseline") or {}).get("stopped", "?")
    return (f"| {name} | {record['target']:g} | 0 | {best['scheme']} {step}, "
            f"{best['cpu_seconds']:.1f} s | {record['chosen']} | "
            f"{route.get('speedup_vs_best_serial', math.nan):.2f} | {complete} | {loads} |")


def table(records: dict[str, dict[str, Any]]) -> str:
    """The markdown summary of ``records``."""
    head = ("| record | η* | exit | fastest serial run found | chosen | speedup vs it | "
            "serial search stopped by | load average |\n|---|---|---|---|---|---|---|---|")
    return "\n".join([head, *(summary_row(name, rec) for name, rec in sorted(records.items()))])


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("configs", nargs="*", help="configurations (default: the target table's)")
    parser.add_argument("--target", type=float, default=1e-6,
                        help="η* for configurations named on the command line")
    parser.add_argument("--cores", type=int, default=40)
    parser.add_argument("--budget", type=float, default=600.0)
    parser.add_argument("--only", nargs="*", choices=sorted(TARGETS), default=None,
                        help="of the target table's problems, these only")
    parser.add_argument("--redo", nargs="*", default=[], help="record names to measure again")
    parser.add_argument("--table", action="store_true", help="print the records' table only")
    parser.add_argument("--tag", default="",
                        help="appended to each record's name (NAME_TAG.json), so that a new "
                             "round of measurements keeps the earlier records; --redo and the "
                             "table take the tagged names")
    args = parser.parse_args(argv)
    jobs = ({pathlib.Path(c).stem: (c, args.target) for c in args.configs} if args.configs
            else {name: TARGETS[name] for name in args.only or TARGETS})
    if args.tag:
        jobs = {f"{name}_{args.tag}": job for name, job in jobs.items()}
    if not args.table:
        RECORDS.mkdir(parents=True, exist_ok=True)
        for name, (config, target) in jobs.items():
            path = RECORDS / f"{name}.json"
            if path.exists() and name not in args.redo:
                continue
            print(f"plan {config} at η* = {target:g} ...", flush=True)
            path.write_text(json.dumps(run_one(name, config, target, args.cores, args.budget),
                                       indent=1) + "\n")
    records = {name: json.loads((RECORDS / f"{name}.json").read_text())
               for name in jobs if (RECORDS / f"{name}.json").exists()}
    print(table(records))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
