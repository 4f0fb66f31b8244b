"""Does an adaptive Rosenbrock scheme's error estimate follow its error? Per step, the estimate
against the true local error, and at the end the global error against the sum of the local
ones (docs/stiff.md, "`scheme = "auto"`": why `auto` runs the exact Jacobian below rtol 1e-2).

Run from the repository root::

    PYTHONPATH=. python benchmarks/w_defect.py --problem rod301 --rtol 1e-4 \\
        [--schemes ros34pw2 ros34pw2-krylov]

The adaptive steps of each scheme (the controller of ``integrate.controller``, elementary, as
the Rosenbrock schemes run) over T = ``stiff.SHORT_T`` on a rod of ``stiff.SHORT_RODS``; at each
accepted step from ``(t, x)`` the true local error of the main and the embedded solution, in the
controller's norm (``error_norm``), against RK4 from the same ``(t, x)`` at half the explicit
limit's step; at T the global error in that norm and as ``benchmarks/adaptive.py`` measures it
(largest position error over the largest displacement) against RK4 from the start. Writes
``docs/figures/stiff/w_defect_PROBLEM.json``: ``{scheme: {rtol, steps: [[t, h, estimate,
true_main, true_embedded], ...], accepted, rejected, global_norm, sum_local, error}}``.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

import numpy as np

from benchmarks import stiff
from parastokes import integrate, models
from parastokes.integrate.adaptive import stepper_for
from parastokes.integrate.controller import error_norm, estimate_order, factor
from parastokes.integrate.schemes import SCHEMES


def local_errors(rod: Any, scheme: str, rtol: float, t1: float, reference_step: float,
                 first_step: float = 1e-5) -> dict[str, Any]:
    """The adaptive run of ``scheme`` at ``rtol`` (atol = rtol/10) with each accepted step's
    estimate and true local errors (module docstring); ``x`` its state at ``t1``."""
    atol = rtol / 10
    stepper = stepper_for(rod, SCHEMES[scheme])
    q = estimate_order(SCHEMES[scheme])
    t, h, x = 0.0, first_step, rod.initial_state()
    steps, rejected = [], 0
    while t < t1:
        h = min(h, t1 - t)
        x_new, x_low = stepper.step_with_estimate(t, x, h)
        err = error_norm(x, x_new, x_low, rtol, atol)
        if err <= 1.0:
            n = max(1, int(np.ceil(h / reference_step)))
            ref = integrate.run(rod, x, t, t + h, "rk4", h / n).state
            steps.append([t, h, err, error_norm(x, x_new, ref, rtol, atol),
                          error_norm(x, x_low, ref, rtol, atol)])
            t, x = t + h, x_new
        else:
            rejected += 1
        h *= factor(err, q, err <= 1.0)
    return {"rtol": rtol, "steps": steps, "accepted": len(steps), "rejected": rejected, "x": x}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problem", choices=sorted(stiff.SHORT_RODS), default="rod301")
    parser.add_argument("--rtol", type=float, default=1e-4)
    parser.add_argument("--schemes", nargs="+", default=["ros34pw2", "ros34pw2-krylov"],
                        choices=[n for n, s in SCHEMES.items()
                                 if s.implicit and getattr(s, "adaptive", False)])
    args = parser.parse_args(argv)
    if not 0 < args.rtol < 1:
        parser.error(f"--rtol: must lie in (0, 1), got {args.rtol}")
    m, eps, limit = stiff.SHORT_RODS[args.problem]
    rod = models.rod_swimmer(n_points=m, epsilon=eps, n_threads=1)
    x0 = rod.initial_state()
    reference, _ = stiff.reference_state(f"short_{args.problem}", rod, stiff.SHORT_T,
                                         float(f"{0.5 * limit:.2g}"))
    path = stiff.OUT / f"w_defect_{args.problem}.json"
    data = stiff._load(path)
    for scheme in args.schemes:
        run = local_errors(rod, scheme, args.rtol, stiff.SHORT_T, 0.5 * limit)
        x = run.pop("x")
        s = np.array(run["steps"])
        run.update(global_norm=error_norm(x0, x, reference, args.rtol, args.rtol / 10),
                   sum_local=float(s[:, 3].sum()),
                   error=stiff._relative_error(x, reference, x0))
        data[f"{scheme} {args.rtol:g}"] = run
        print(f"{args.problem} {scheme} rtol {args.rtol:g}: {run['accepted']} steps, "
              f"{run['rejected']} rejected; true/estimate median "
              f"{np.median(s[:, 3] / s[:, 2]):.2f}, max {np.max(s[:, 3] / s[:, 2]):.2f} "
              f"(embedded {np.median(s[:, 4] / s[:, 2]):.2f}); global {run['global_norm']:.3g}"
              f" of the sum of local {run['sum_local']:.3g}; error {run['error']:.3g} "
              f"({run['error'] / args.rtol:.2g} x rtol)", flush=True)
        stiff._save(path, data)
    return 0


if __name__ == "__main__":
    sys.exit(main())
