"""Work-precision of the adaptive explicit pairs and ``scheme="auto"`` on the paper's rod, beside
RK2 at its stability limit and adaptive ROS34PW2 (docs/stiff.md, "scheme = auto").

Run from the repository root (resumes from its JSON: a row already measured is kept)::

    PYTHONPATH=. python benchmarks/adaptive.py [--rtols 1e-3 1e-4 1e-5 1e-6 1e-7]

The rod of 301 points (ε = 1.0 μm, above the wall) over T = 0.005 s: for RK2 just below
forward Euler's limit (1.2e-5 s) and for ``rk23``, ``rk45``, ``auto`` and ``ros34pw2`` at each
rtol (atol = rtol/10 μm, first step 1e-5 s), the error at T (largest position error over the
largest displacement) against RK4 at 6e-6 s, the CPU time of one run (``time.process_time``,
one kernel thread) and its ratio to RK2's, measured in the same run. Results:
``docs/figures/stiff/adaptive_rod301.json``.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
import time
from typing import Any

import numpy as np

from parastokes import integrate, models

OUT = pathlib.Path(__file__).resolve().parents[1] / "docs" / "figures" / "stiff"
T, LIMIT, REFERENCE_STEP = 0.005, 1.2e-5, 6e-6
SCHEMES = ("rk23", "rk45", "auto", "ros34pw2")


def _relative_error(x: np.ndarray, reference: np.ndarray, x0: np.ndarray) -> float:
    scale = float(np.abs(reference[:, :3] - x0[:, :3]).max())
    return float(np.abs(x[:, :3] - reference[:, :3]).max()) / scale


def _timed(run: Any) -> tuple[Any, float]:
    start = time.process_time()
    value = run()
    return value, time.process_time() - start


def measure(rtols: list[float]) -> dict[str, Any]:
    """The rows ``{scheme, rtol, error, cpu, cpu_over_rk2, steps, rejected, switches}``."""
    path = OUT / "adaptive_rod301.json"
    data = json.loads(path.read_text()) if path.exists() else {}
    rod = models.rod_swimmer(n_points=301, epsilon=1.0, n_threads=1)
    x0 = rod.initial_state()
    reference = integrate.propagate(rod, x0, 0.0, T, "rk4", REFERENCE_STEP)
    rk2, cpu_rk2 = _timed(lambda: integrate.run(rod, x0, 0.0, T, "rk2", LIMIT))
    data["rk2"] = {"dt": LIMIT, "error": _relative_error(rk2.state, reference, x0),
                   "cpu": cpu_rk2, "steps": rk2.n_steps}
    print("rk2", data["rk2"], flush=True)
    rows = data.setdefault("rows", [])
    done = {(r["scheme"], r["rtol"]) for r in rows}
    for rtol in rtols:
        for scheme in SCHEMES:
            if (scheme, rtol) in done:
                continue
            run, cpu = _timed(lambda s=scheme, r=rtol: integrate.run(
                rod, x0, 0.0, T, s, 1e-5, rtol=r, atol=0.1 * r))
            row = {"scheme": scheme, "rtol": rtol,
                   "error": _relative_error(run.state, reference, x0), "cpu": cpu,
                   "cpu_over_rk2": cpu / cpu_rk2, "steps": run.n_steps,
                   "rejected": run.n_rejected, "switches": [list(s) for s in run.switches]}
            rows.append(row)
            print(row, flush=True)
            path.write_text(json.dumps(data, indent=1))
    path.write_text(json.dumps(data, indent=1))
    return data


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rtols", nargs="+", type=float, default=[1e-3, 1e-4, 1e-5, 1e-6, 1e-7])
    measure(parser.parse_args(argv).rtols)
    return 0


if __name__ == "__main__":
    sys.exit(main())
