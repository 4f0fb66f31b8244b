"""HODMD-Parareal on the authors' rod (experiments/hodmd/authors_rod.toml; docs/hodmd.md).

Runs (or resumes: the run directory keeps the serial reference and the Parareal checkpoint) the
configuration of weifan-liu/parareal_hodmd's RodSwimmerExample/Parareal_DMD_5ds.py on our rod
(ε = 5σ_f, T = 0.1, τ_f = 1e-6 RK2, 50 slices; G1 Euler 8τ_f on the fine grid over r_s = 0.48,
0.52, 0.96 of each slice; G2 Euler 16τ_f on the 51-node grid; 125 snapshots per slice; d = 12;
ε1 = ε = 1e-8) for three iterations, and writes η^k, η̃^k, the measured γ_G/γ_F and the estimate
of the family to ``OUT/hodmd_rod.json``.

Usage (repository root): ``python -m validation.hodmd_rod [--runs DIR] [--out docs/figures]
[--scaled]``. Full scale: about 25 min of serial reference and 45 min of Parareal on two shared
cores (2 process workers). ``--scaled``: the quick rod (61 nodes, L = 12, σ_f kept) over
T = 0.02 in 10 slices, a few minutes.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from parastokes import config, io, runner

CONFIG = "experiments/hodmd/authors_rod.toml"
SCALED = ["model.n_points=61", "model.length=12.0", "time.t1=0.02", "parareal.n_slices=10",
          "coarse.g2.grid_factor=6"]


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", default="/work/hodmd_runs")
    parser.add_argument("--out", default="docs/figures")
    parser.add_argument("--scaled", action="store_true")
    args = parser.parse_args(argv)
    overrides = SCALED if args.scaled else []
    name = "authors_rod_scaled" if args.scaled else "authors_rod"
    cfg, resolved = config.load(CONFIG, overrides)
    out = Path(args.runs) / name
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
    path = Path(args.out) / f"hodmd_{name.removeprefix('authors_')}.json"
    path.write_text(json.dumps(record, indent=1))
    print(json.dumps(record, indent=1))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
