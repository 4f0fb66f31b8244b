"""Work-precision of the adaptive schemes and ``scheme="auto"`` across tolerances, beside RK2
just below forward Euler's limit (docs/benchmarks.md, "Work-precision diagrams (round 5)").

Run from the repository root (resumes from its JSON: a row already measured is kept)::

    PYTHONPATH=. python benchmarks/adaptive.py --problem rod601 \\
        [--rtols 1e-2 1e-3 ... 1e-8] [--schemes rk23 auto] [--cap 120] [--redo rk45]

Problems (:data:`PROBLEMS`, the bodies, T, steps and references of ``benchmarks/stiff.py``):
the rods of 301 and 601 points over T = 0.005 s and of 1201 points over T = 2.5e-4 s (ε = 5Δs,
above the wall; ``stiff.SHORT_RODS``, ``stiff.SHORT_ROD1201``) and the vesicle (642 points,
shear 0.1, κ = 0.1) over T = 10. For RK2 at the problem's explicit step and for each scheme of
:data:`SCHEMES` at each rtol (atol = rtol/10), the error at T (largest position error over the
largest displacement, ``stiff._relative_error``) against the RK4 reference of ``stiff.py`` (its
cached state, computed here when missing), the CPU time of one run (``time.process_time``, one
kernel thread; each scheme warmed up first by two untimed steps), its ratio to RK2's, the load
average and the commit of the code. A run whose CPU time :func:`predicted_cpu` puts above
``--cap`` seconds is not run but recorded under ``skipped`` with the prediction. Results:
``docs/figures/stiff/adaptive_PROBLEM.json``.

``--prices`` measures instead the prices ``auto`` counts an implicit step's work at
(:func:`measure_prices`: ``auto.STEP_EVALS`` and ``auto.PRODUCT_EVALS`` of the problem's kind of
factorization), into ``docs/figures/stiff/auto_prices.json``::

    PYTHONPATH=. python benchmarks/adaptive.py --problem rod301 --prices [--rtols 1e-3 1e-4]
"""

from __future__ import annotations

import argparse
import math
import os
import pathlib
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from benchmarks import stiff
from parastokes import integrate, models
from parastokes.integrate import auto
from parastokes.integrate.adaptive import Watch, segment, stepper_for
from parastokes.integrate.base import rates
from parastokes.integrate.controller import estimate_order
from parastokes.integrate.schemes import lookup, real_stability_boundary

OUT = pathlib.Path(__file__).resolve().parents[1] / "docs" / "figures" / "stiff"
#: The adaptive schemes measured, in the order of each tolerance's runs.
SCHEMES = ("rk23", "rk45", "auto", "ros34pw2", "ros34pw2-krylov")
RTOLS = (1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8)


@dataclass(frozen=True)
class Problem:
    """A body of ``stiff.py``'s work-precision: its builder, T, RK2's step (just below forward
    Euler's limit), the adaptive runs' first step, the name of ``stiff.py``'s cached reference
    and its RK4 step, and the default ``--cap`` (seconds of CPU per run)."""

    build: Callable[[], Any]
    t1: float
    explicit_step: float
    first_step: float
    reference: str
    reference_step: float
    cap: float


def _rod(name: str, t1: float, first_step: float, cap: float) -> Problem:
    m, eps, limit = {**stiff.SHORT_RODS, **stiff.SHORT_ROD1201}[name]
    return Problem(lambda: models.rod_swimmer(n_points=m, epsilon=eps, n_threads=1), t1, limit,
                   first_step, f"short_{name}", float(f"{0.5 * limit:.2g}"), cap)


def _vesicle() -> Problem:
    limit = stiff._load(OUT / "vesicle.json")["euler_limit"]  # stiff.py --parts vesicle
    return Problem(lambda: models.vesicle(subdivisions=3, n_threads=1), 10.0,
                   float(f"{0.95 * limit:.3g}"), float(f"{0.95 * limit:.3g}"), "vesicle",
                   float(f"{0.25 * limit:.3g}"), 120.0)


#: The problems by name (built when asked: the vesicle's limit is read from its JSON).
PROBLEMS: dict[str, Callable[[], Problem]] = {
    "rod301": lambda: _rod("rod301", stiff.SHORT_T, 1e-5, 60.0),
    "rod601": lambda: _rod("rod601", stiff.SHORT_T, 1e-5, 120.0),
    "rod1201": lambda: _rod("rod1201", stiff.SHORT_T1201, 5e-7, 300.0),
    "vesicle": _vesicle,
}


def evaluations(scheme: str) -> int:
    """Rate evaluations per step of an explicit tableau (one fewer when first same as last)."""
    s = lookup(scheme)
    return s.stages - 1 if s.fsal else s.stages


def stability_floor(scheme: str, rk2_cpu: float) -> float:
    """The least CPU time of an explicit scheme's run: at its stability boundary on the negative
    real axis, it takes ``boundary(rk2) / boundary(scheme)`` times RK2's steps (RK2 runs just
    below the same limit), each costing ``evaluations(scheme) / 2`` of RK2's; 0 for the
    implicit schemes and ``auto`` (which may leave the explicit pair)."""
    s = lookup(scheme)
    if s.implicit or scheme == "auto":
        return 0.0
    rk2 = lookup("rk2")
    return (rk2_cpu * evaluations(scheme) / evaluations("rk2")
            * real_stability_boundary(rk2) / real_stability_boundary(s))


def predicted_cpu(scheme: str, rtol: float, rows: list[dict[str, Any]], rk2_cpu: float
                  ) -> tuple[float, str]:
    """The CPU time a run of ``scheme`` at ``rtol`` is expected to take, and how it was found:
    from the measured run of the same scheme at the nearest looser rtol ``r``, its CPU times
    ``(r / rtol)^(1/(q+1))`` (an error per step ~ h^(q+1), q = the estimate's order: the step
    count grows by that factor; an upper bound where stability, not accuracy, set the steps),
    at least :func:`stability_floor`; the floor alone without such a run."""
    floor = stability_floor(scheme, rk2_cpu)
    looser = [r for r in rows if r["scheme"] == scheme and r["rtol"] > rtol]
    if not looser:
        return floor, f"stability floor {floor:.3g} s"
    prev = min(looser, key=lambda r: r["rtol"])
    q = estimate_order(lookup(scheme))
    grown = prev["cpu"] * (prev["rtol"] / rtol) ** (1.0 / (q + 1))
    if grown < floor:
        return floor, f"stability floor {floor:.3g} s"
    return grown, (f"{prev['cpu']:.3g} s at rtol {prev['rtol']:g} x "
                   f"({prev['rtol']:g}/{rtol:g})^(1/{q + 1})")


def forget(data: dict[str, Any], schemes: list[str]) -> None:
    """Drop the measured and skipped runs of ``schemes`` (``rk2``: the yardstick) from ``data``,
    to be measured again."""
    if "rk2" in schemes:
        data.pop("rk2", None)
    for key in ("rows", "skipped"):
        data[key] = [r for r in data.get(key, []) if r["scheme"] not in schemes]


def _code() -> str:
    """The commit of the code that measures (``+dirty`` with uncommitted changes)."""
    def git(*args: str) -> str:
        return subprocess.run(["git", *args], capture_output=True, text=True,
                              cwd=OUT.parents[2]).stdout.strip()

    return git("rev-parse", "--short", "HEAD") + ("+dirty" if git("status", "--porcelain",
                                                                 "--", "parastokes") else "")


def measure(name: str, rtols: list[float], schemes: list[str], cap: float) -> dict[str, Any]:
    """The file's ``rk2`` (``{dt, error, cpu, steps, load}``), ``rows`` (``{scheme, rtol, error,
    cpu, cpu_over_rk2, steps, rejected, switches, load, code}``) and ``skipped`` (``{scheme,
    rtol, predicted_cpu, cap, why}``) of problem ``name``, resumed from and saved to its JSON
    after every run."""
    problem = PROBLEMS[name]()
    path = OUT / f"adaptive_{name}.json"
    data = stiff._load(path)
    system = problem.build()
    x0 = system.initial_state()
    reference, computed = stiff.reference_state(problem.reference, system, problem.t1,
                                                problem.reference_step)
    if computed:
        data["reference"] = computed
    data["t1"] = problem.t1
    code = _code()

    def error(state: Any) -> float:
        return stiff._relative_error(state, reference, x0)

    warm: set[str] = set()

    def warm_up(scheme: str, **tolerances: float) -> None:
        """Two first steps of ``scheme``, untimed: compiling its loops (numba) is not its CPU;
        for ``auto``, of its implicit schemes too (its first steps are explicit ones)."""
        if scheme not in warm:
            integrate.run(system, x0, 0.0, 2 * problem.first_step, scheme, problem.first_step,
                          **tolerances)
            warm.add(scheme)
            if scheme == "auto":
                for implicit in (auto.IMPLICIT, auto.IMPLICIT_EXACT):
                    warm_up(implicit, **tolerances)

    if "rk2" not in data:
        warm_up("rk2")
        rk2, cpu = stiff._timed(lambda: integrate.run(system, x0, 0.0, problem.t1, "rk2",
                                                      problem.explicit_step))
        data["rk2"] = {"dt": problem.explicit_step, "error": error(rk2.state), "cpu": cpu,
                       "steps": rk2.n_steps, "load": os.getloadavg()[0], "code": code}
        print(name, "rk2", data["rk2"], flush=True)
        stiff._save(path, data)
    rk2_cpu = data["rk2"]["cpu"]
    rows = data.setdefault("rows", [])
    for rtol in sorted(rtols, reverse=True):
        for scheme in schemes:
            if any(r["scheme"] == scheme and r["rtol"] == rtol for r in rows):
                continue
            data["skipped"] = [s for s in data.get("skipped", [])
                               if (s["scheme"], s["rtol"]) != (scheme, rtol)]
            guess, why = predicted_cpu(scheme, rtol, rows, rk2_cpu)
            if guess > cap:
                data["skipped"].append({"scheme": scheme, "rtol": rtol, "predicted_cpu": guess,
                                        "cap": cap, "why": why})
                print(name, "skipped", data["skipped"][-1], flush=True)
                stiff._save(path, data)
                continue
            warm_up(scheme, rtol=rtol, atol=0.1 * rtol)
            run, cpu = stiff._timed(lambda s=scheme, r=rtol: integrate.run(
                system, x0, 0.0, problem.t1, s, problem.first_step, rtol=r, atol=0.1 * r))
            row = {"scheme": scheme, "rtol": rtol, "error": error(run.state), "cpu": cpu,
                   "cpu_over_rk2": cpu / rk2_cpu, "steps": run.n_steps,
                   "rejected": run.n_rejected, "switches": [list(s) for s in run.switches],
                   "load": os.getloadavg()[0], "code": code}
            rows.append(row)
            print(name, row, flush=True)
            stiff._save(path, data)
    return data


def fit_prices(runs: list[dict[str, float]]) -> tuple[float, float]:
    """The prices ``(S, P)`` of a stage set and of a GMRES product, in evaluations' worth of
    CPU, that fit ``cpu / evaluation = S sets + P products`` over ``runs`` (each ``{cpu,
    evaluation, sets, products}``: a run's CPU time, one evaluation's, its stage sets and its
    products) by least squares, each run weighed by its CPU over its evaluation's (relative
    residuals: a short run counts as much as a long one)."""
    work = np.array([r["cpu"] / r["evaluation"] for r in runs])
    counts = np.array([[r["sets"], r["products"]] for r in runs], dtype=float)
    (step, product), *_ = np.linalg.lstsq(counts / work[:, None], np.ones(len(runs)), rcond=None)
    return float(step), float(product)


def _evaluation_cpu(system: Any, x: np.ndarray, t: float, repeats: int = 50) -> float:
    """The CPU time of one evaluation of the rates at ``(t, x)``, the mean over ``repeats``
    after one untimed."""
    rates(system, t, x)
    start = time.process_time()
    for _ in range(repeats):
        rates(system, t, x)
    return (time.process_time() - start) / repeats


def measure_prices(name: str, rtols: list[float]) -> dict[str, Any]:
    """The adaptive runs of ``auto``'s two implicit schemes (:data:`auto.IMPLICIT`, whose stages
    take no GMRES product, and :data:`auto.IMPLICIT_EXACT`) on problem ``name`` over its T at
    each of ``rtols`` (atol = rtol/10), each run's CPU time beside one evaluation's measured just
    before it in the same process, its stage sets and products (the stepper's counts), and
    the prices :func:`fit_prices` draws from them, with the kind of factorization; saved to
    ``auto_prices.json`` under ``name``."""
    problem = PROBLEMS[name]()
    system = problem.build()
    x0 = system.initial_state()
    out: dict[str, Any] = {"runs": [], "load": [os.getloadavg()[0]], "code": _code()}
    banded = None
    for scheme in (auto.IMPLICIT, auto.IMPLICIT_EXACT):
        integrate.run(system, x0, 0.0, 2 * problem.first_step, scheme, problem.first_step,
                      rtol=rtols[0], atol=0.1 * rtols[0])  # compiling is not its price
        for rtol in rtols:
            evaluation = _evaluation_cpu(system, x0, 0.0)
            stepper = stepper_for(system, integrate.SCHEMES[scheme])
            _, cpu = stiff._timed(lambda s=stepper, r=rtol: segment(
                s, x0, 0.0, problem.t1, problem.first_step, (r, 0.1 * r),
                Watch(system, x0, math.inf)))
            banded = stepper.banded is not False  # type: ignore[union-attr]
            out["runs"].append({"scheme": scheme, "rtol": rtol, "cpu": cpu,
                                "evaluation": evaluation, "sets": stepper.steps,
                                "products": stepper.iterations})  # type: ignore[union-attr]
            print(name, out["runs"][-1], flush=True)
    out["load"].append(os.getloadavg()[0])
    out["banded"] = banded
    out["step_evals"], out["product_evals"] = fit_prices(out["runs"])
    path = OUT / "auto_prices.json"
    data = stiff._load(path)
    data[name] = out
    stiff._save(path, data)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problem", choices=sorted(PROBLEMS), default="rod301")
    parser.add_argument("--rtols", nargs="+", type=float, default=None,
                        help="default: 1e-2 ... 1e-8 (with --prices: 1e-3 1e-4)")
    parser.add_argument("--schemes", nargs="+", choices=SCHEMES, default=list(SCHEMES))
    parser.add_argument("--cap", type=float, default=None,
                        help="seconds of CPU above which a run is skipped (default: the "
                             "problem's)")
    parser.add_argument("--redo", nargs="+", choices=(*SCHEMES, "rk2"), default=[],
                        help="measure these schemes' runs again (rk2: the yardstick)")
    parser.add_argument("--prices", action="store_true",
                        help="measure the prices of auto's implicit work instead (at --rtols, "
                             "default 1e-3 1e-4)")
    args = parser.parse_args(argv)
    rtols = args.rtols or ([1e-3, 1e-4] if args.prices else list(RTOLS))
    if any(not 0 < r < 1 for r in rtols):
        parser.error(f"--rtols: each must lie in (0, 1), got {args.rtols}")
    if args.cap is not None and not args.cap > 0:
        parser.error(f"--cap: must be positive seconds, got {args.cap}")
    if args.prices:
        out = measure_prices(args.problem, rtols)
        print(args.problem, "STEP_EVALS", out["step_evals"], "PRODUCT_EVALS",
              out["product_evals"], "banded", out["banded"])
        return 0
    if args.redo:
        path = OUT / f"adaptive_{args.problem}.json"
        data = stiff._load(path)
        forget(data, args.redo)
        stiff._save(path, data)
    cap = PROBLEMS[args.problem]().cap if args.cap is None else args.cap
    measure(args.problem, rtols, args.schemes, cap)
    return 0


if __name__ == "__main__":
    sys.exit(main())
