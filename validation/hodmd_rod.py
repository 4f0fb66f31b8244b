"""HODMD-Parareal on the authors' rod (experiments/hodmd/authors_rod.toml; docs/hodmd.md).

Runs (or resumes: the run directory keeps the serial reference and the Parareal checkpoint) the
configuration of weifan-liu/parareal_hodmd's RodSwimmerExample/Parareal_DMD_5ds.py on our rod
(ε = 5σ_f, T = 0.1, τ_f = 1e-6 RK2, 50 slices; G1 Euler 8τ_f on the fine grid over r_s = 0.48,
0.52, 0.96 of each slice; G2 Euler 16τ_f on the 51-node grid; 125 snapshots per slice; d = 12;
ε1 = ε = 1e-8) for three iterations, and writes η^k, η̃^k, the measured γ_G/γ_F and the estimate
of the family to ``OUT/hodmd_rod.json``.

Usage (repository root): ``python -m validation.hodmd_rod [--runs DIR] [--out docs/figures]
[--scaled] [--initial global|sweep]``. Full scale: about 25 min of serial reference and 30-45 min
of Parareal on two shared cores (2 process workers) with ``--initial sweep``; the authors'
``global`` guess (the configuration's) needs one HODMD of 751 snapshots of 903 rows per column
group, whose amplitude least squares can reach 564k × 742 complex entries, as in the authors'
code. ``--scaled``: the quick rod (61 nodes, L = 12, σ_f kept) over T = 0.02 in 10 slices (the
slice length, the solvers and the HODMD settings kept), a few minutes. Each run is recorded under
its name in ``OUT/hodmd_rod.json``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from parastokes import config
from parastokes import run as runner
from parastokes.output import trajectory as io

#: Where the runs go by default: ``hodmd_runs`` in the folder that holds the checkout (not in git).
RUNS_ROOT = Path(__file__).resolve().parents[2] / "hodmd_runs"

CONFIG = "experiments/hodmd/authors_rod.toml"
SCALED = ["model.n_points=61", "model.length=12.0", "time.t1=0.02", "parareal.n_slices=10",
          "coarse.g2.grid_factor=6"]
#: The CI-sized twin of the scaled runs (tests/test_numbers_hodmd.py): the same rod, slice and
#: HODMD settings over 4 slices instead of 10 (three iterations still short of exact).
TWIN = [*SCALED[:2], "time.t1=0.008", "parareal.n_slices=4", *SCALED[4:]]


def run_overrides(scaled: bool, initial: str, twin: bool = False) -> list[str]:
    """The ``--set`` overrides of a run: full scale, ``SCALED`` or its ``TWIN``, and the initial
    guess (``global``: the authors'; ``sweep``: HODMD coarse steps)."""
    size = TWIN if twin else SCALED if scaled else []
    return [*size, f'coarse.initial="{initial}"']


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", default=str(RUNS_ROOT))
    parser.add_argument("--out", default="docs/figures")
    parser.add_argument("--scaled", action="store_true")
    parser.add_argument("--initial", choices=("global", "sweep"), default="global")
    args = parser.parse_args(argv)
    overrides = run_overrides(args.scaled, args.initial)
    name = f"{'scaled' if args.scaled else 'full'}_{args.initial}"
    cfg, resolved = config.load(CONFIG, overrides)
    out = Path(args.runs) / {"full_sweep": "authors_rod"}.get(name, f"authors_rod_{name}")
    if not (out / "summary.json").exists():
        runner.execute(cfg, resolved, out, resume=out.exists())
    summary = io.read_summary(out / "summary.json")
    record = {
        "config": CONFIG, "overrides": overrides,
        "errors": summary["errors"], "increments": summary["increments"],
        "gamma_ratio_measured": summary["speedup"]["gamma_ratio"],
        "gamma_ratio_estimated": cfg.coarse.gamma_ratio(cfg, resolved, 50),
        "speedup_theoretical": summary["speedup"]["theoretical"],
        "wall_time_s": summary["timings"]["total"],
    }
    path = Path(args.out) / "hodmd_rod.json"
    records = json.loads(path.read_text()) if path.exists() else {}
    records[name] = record
    path.write_text(json.dumps(records, indent=1))
    print(json.dumps(record, indent=1))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
