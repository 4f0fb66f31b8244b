"""HODMD-Parareal against parameter extrapolation and their combination (docs/hodmd.md).

On the quick analogues of the rod of Table 4 (ε⁰ = 5σ_f, 61 nodes, four slices of 1000 τ_f; its
forward-Euler step limit at Θ⁰ is 12.3 τ_f on the fine grid and about 16 τ_f on the 6σ_f grid of
11 nodes, so G2 gains by the grid, not the step) and of
the vesicle of Table 7 (four slices of 2500 τ_f), every solver is run from its configuration
(serial executor: the iterates are those of every executor and both schedules, bit for bit, as
tests/test_parareal_tracing.py checks) for three iterations against the serial fine solution, and:

- η^k (eq. 34) for k = 1..3;
- γ_G/γ_F: each family's operation-count estimate at 40 cores (``CoarseSection.gamma_ratio``,
  what ``parastokes predict`` uses, the same model for every family), and the slice-cost probe's
  measured ratio (``parareal.measure_slice_costs``; this machine is shared and noisy);
- the predicted 40-core speedup (eq. 14 without overhead, and the closed formulas of both
  schedules) against the desired error (Fig. 6b style): for a desired error e, the fewest k with
  η^k <= e, and that k's speedup.

Usage (repository root): ``python -m validation.hodmd_compare [--only rod|vesicle] [--runs DIR]
[--out docs/figures]``: runs what ``--runs`` (default ``hodmd_runs/compare`` in the folder that
holds the checkout) does not hold yet (rod about 5 min, vesicle about an hour on two shared
cores), then writes ``OUT/hodmd_compare.json`` and prints the tables.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

from parastokes import config, integrate, parallel, parareal
from parastokes import run as runner
from parastokes.output import trajectory as io
from parastokes.parareal.speedup import speedup, speedup_pipelined, speedup_standard
from validation.hodmd_rod import RUNS_ROOT

CORES = 40
ITERATIONS = 3
COMMON = ['execution.executor="serial"', "execution.workers=1", "output.figures=false",
          "parareal.tol=0", f"parareal.max_iterations={ITERATIONS}"]


def hodmd(snapshots: int, window: float, d: int, g1: str, g2: str) -> str:
    """A ``coarse=...`` override replacing the whole [coarse] table with a HODMD section."""
    return (f'coarse={{kind="hodmd", snapshots={snapshots}, window=[{window}], d={d}, '
            f"g1={{{g1}}}, g2={{{g2}}}}}")


ROD_G3 = ('scheme="euler", dt_ratio=10, richardson={m=1, r=0.83}, lagrange={epsilon={nodes=['
          '5.02, 5.04, 5.06, 5.08, 5.1], unit="sigma_f"}, bending={nodes=[0.94, 0.96, 0.98], '
          'unit="relative"}}')
ROD_G1 = ('scheme="euler", dt_ratio=20, lagrange={epsilon={nodes=[5.6, 5.65, 5.7, 5.75], '
          'unit="sigma_f"}, bending={nodes=[0.6, 0.7, 0.8], unit="relative"}, viscosity={nodes='
          '[2, 2.5, 3], unit="relative"}}')
VES_G1 = ('scheme="euler", dt_ratio=20, lagrange={epsilon={nodes=[1.6, 1.9, 2.2, 2.5], unit='
          '"relative"}, stiffness={nodes=[0.6, 0.7, 0.8], unit="relative"}, viscosity={nodes='
          '[2, 2.5, 3], unit="relative"}}')

#: problem -> case -> (config file, overrides); "ext" = the paper's extrapolated solvers
CASES: dict[str, dict[str, tuple[str, list[str]]]] = {
    "rod": {
        "ext G1 (Lagrange ε,a,μ; 20τ_f)": ("experiments/quick/table4_g1.toml", []),
        "ext G2 (Lagrange ε,a,μ; 15τ_f)": ("experiments/quick/table4_g2.toml", []),
        "ext G3 (Lagrange ε,a + Richardson; 10τ_f)": ("experiments/quick/table4_g3.toml", []),
        "plain G4 (10τ_f)": ("experiments/quick/table4_g4.toml", []),
        "hodmd: G1 10τ_f, G2 10τ_f grid 6σ_f, r_s 0.5": ("experiments/quick/table4_g4.toml", [
            hodmd(50, 0.5, 12, 'scheme="euler", dt_ratio=10',
                  'scheme="euler", dt_ratio=10, grid_factor=6')]),
        "hodmd: G1 10τ_f, G2 10τ_f grid 6σ_f, r_s 0.25": ("experiments/quick/table4_g4.toml", [
            hodmd(50, 0.25, 6, 'scheme="euler", dt_ratio=10',
                  'scheme="euler", dt_ratio=10, grid_factor=6')]),
        "combination: G1 = ext G3, G2 10τ_f grid 6σ_f": ("experiments/quick/table4_g4.toml", [
            hodmd(20, 0.5, 6, ROD_G3, 'scheme="euler", dt_ratio=10, grid_factor=6')]),
        "combination: G1 10τ_f, G2 = ext G1": ("experiments/quick/table4_g4.toml", [
            hodmd(50, 0.5, 12, 'scheme="euler", dt_ratio=10', ROD_G1)]),
    },
    "vesicle": {
        "ext G1 (Lagrange ε,κ,μ; 20τ_f)": ("experiments/quick/table7_g1.toml", []),
        "ext G2 (Lagrange ε,κ,μ; 10τ_f)": ("experiments/quick/table7_g2.toml", []),
        "plain G4 (3τ_f)": ("experiments/quick/table7_g4.toml", ["time.t1=10"]),
        "hodmd: G1 2.5τ_f, G2 4τ_f": ("experiments/quick/table7_g4.toml", ["time.t1=10", hodmd(
            125, 0.5, 12, 'scheme="euler", dt_ratio=2.5', 'scheme="euler", dt_ratio=4')]),
        "combination: G1 2.5τ_f, G2 = ext G1, r_s 0.5": ("experiments/quick/table7_g4.toml", [
            "time.t1=10", hodmd(125, 0.5, 12, 'scheme="euler", dt_ratio=2.5', VES_G1)]),
        "combination: G1 2.5τ_f, G2 = ext G1, r_s 0.25": ("experiments/quick/table7_g4.toml", [
            "time.t1=10", hodmd(125, 0.25, 12, 'scheme="euler", dt_ratio=2.5', VES_G1)]),
    },
}


def slug(name: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in name).strip("_")[:60]


def run_case(path: str, overrides: list[str], out: Path) -> dict[str, Any]:
    """Run one case into ``out`` (or read it when it is there) and measure its costs."""
    cfg, resolved = config.load(path, [*COMMON, *overrides])
    if not (out / "summary.json").exists() and not (out / "blowup.npz").exists():
        try:
            runner.execute(cfg, resolved, out, resume=out.exists())
        except (integrate.BlowUpError, parallel.TaskError) as error:
            print(f"{out.name}: {str(error).splitlines()[0]}", flush=True)
    if not (out / "summary.json").exists():
        return {"config": path, "overrides": overrides, "errors": [], "blew_up": True,
                "gamma_estimate": cfg.coarse.gamma_ratio(cfg, resolved, CORES),
                "gamma_probe": math.nan, "n_auxiliary": resolved.n_auxiliary}
    summary = io.read_summary(out / "summary.json")
    estimate = cfg.coarse.gamma_ratio(cfg, resolved, CORES)
    setup = config.build(cfg, resolved)
    costs = parareal.measure_slice_costs(setup.fine, setup.coarse, cfg.time.t0,
                                         cfg.time.t0 + resolved.slice_length,
                                         setup.system.initial_state(), repeats=2)
    return {"config": path, "overrides": overrides, "errors": summary["errors"],
            "gamma_estimate": estimate, "gamma_probe": costs.gamma_ratio(CORES),
            "n_auxiliary": resolved.n_auxiliary}


def speedups(alpha: float, k: int) -> dict[str, float]:
    return {"eq14": speedup(alpha, 1.0, k, CORES), "standard": speedup_standard(alpha, k, CORES),
            "pipelined": speedup_pipelined(alpha, k, CORES)}


def best_by_error(cases: dict[str, dict], targets: list[float]) -> list[dict]:
    """For each desired error: every case's fewest iterations reaching it and the speedups."""
    rows = []
    for target in targets:
        row: dict[str, Any] = {"target": target}
        for name, case in cases.items():
            k = next((i + 1 for i, e in enumerate(case["errors"]) if e <= target), None)
            row[name] = None if k is None else {"k": k, **speedups(case["gamma_estimate"], k)}
        rows.append(row)
    return rows


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", choices=sorted(CASES))
    parser.add_argument("--runs", default=str(RUNS_ROOT / "compare"))
    parser.add_argument("--out", default="docs/figures")
    args = parser.parse_args(argv)
    path = Path(args.out) / "hodmd_compare.json"
    results: dict[str, Any] = {}
    for problem, cases in CASES.items():
        if args.only not in (None, problem):
            continue
        measured = {}
        for name, (cfg_path, overrides) in cases.items():
            measured[name] = run_case(cfg_path, overrides, Path(args.runs) / problem / slug(name))
            case = measured[name]
            print(problem, name, [f"{e:.2e}" for e in case["errors"]],
                  f"γ est {case['gamma_estimate']:.4f} probe {case['gamma_probe']:.4f}", flush=True)
        targets = [10.0**p for p in range(-3, -14, -1)]
        results[problem] = {"cases": measured, "by_error": best_by_error(measured, targets)}
        report(problem, results[problem])
    path.parent.mkdir(parents=True, exist_ok=True)
    saved = json.loads(path.read_text()) if path.exists() else {}  # other problems' runs
    path.write_text(json.dumps({**saved, **results}, indent=1, ensure_ascii=False))
    print(f"wrote {path}")


def report(problem: str, result: dict) -> None:
    """Print η^k, γ and the best case per desired error (standard and pipelined)."""
    print(f"\n## {problem}")
    for name, case in result["cases"].items():
        errs = " ".join(f"{e:.2e}" for e in case["errors"])
        print(f"| {name} | {errs} | {case['gamma_estimate']:.4f} | {case['gamma_probe']:.4f} |")
    for schedule in ("standard", "pipelined"):
        print(f"\nbest at 40 cores ({schedule}):")
        for row in result["by_error"]:
            options = {n: v[schedule] for n, v in row.items() if n != "target" and v}
            best = max(options, key=lambda n: options[n]) if options else None
            text = "none" if best is None else f"{best} ({options[best]:.2f}x)"
            print(f"  η* = {row['target']:.0e}: {text}")


if __name__ == "__main__":
    main()
