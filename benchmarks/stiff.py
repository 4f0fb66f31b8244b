"""Work-precision of every scheme, explicit and linearly implicit, and implicit coarse solvers
for Parareal (docs/benchmarks.md, "Stiff bodies"; docs/stiff.md).

Run from the repository root (each part resumes from its JSON: a row already measured is kept)::

    PYTHONPATH=. python benchmarks/stiff.py --parts rod rod601 vesicle parareal parareal601 \
        best_serial

- ``rod``: the paper's rod (M = 301, ε = 5 σ_f, above the wall), one beat T = 0.05 s: the
  error at T (largest position error over the largest displacement) against RK4 at 2e-6, and
  the CPU time of one run, for every scheme at several steps;
- ``rod601``: the same on the rod refined to 601 points (ε = 5Δs), over T = 0.01 s;
- ``vesicle``: the vesicle (642 points, shear rate 0.1, κ = 0.1), T = 10, against RK4 at a
  quarter of the explicit limit, likewise;
- ``parareal``: on the paper's rod over T = 0.01 (10 slices, fine RK2 at 1e-6), coarse solvers
  G = the paper's Table 4 G¹ (36 auxiliary Euler solvers at 20 τ_f), ROS2 on the exact Jacobian
  (ros2-krylov) and ROS2 on the local one (ros2) at several steps: η^k against the serial
  fine solution, the CPU time of one coarse step (one auxiliary solve for G¹, whose 36 run at
  once on 36 cores, as eq. 14 counts them) over that of one fine slice (γ_G/γ_F), and the
  eq. 14 speedup at 40 slices on 40 cores with the first iteration reaching the target;
- ``parareal601``: the same on the rod of 601 points over T = 0.005 (fine RK2 at 5e-7), with
  forward Euler at its limit as the explicit coarse solver;
- ``best_serial``: for each of the paper's fine problems (Tables 3-4, 5, 7, 8; the config of
  each), F's serial solution at T and candidate serial runs (explicit at and below forward
  Euler's limit, implicit above it): their error at T against F (eta of eq. 34) and their CPU
  time beside F's (measured over 1 % of T just before each, scaled), for the speedups of the
  paper's records against the fastest serial run of the same accuracy
  (``docs/figures/stiff/best_serial.json``, read by ``parastokes predict --serial``).

- ``linalg``: the pieces of a linearly implicit step (loads' Jacobian, near mobility, their
  product, factorization, stage solve) over one evaluation of the rates, on the rods of 301
  and 601 points, beside the same pieces as they were at the start of this session (coloured
  differences, stored M, BSR product, double-precision LU) and before round 5 (SuperLU), the
  stage solve beside its second session's loops and LAPACK's dgbtrs and sgbtrs, with the load
  average, the factorization with A's own lower bandwidth (not ``stiff.solve.elimination_width``),
  and the fused product of round 5's third session (:data:`PREVIOUS_PRODUCT`, loaded
  from git) beside the current one; the counts of Jacobians and factorizations of a fixed and
  an adaptive ROS34PW2 run;
- ``linalg_accuracy``: the 21 ROS2 and ROS34PW2 runs of ``short`` (fixed steps, ``A`` every 5
  and 10 steps, adaptive) with the current ``A`` and with the third session's product, in one
  process: errors, steps and rejections of each (``docs/figures/stiff/linalg_accuracy.json``);
- ``short``: work-precision over T = 0.005 s on those rods: forward Euler and RK2 at their
  limit, ROS2, ROS34PW2 and ROS2-Krylov at fixed steps, ROS2 and ROS34PW2 adaptive.

CPU times are ``time.process_time`` of one process with one kernel thread; ratios within one
run are what to compare (the machine is shared). Results: ``docs/figures/stiff/*.json`` and
``docs/figures/stiff/work_precision.png``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import pathlib
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from numba import njit

from parastokes import integrate, models, parareal
from parastokes.parallel import TaskError
from parastokes.parareal.speedup import speedup as eq14
from parastokes.stiff import stepper

OUT = pathlib.Path("docs/figures/stiff")
#: Slices of the Parareal part (T = 0.01).
N_SLICES = 10

ROD_STEPS = {
    "euler": [1.2e-5],
    "rk2": [1.2e-5, 1e-5],
    "rk4": [1.6e-5, 1.25e-5],
    "lieuler": [2.5e-4, 1.25e-4],
    "ros2": [5e-4, 2.5e-4, 1.25e-4, 6.25e-5],
    "ros2-krylov": [5e-4, 2.5e-4, 1.25e-4, 6.25e-5],
}


def _load(path: pathlib.Path) -> dict[str, Any]:
    return json.loads(path.read_text()) if path.exists() else {}


def _save(path: pathlib.Path, data: dict[str, Any]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=1, sort_keys=True))
    tmp.replace(path)


def _timed(function: Callable[[], Any]) -> tuple[Any, float]:
    start = time.process_time()
    value = function()
    return value, time.process_time() - start


def _relative_error(x: np.ndarray, reference: np.ndarray, x0: np.ndarray) -> float:
    scale = float(np.abs(reference[:, :3] - x0[:, :3]).max())
    return float(np.abs(x[:, :3] - reference[:, :3]).max()) / scale


def reference_state(name: str, system: Any, t1: float, step: float
                    ) -> tuple[np.ndarray, dict[str, Any] | None]:
    """RK4's state at ``t1`` from the initial state at steps of ``step``, cached in
    ``OUT/.NAME_reference.npy`` (read from there when it exists); with ``{scheme, dt, cpu}``
    when computed now, None when read from the cache."""
    cache = OUT / f".{name}_reference.npy"
    if cache.exists():
        return np.load(cache), None
    x0 = system.initial_state()
    reference, cpu = _timed(lambda: integrate.propagate(system, x0, 0.0, t1, "rk4", step))
    OUT.mkdir(parents=True, exist_ok=True)
    np.save(cache, reference)
    return reference, {"scheme": "rk4", "dt": step, "cpu": cpu}


def work_precision(name: str, system: Any, t1: float, reference_step: float,
                   steps: dict[str, list[float]], refresh: dict[str, list[int]]
                   ) -> dict[str, Any]:
    """Rows ``{scheme, dt, refresh, error, cpu, steps}`` (resumed from the JSON); ``refresh``:
    the Jacobian rebuild periods to measure per scheme (default: stiff.stepper.REFRESH)."""
    path = OUT / f"{name}.json"
    data = _load(path)
    default = stepper.REFRESH
    x0 = system.initial_state()
    reference, computed = reference_state(name, system, t1, reference_step)
    if computed:
        data["reference"] = computed
    rows = data.setdefault("rows", [])
    done = {(r["scheme"], r["dt"], r.get("refresh")) for r in rows}
    for scheme, dts in steps.items():
        for dt in dts:
            for every in refresh.get(scheme, [default]):
                key = (scheme, dt, every)
                if key in done:
                    continue
                stepper.REFRESH = every
                try:
                    result, cpu = _timed(lambda s=scheme, h=dt: integrate.run(system, x0, 0.0, t1,
                                                                              s, h))
                    row = {"error": _relative_error(result.state, reference, x0), "cpu": cpu,
                           "steps": result.n_steps}
                except integrate.BlowUpError as error:
                    row = {"error": math.inf, "cpu": math.nan, "blowup": str(error)[:200]}
                row.update(scheme=scheme, dt=dt, refresh=every)
                rows.append(row)
                print(name, row, flush=True)
                _save(path, data)
    stepper.REFRESH = default
    return data


def cheapest(rows: list[dict[str, Any]], target: float, implicit: bool) -> dict | None:
    """The fastest row of explicit (or implicit) schemes whose error is at most ``target``."""
    kind = {k for k, v in integrate.SCHEMES.items() if v.implicit == implicit}
    ok = [r for r in rows if r["scheme"] in kind and r["error"] <= target]
    return min(ok, key=lambda r: r["cpu"]) if ok else None


def summary(data: dict[str, Any]) -> dict[str, Any]:
    out = {}
    for target in (1e-2, 1e-3, 1e-4):
        e = cheapest(data["rows"], target, implicit=False)
        i = cheapest(data["rows"], target, implicit=True)
        out[f"{target:g}"] = {
            "explicit": e and {k: e[k] for k in ("scheme", "dt", "cpu", "error")},
            "implicit": i and {k: i[k] for k in ("scheme", "dt", "cpu", "error", "refresh")},
            "ratio": e and i and e["cpu"] / i["cpu"],
        }
    return out


def rod_part() -> dict[str, Any]:
    rod = models.rod_swimmer(n_points=301, epsilon=1.0, n_threads=1)
    data = work_precision("rod", rod, 0.05, 2e-6, ROD_STEPS, {"ros2": [stepper.REFRESH, 1]})
    data["summary"] = summary(data)
    _save(OUT / "rod.json", data)
    return data


#: The finer rod: twice the paper's points, eps = 5 Delta s, one fifth of a beat.
FINE_ROD = {"n_points": 601, "epsilon": 0.5, "t1": 0.01}


def fine_rod_part() -> dict[str, Any]:
    """The rod refined (M = 601): where the explicit limit (about Delta s^3.7) falls below what
    the implicit schemes' steps cost. The same measurement as ``rod``, over a fifth of a beat."""
    rod = models.rod_swimmer(n_points=FINE_ROD["n_points"], epsilon=FINE_ROD["epsilon"],
                             n_threads=1)
    path = OUT / "rod601.json"
    data = _load(path)
    if "euler_limit" not in data:
        data["euler_limit"] = integrate.largest_stable_step(rod, "euler", 0.005, 2e-7, 5e-6,
                                                            rtol=0.02)
        _save(path, data)
    limit = data["euler_limit"]
    steps = {"euler": [0.95 * limit], "rk2": [0.95 * limit], "rk4": [1.3 * limit],
             "ros2": [2.5e-4, 1.25e-4, 6.25e-5], "ros2-krylov": [2.5e-4, 1.25e-4, 6.25e-5]}
    steps = {k: [float(f"{v:.3g}") for v in vs] for k, vs in steps.items()}
    data = work_precision("rod601", rod, FINE_ROD["t1"], float(f"{0.5 * limit:.3g}"), steps, {})
    data["summary"] = summary(data)
    _save(path, data)
    return data


def vesicle_part() -> dict[str, Any]:
    ves = models.vesicle(subdivisions=3, n_threads=1)
    path = OUT / "vesicle.json"
    data = _load(path)
    if "euler_limit" not in data:
        data["euler_limit"] = integrate.largest_stable_step(ves, "euler", 1.0, 1e-5, 1e-1,
                                                            relative=True)
        _save(path, data)
    limit = data["euler_limit"]
    steps = {"euler": [0.95 * limit], "rk2": [0.95 * limit, 0.5 * limit],
             "rk4": [1.3 * limit, 0.95 * limit],
             "lieuler": [5 * limit, 2.5 * limit], "ros2": [20 * limit, 10 * limit, 5 * limit],
             "ros2-krylov": [20 * limit, 10 * limit, 5 * limit]}
    steps = {k: [float(f"{v:.3g}") for v in vs] for k, vs in steps.items()}
    data = work_precision("vesicle", ves, 10.0, float(f"{0.25 * limit:.3g}"), steps, {})
    data["summary"] = summary(data)
    _save(path, data)
    return data


def parareal_part() -> dict[str, Any]:
    """The paper's rod over T = 0.01: Table 4's G1 against ROS2 coarse solvers."""
    rod = models.rod_swimmer(n_points=301, epsilon=1.0, n_threads=1)
    fine_dt = 1e-6
    return _parareal("parareal", rod, 0.01, fine_dt, {
        "table4_g1 (36 x euler, 20 tau_f)": lambda: parareal.extrapolated(
            rod, "euler", 20 * fine_dt, lagrange=TABLE4_G1),
        **{f"ros2-krylov {dt:g}": (lambda dt=dt: integrate.Propagator(rod, "ros2-krylov", dt))
           for dt in (1e-3, 5e-4, 2.5e-4)},
        **{f"ros2 {dt:g}": (lambda dt=dt: integrate.Propagator(rod, "ros2", dt))
           for dt in (5e-4, 2.5e-4)},
    })


#: Table 4 G1's Lagrange nodes (eps in units of eps0 = 5 sigma_f; a; mu).
TABLE4_G1 = {"epsilon": [5.2 / 5, 5.25 / 5, 5.3 / 5, 5.35 / 5], "bending": [0.7, 0.75, 0.8],
             "viscosity": [1.3e-6, 1.45e-6, 1.6e-6]}


def fine_parareal_part() -> dict[str, Any]:
    """The rod of 601 points over T = 0.005, F = RK2 at 5e-7 (below Euler's limit 7.97e-7):
    Table 4 G1's construction at 20 tau_f and forward Euler at its limit against ROS2."""
    rod = models.rod_swimmer(n_points=FINE_ROD["n_points"], epsilon=FINE_ROD["epsilon"],
                             n_threads=1)
    fine_dt = 5e-7
    return _parareal("parareal601", rod, 0.005, fine_dt, {
        "table4_g1 construction (36 x euler, 20 tau_f)": lambda: parareal.extrapolated(
            rod, "euler", 20 * fine_dt, lagrange=TABLE4_G1),
        "euler 7.5e-07 (its limit)": lambda: integrate.Propagator(rod, "euler", 7.5e-7),
        **{f"ros2-krylov {dt:g}": (lambda dt=dt: integrate.Propagator(rod, "ros2-krylov", dt))
           for dt in (2.5e-4, 1.25e-4)},
        "ros2 0.000125": lambda: integrate.Propagator(rod, "ros2", 1.25e-4),
    })


def _parareal(name: str, rod: Any, t1: float, fine_dt: float,
              candidates: dict[str, Callable[[], Any]]) -> dict[str, Any]:
    """Per coarse candidate: eta^k of 3 iterations on N_SLICES slices against the serial fine
    solution (RK2 at ``fine_dt``), the CPU of one coarse call over a slice (one auxiliary solve
    of an extrapolated G) over that of one fine slice measured just before it (gamma_G/gamma_F),
    and eq. 14 at 40 cores; a candidate that blows up is recorded as such."""
    path = OUT / f"{name}.json"
    data = _load(path)
    x0 = rod.initial_state()
    fine = integrate.Propagator(rod, "rk2", fine_dt)
    slice_length = t1 / N_SLICES
    cache = OUT / f".{name}_serial.npy"
    if not cache.exists():
        np.save(cache, parareal.serial_solution(fine, x0, 0.0, t1, N_SLICES))
    reference = np.load(cache)
    rows = data.setdefault("rows", {})
    for label, make in candidates.items():
        if label in rows:
            continue
        coarse = make()
        n_aux = getattr(coarse, "n_auxiliary", 1)
        _, fine_cpu = _timed(lambda: fine(0.0, slice_length, x0))
        try:
            _, cpu = _timed(lambda c=coarse: c(0.0, slice_length, x0))
            result = parareal.run(fine, coarse, x0, t0=0.0, t1=t1, n_slices=N_SLICES, tol=0.0,
                                  max_iterations=3, reference=reference)
        except (integrate.BlowUpError, TaskError) as error:  # (a coarse step's, wrapped)
            rows[label] = {"blowup": str(error)[:300], "n_auxiliary": n_aux}
        else:
            gamma = cpu / n_aux / fine_cpu
            rows[label] = {"gamma_ratio": gamma, "n_auxiliary": n_aux, "fine_slice_cpu": fine_cpu,
                           "errors": result.errors, "increments": result.increments,
                           "speedup_eq14_40_cores_k1": eq14(gamma, 1.0, 1, 40),
                           "speedup_eq14_40_cores_k2": eq14(gamma, 1.0, 2, 40)}
        print(name, label, rows[label], flush=True)
        _save(path, data)
    return data


#: The paper's fine problems (one per distinct F: Tables 3 and 4 share theirs), the config that
#: states each and the records of docs/reproduction whose eta^k it is compared with. Table 6
#: (tau_f = 1e-7: F alone takes about three hours of CPU here) comes last; its F resumes.
CASES = {
    "table4": ("experiments/table4_g1.toml", ("table3_", "table4_")),
    "table7": ("experiments/table7_g1.toml", ("table7_",)),
    "table8": ("experiments/table8_g1.toml", ("table8_",)),
    "table5": ("experiments/table5_g1.toml", ("table5_",)),
    "table6_eps3": ("experiments/table6_eps3.toml", ("table6_eps3",)),
}
#: Candidate serial runs: steps in units of forward Euler's stability limit of the case
#: (``integrate.largest_stable_step``; Table 5's rows were taken at Table 4's limit, 1.22e-5).
SERIAL_CANDIDATES = {"euler": [0.95], "rk2": [0.95, 0.5], "rk4": [1.3, 0.65],
                     "ros2": [10.0], "ros2-krylov": [20.0, 10.0]}
#: F's CPU time beside each row is measured over this fraction of T and scaled to T.
FINE_PROBE = 0.01
BEST_SERIAL = OUT / "best_serial.json"


def _records(prefixes: tuple[str, ...]) -> dict[str, dict[str, Any]]:
    """eta^k and the eq. 14 speedups at 40 cores of the full-scale records (docs/reproduction)."""
    out = {}
    for path in sorted(pathlib.Path("docs/reproduction").glob("table*.json")):
        if path.stem.startswith(prefixes):
            record = json.loads(path.read_text())
            out[path.stem] = {"errors": record["errors"],
                              "speedups": record["speedup_40"]["speedup"]}
    return out


def _serial_case(case: str, config_path: str, data: dict[str, Any]) -> None:
    from parastokes import config
    from parastokes.parareal import relative_change

    cfg, resolved = config.load(config_path, ["execution.threads=1"])
    system = config.build_system(cfg, resolved)
    x0 = system.initial_state()
    t1, scheme, dt = cfg.time.t1, cfg.fine.scheme, cfg.fine.dt
    entry = data["cases"].setdefault(case, {"config": config_path, "t1": t1})
    entry["problem"] = config.problem_key(cfg)  # predict --serial checks it is the same problem
    partial = OUT / f".best_serial_{case}_partial.npz"  # (kept with the results: F's state)

    def fine_solution() -> np.ndarray:
        """F's serial solution at T, computed (or resumed) the first time a row needs it."""
        reference, cpu = _fine_reference(system, x0, t1, scheme, dt, partial)
        entry.setdefault("reference", {"scheme": scheme, "dt": dt, "cpu": cpu})
        _save(BEST_SERIAL, data)
        return reference

    if "reference" not in entry:
        fine_solution()
    if "euler_limit" not in entry:
        rod = cfg.model.kind == "rod"  # (the limit over a beat, to 2 %, as docs/benchmarks.md's)
        entry["euler_limit"] = integrate.largest_stable_step(
            system, "euler", 0.05 if rod else 1.0, dt, (200 if rod else 40) * dt,
            rtol=0.02 if rod else 0.05, relative=not rod)
        _save(BEST_SERIAL, data)
    entry["targets"] = _records(CASES[case][1])
    rows = entry.setdefault("rows", [])
    blowups = entry.setdefault("blowups", [])
    done = {(r["scheme"], r["dt"]) for r in rows + blowups}
    for name, factors in SERIAL_CANDIDATES.items():
        for factor in factors:
            step = float(f"{factor * entry['euler_limit']:.3g}")
            if (name, step) in done:
                continue
            _, probe = _timed(lambda: integrate.propagate(system, x0, 0.0, FINE_PROBE * t1,
                                                          scheme, dt))
            try:
                result, cpu = _timed(lambda s=name, h=step: integrate.run(system, x0, 0.0, t1,
                                                                          s, h))
            except integrate.BlowUpError as error:
                blowups.append({"scheme": name, "dt": step, "error": str(error)[:200]})
                print(case, blowups[-1], flush=True)
                _save(BEST_SERIAL, data)
                continue
            reference = fine_solution()
            rows.append({"scheme": name, "dt": step, "cpu": cpu, "fine_cpu": probe / FINE_PROBE,
                         "error": relative_change(result.state, reference, system.positions),
                         "steps": result.n_steps})
            print(case, rows[-1], flush=True)
            _save(BEST_SERIAL, data)


#: F's serial run of a case is saved after each of this many chunks (a stopped run resumes).
REFERENCE_CHUNKS = 100


def _fine_reference(system: Any, x0: np.ndarray, t1: float, scheme: str, dt: float,
                    partial: pathlib.Path) -> tuple[np.ndarray, float]:
    """F's state at ``t1`` from ``x0`` and its CPU time, in :data:`REFERENCE_CHUNKS` chunks on
    F's own step grid, the state after each saved to ``partial`` (resumed from it)."""
    steps = integrate.n_steps(0.0, t1, dt)
    h = t1 / steps
    bounds = np.linspace(0, steps, REFERENCE_CHUNKS + 1).round().astype(int)
    done, x, cpu = 0, x0, 0.0
    if partial.exists():
        saved = np.load(partial)
        done, x, cpu = int(saved["done"]), saved["x"], float(saved["cpu"])
    for i in range(done, REFERENCE_CHUNKS):
        a, b = bounds[i], bounds[i + 1]
        x, seconds = _timed(lambda x=x, a=a, b=b: integrate.propagate(system, x, a * h, b * h,
                                                                      scheme, dt))
        cpu += seconds
        np.savez(partial.with_suffix(".tmp.npz"), done=i + 1, x=x, cpu=cpu)
        partial.with_suffix(".tmp.npz").replace(partial)
        print(f"F: chunk {i + 1} of {REFERENCE_CHUNKS}, {cpu:.0f} s", flush=True)
    return x, cpu


def best_serial_part() -> dict[str, Any]:
    """Per paper case: F's serial solution at T, then each candidate's error at T against it
    (eta of eq. 34) and its CPU time beside F's (measured over FINE_PROBE T just before, scaled)."""
    data = _load(BEST_SERIAL)
    data.setdefault("cases", {})
    for case, (config_path, _) in CASES.items():
        _serial_case(case, config_path, data)
    print(best_serial_table(data))
    return data


def own_error(entry: dict[str, Any]) -> float:
    """F's own error at T, estimated as the smallest error of the case's runs of a higher order
    than F's: they converge to the exact solution far faster than F, so their distance to F
    levels off at F's own distance to it; 0 (not estimated) without such runs."""
    order = integrate.SCHEMES[entry["reference"]["scheme"]].order
    higher = [r["error"] for r in entry["rows"] if integrate.SCHEMES[r["scheme"]].order > order]
    return min(higher, default=0.0)


def _own(entry: dict[str, Any]) -> str:
    floor = own_error(entry)
    return f"about {floor:.2g}" if floor else "not estimated (no run of a higher order)"


def best_serial_table(data: dict[str, Any]) -> str:
    """The markdown table of docs/benchmarks.md: per record and iteration, eta^k, the paper's
    speedup (eq. 14 at 40 cores, against F), the fastest measured serial run reaching eta^k and
    the speedup against it."""
    from parastokes.parareal.best_serial import load_serial_runs

    lines = []
    for case, entry in data["cases"].items():
        if "rows" not in entry:
            continue
        ref, limit = entry["reference"], entry["euler_limit"]
        lines += [f"{case} ({entry['config']}, T = {entry['t1']:g}; F = {ref['scheme']} at "
                  f"{ref['dt']:g}, {ref['cpu']:.0f} s; forward Euler's limit {limit:.3g}; F's own "
                  f"error {_own(entry)}):", "",
                  "| scheme | step | x limit | error at T (eq. 34) | CPU (s) | F's CPU over it |",
                  "|---|---|---|---|---|---|"]
        lines += [f"| `{r['scheme']}` | {r['dt']:.3g} | {r['dt'] / limit:.3g} | {r['error']:.2e} | "
                  f"{r['cpu']:.1f} | {r['fine_cpu'] / r['cpu']:.3g} |" for r in entry["rows"]]
        lines += [f"| `{b['scheme']}` | {b['dt']:.3g} | {b['dt'] / limit:.3g} | blew up | - | - |"
                  for b in entry.get("blowups", [])]
        lines.append("")
    lines += ["| record | k | eta^k | eq. 14 speedup against F (40 cores) | fastest serial run "
             "reaching eta^k (its error) | F's CPU over its | speedup against it |",
             "|---|---|---|---|---|---|---|"]
    for case, entry in data["cases"].items():
        if "rows" not in entry:
            continue
        runs = load_serial_runs(BEST_SERIAL, case)
        errors = {(r["scheme"], r["dt"]): r["error"] for r in entry["rows"]}
        floor = own_error(entry)
        for record, target in entry["targets"].items():
            for k, (eta, speedup) in enumerate(zip(target["errors"], target["speedups"],
                                                   strict=False), start=1):
                best = runs.best(eta)
                if best is runs.reference:
                    what = (f"F itself (eta^k below F's own error, {floor:.2g})" if eta < floor
                            else "F itself (no measured run reaches it)")
                else:
                    what = f"{best.describe()} ({errors[(best.scheme, best.dt)]:.2g})"
                lines.append(f"| {record} | {k} | {eta:.2g} | {speedup:.3g} | {what} | "
                             f"{best.fine_over:.3g} | {speedup / best.fine_over:.3g} |")
    return "\n".join(lines)


def figure() -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    parts = [p for p in ("rod", "rod601", "vesicle") if (OUT / f"{p}.json").exists()]
    if not parts:
        return
    fig, axes = plt.subplots(1, len(parts), figsize=(5.5 * len(parts), 4.2), squeeze=False)
    for ax, part in zip(axes[0], parts, strict=True):
        rows = _load(OUT / f"{part}.json")["rows"]
        for scheme in integrate.SCHEMES:
            implicit = integrate.SCHEMES[scheme].implicit
            for every in sorted({r.get("refresh") for r in rows if r["scheme"] == scheme},
                                key=lambda v: -(v or 0)):
                pts = sorted((r["cpu"], r["error"]) for r in rows
                             if r["scheme"] == scheme and r.get("refresh") == every
                             and math.isfinite(r["error"]))
                if not pts:
                    continue
                label = f"{scheme} (A every {every})" if implicit and every == 1 else scheme
                style = ":o" if implicit and every == 1 else "-o" if implicit else "--s"
                ax.loglog(*zip(*pts, strict=True), style, label=label,
                          color=f"C{list(integrate.SCHEMES).index(scheme)}")
        ax.xaxis.set_minor_formatter(plt.NullFormatter())
        ax.set_xlabel("CPU time (s, one thread)")
        ax.set_ylabel("error at T (relative)")
        ax.set_title({"rod": "rod M = 301 above the wall, T = 0.05 s",
                      "rod601": "rod M = 601 above the wall, T = 0.01 s",
                      "vesicle": "vesicle 642 points in shear, T = 10"}[part])
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(OUT / "work_precision.png", dpi=120)


#: The rods of the short work-precision (``--parts linalg short``): points, ε, and the explicit
#: schemes' step: just below forward Euler's limit (1.22e-5 and 7.97e-7 s, bisected in
#: docs/benchmarks.md, "Stiff bodies"; at the limit itself both blow up over T).
SHORT_RODS = {"rod301": (301, 1.0, 1.2e-5), "rod601": (601, 0.5, 7.58e-7)}
SHORT_T = 0.005
#: The rod of 1201 points (``--parts short1201``, ε = 5Δs) over its own, shorter T: RK4 at
#: half its limit over 0.005 s would take about 1.5 hours of CPU here. Its explicit step: 0.95
#: of forward Euler's limit 5.11e-8 s, bisected over that T (``integrate.largest_stable_step(
#: rod, "euler", 2.5e-4, 2e-8, 1.2e-7, rtol=0.02)``, 160 s of CPU).
SHORT_ROD1201 = {"rod1201": (1201, 0.25, 4.85e-8)}
SHORT_T1201 = 2.5e-4


#: Rounds of :func:`_interleaved` (each piece timed once per round, the least kept).
ROUNDS = 9

#: The commit whose ``stiff.banded`` (and ``.local``) held round 5's third-session fused
#: product (a pair list, the scalars per pair): timed and run beside the current one.
PREVIOUS_PRODUCT = "4ad4b43"


def _previous_banded(commit: str = PREVIOUS_PRODUCT) -> Any:
    """``parastokes.stiff.banded`` as it was at ``commit`` (with its ``.local``), loaded from
    git into a package of its own (in the temporary directory), beside the current one."""
    import importlib
    import subprocess
    import tempfile

    package = pathlib.Path(tempfile.gettempdir()) / "parastokes_previous" / f"stiff_{commit}"
    package.mkdir(parents=True, exist_ok=True)
    (package / "__init__.py").write_text("")
    for name in ("banded", "local"):
        source = subprocess.run(["git", "show", f"{commit}:parastokes/stiff/{name}.py"],
                                check=True, capture_output=True, text=True).stdout
        (package / f"{name}.py").write_text(source)
    sys.path.insert(0, str(package.parent))
    return importlib.import_module(f"stiff_{commit}.banded")


def _interleaved(pieces: dict[str, Callable[[], Any]], repeat: dict[str, int]
                 ) -> dict[str, float]:
    """CPU seconds per call of each of ``pieces``: after one warm-up call each, :data:`ROUNDS`
    rounds that time every piece once (a batch of ``repeat`` calls, default 5) in turn, and
    the least per piece over the rounds (on a shared machine the other jobs only add: the least
    is the least disturbed, and the pieces meet the same moments)."""
    def batch(function: Callable[[], Any], n: int) -> None:
        for _ in range(n):  # each result dropped before the next call, as a run drops them
            function()

    for function in pieces.values():
        function()
    best = dict.fromkeys(pieces, math.inf)
    for _ in range(ROUNDS):
        for key, function in pieces.items():
            n = repeat.get(key, 5)
            best[key] = min(best[key], _timed(lambda f=function, n=n: batch(f, n))[1] / n)
    return best


@njit(cache=True, error_model="numpy")
def _band_solve_signed(lu, kl, ku, piv, b):  # pragma: no cover - compiled
    """``stiff.solve.band_solve`` as round 5's second session left it (the session-start row of
    the stage solve): the same operations in the same order, over numpy slices and signed
    indices (a slice's set-up per column, numba's check for negative indices in the loops)."""
    n = lu.shape[1]
    kv = kl + ku
    x = b.copy()
    for j in range(n - 1):
        pivot = piv[j]
        if pivot != j:
            x[pivot], x[j] = x[j], x[pivot]
        xj = x[j]
        if xj != 0.0:
            lm = min(kl, n - j - 1)
            column, below = lu[kv + 1:kv + 1 + lm, j], x[j + 1:j + 1 + lm]
            for i in range(lm):
                below[i] -= np.float64(column[i]) * xj
    for j in range(n - 1, -1, -1):
        if x[j] != 0.0:
            x[j] /= np.float64(lu[kv, j])
            xj = x[j]
            first = max(0, j - kv)
            column, above = lu[kv + first - j:kv, j], x[first:j]
            for i in range(j - first):
                above[i] -= np.float64(column[i]) * xj
    return x


def _linalg_rod(m: int, eps: float) -> dict[str, Any]:
    """:func:`linalg_part` on the rod of ``m`` points and regularization ``eps``."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla
    from scipy.linalg import lapack

    from parastokes.stiff import banded, coloring, jacobian, local, solve

    rod = models.rod_swimmer(n_points=m, epsilon=eps, n_threads=1)
    x = rod.initial_state()
    n = rod.rates(0.0, x).size
    hgamma = 2.5e-4 * integrate.SCHEMES["ros34pw2"].gamma
    cutoff = jacobian.CUTOFF * eps

    def coloured() -> sp.bsr_array:  # the loads' Jacobian before the rod's hook
        return coloring.fd_jacobian(jacobian._loads_function(rod, 0.0), rod.advance, x, 6,
                                    rod.load_coupling(), jacobian.fd_step(x))

    k = sp.bsr_array(jacobian.load_jacobian(rod, 0.0, x), blocksize=(6, 6))
    mob = local.near_mobility(rod.positions(x), eps, rod.viscosity, True, cutoff)
    a = banded.near_product(rod.positions(x), eps, rod.viscosity, True, cutoff, k)
    a_bsr = banded.block_product(mob, k)
    previous = _previous_banded()
    a_previous = previous.near_product(rod.positions(x), eps, rod.viscosity, True, cutoff, k)
    lu = solve.Factorization(a, hgamma, 0.0)
    v = np.ones(n)
    lu_band, piv, kl, ku = lu._band  # type: ignore[misc]
    lu_double = lu_band.astype(float, order="F")  # dgbtrs's: the factors in double

    def double(matrix: Any) -> solve.Factorization:  # the banded LU in double precision
        solve.BAND_PRECISION = np.float64
        try:
            return solve.Factorization(matrix, hgamma, 0.0)
        finally:
            solve.BAND_PRECISION = np.float32

    def own_width(matrix: Any) -> solve.Factorization:  # sgbtrf with A's own kl (95, not 96)
        width, solve.elimination_width = solve.elimination_width, lambda kl: kl
        try:
            return solve.Factorization(matrix, hgamma, 0.0)
        finally:
            solve.elimination_width = width

    def session_start() -> None:  # this session's start: coloured K, M, BSR product, dgbtrf
        product = banded.block_product(
            local.near_mobility(rod.positions(x), eps, rod.viscosity, True, cutoff),
            sp.bsr_array(coloured(), blocksize=(6, 6)))
        double(product)

    def before() -> None:  # this round's start: scipy's BSR product, CSC, SuperLU
        system = sp.eye_array(n, format="csc") - hgamma * (mob @ k).tocsc()
        spla.splu(system, permc_spec="NATURAL")

    pieces = {
        "evaluation": lambda: rod.rates(0.0, x),
        "K": lambda: jacobian.load_jacobian(rod, 0.0, x),
        "K_coloured": coloured,
        "M": lambda: local.near_mobility(rod.positions(x), eps, rod.viscosity, True, cutoff),
        "product": lambda: banded.block_product(mob, k),
        "fused_product": lambda: banded.near_product(rod.positions(x), eps, rod.viscosity,
                                                     True, cutoff, k),
        "fused_product_third_session": lambda: previous.near_product(
            rod.positions(x), eps, rod.viscosity, True, cutoff, k),
        "factorization": lambda: solve.Factorization(a, hgamma, 0.0),
        "factorization_double": lambda: double(a),
        "factorization_own_width": lambda: own_width(a),
        "stage_solve": lambda: lu.solve(v),
        "stage_solve_signed": lambda: _band_solve_signed(lu_band, kl, ku, piv, v),
        "stage_solve_dgbtrs": lambda: lapack.dgbtrs(lu_double, kl, ku, v, piv),
        "stage_solve_sgbtrs": lambda: lapack.sgbtrs(lu_band, kl, ku, v.astype(np.float32), piv),
        "fresh": lambda: solve.Factorization(jacobian.local_jacobian(rod, 0.0, x, n), hgamma,
                                             0.0),
        "fresh_third_session": lambda: solve.Factorization(previous.near_product(
            rod.positions(x), eps, rod.viscosity, True, cutoff,
            sp.bsr_array(jacobian.load_jacobian(rod, 0.0, x), blocksize=(6, 6))), hgamma, 0.0),
        "session_start_fresh": session_start,
        "before_product_csc_splu": before,
    }
    load = os.getloadavg()
    cpu = _interleaved(pieces, {"evaluation": 20, "stage_solve": 20})
    ratio = {key: value / cpu["evaluation"] for key, value in cpu.items()}
    exact = double(a_bsr).solve(v)
    entry: dict[str, Any] = {"points": m, "unknowns": n, "band": list(banded.bandwidth(a)),
                             "cpu_ms": {key: 1e3 * value for key, value in cpu.items()},
                             "per_evaluation": ratio,
                             "load_average": [round(v, 2) for v in (*load, *os.getloadavg())],
                             "fused_vs_bsr_product": float(np.abs(a.toarray() - a_bsr.toarray())
                                                           .max() / np.abs(a_bsr.data).max()),
                             "fused_vs_third_session": float(
                                 np.abs(a.toarray() - a_previous.toarray()).max()
                                 / np.abs(a_previous.data).max()),
                             "single_vs_double_solve": float(np.abs(lu.solve(v) - exact).max()
                                                             / np.abs(exact).max()),
                             "stage_solve_same_bits": bool(np.array_equal(
                                 lu.solve(v), _band_solve_signed(lu_band, kl, ku, piv, v))),
                             "before_fresh": ratio["K_coloured"] + ratio["M"]
                             + ratio["before_product_csc_splu"]}
    for scheme, stages in (("ros2", 2), ("ros34pw2", 4)):
        for every in (5, 10):
            for fresh in ("fresh", "fresh_third_session"):
                entry[f"amortized_{scheme}_refresh{every}{fresh[5:]}"] = (
                    ratio[fresh] / every + stages * ratio["stage_solve"])
    return entry


def _counts() -> dict[str, Any]:
    """Jacobians and factorizations of ROS34PW2 runs over T on the rod of 301 points: fixed
    steps of 2.5e-4 s and adaptive ones (rtol 1e-4, atol 1e-5)."""
    made = {"jacobians": 0, "factorizations": 0}
    jacobian_of, factorization = stepper.local_jacobian, stepper.Factorization

    def counted_jacobian(*args: Any) -> Any:
        made["jacobians"] += 1
        return jacobian_of(*args)

    def counted_factorization(*args: Any) -> Any:
        made["factorizations"] += 1
        return factorization(*args)

    rod = models.rod_swimmer(n_points=301, epsilon=1.0, n_threads=1)
    out = {}
    stepper.local_jacobian, stepper.Factorization = counted_jacobian, counted_factorization
    try:
        for label, kw in (("fixed", {}), ("adaptive", {"rtol": 1e-4, "atol": 1e-5})):
            made.update(jacobians=0, factorizations=0)
            result = integrate.run(rod, rod.initial_state(), 0.0, SHORT_T, "ros34pw2", 2.5e-4,
                                   **kw)  # type: ignore[arg-type]
            out[label] = dict(made, accepted=result.n_steps, rejected=result.n_rejected)
    finally:
        stepper.local_jacobian, stepper.Factorization = jacobian_of, factorization
    return out


def linalg_part(rods: list[str]) -> dict[str, Any]:
    """The linear algebra of a linearly implicit step on the rods of :data:`SHORT_RODS`, each
    piece's CPU time over one evaluation of the rates, in one run: the loads' Jacobian K (the
    rod's hook; the coloured differences), the near mobility M and the product A = M K (the
    fused pass; stored M and the BSR product), the factorization of I - hγA (single and double
    precision), one stage solve (beside the second session's loops, LAPACK's dgbtrs on the
    factors in double and its sgbtrs, a solve in single precision), a fresh Jacobian and
    factorization now, at this session's start and before this round (scipy's BSR product,
    CSC and SuperLU); and the counts of Jacobians and factorizations of a fixed and an
    adaptive ROS34PW2 run on the rod of 301 points."""
    data = _load(OUT / "linalg.json")
    for name in rods:
        m, eps, _ = SHORT_RODS[name]
        data[name] = _linalg_rod(m, eps)
        print(name, json.dumps(data[name], indent=1), flush=True)
    data["counts_rod301_ros34pw2"] = _counts()
    print(data["counts_rod301_ros34pw2"], flush=True)
    _save(OUT / "linalg.json", data)
    return data


def _accuracy_rows(rod: Any, reference: np.ndarray, limit: float) -> list[dict[str, Any]]:
    """The 21 ROS2 and ROS34PW2 runs of ``--parts short`` on ``rod`` (fixed steps, ``A`` every
    5 and 10 steps for ROS34PW2; adaptive, atol = rtol/10): error at T, steps, rejections."""
    x0 = rod.initial_state()
    steps = short_steps(limit, SHORT_T)
    runs = [(s, dt, None, every) for s, periods in (("ros2", (5,)), ("ros34pw2", (5, 10)))
            for dt in steps[s] for every in periods]
    runs += [(s, 1e-4, rtol, 5) for s in ("ros2", "ros34pw2") for rtol in (1e-2, 1e-3, 1e-4,
                                                                            1e-5)]
    rows = []
    for scheme, dt, rtol, every in runs:
        stepper.REFRESH = every
        tolerance = {} if rtol is None else {"rtol": rtol, "atol": 0.1 * rtol}
        try:
            result = integrate.run(rod, x0, 0.0, SHORT_T, scheme, dt,
                                   **tolerance)  # type: ignore[arg-type]
            row = {"error": _relative_error(result.state, reference, x0),
                   "steps": result.n_steps, "rejected": result.n_rejected}
        except integrate.BlowUpError:
            row = {"error": math.inf}
        finally:
            stepper.REFRESH = 5
        rows.append({"scheme": scheme, "dt": None if rtol else dt, "rtol": rtol,
                     "refresh": every, **row})
    return rows


def linalg_accuracy_part(rods: list[str]) -> dict[str, Any]:
    """The 21 ROS2 and ROS34PW2 runs (:func:`_accuracy_rows`) on the rods ``rods`` with the
    current ``A`` and with that of :data:`PREVIOUS_PRODUCT`'s product (``stiff.jacobian``'s
    ``near_product`` replaced), in one process, against ``--parts short``'s RK4 reference:
    the largest relative change of an error, and whether the steps and rejections agree."""
    from parastokes.stiff import jacobian

    data = _load(OUT / "linalg_accuracy.json")
    previous, current = _previous_banded().near_product, jacobian.near_product
    for name in rods:
        m, eps, limit = SHORT_RODS[name]
        rod = models.rod_swimmer(n_points=m, epsilon=eps, n_threads=1)
        reference, _ = reference_state(f"short_{name}", rod, SHORT_T, float(f"{0.5 * limit:.2g}"))
        entry = {"current": _accuracy_rows(rod, reference, limit)}
        jacobian.near_product = previous
        try:
            entry["third_session"] = _accuracy_rows(rod, reference, limit)
        finally:
            jacobian.near_product = current
        pairs = list(zip(entry["current"], entry["third_session"], strict=True))
        entry["largest_relative_error_change"] = max(
            abs(a["error"] - b["error"]) / b["error"] for a, b in pairs
            if math.isfinite(b["error"]))
        entry["same_steps_and_rejections"] = all(
            (a.get("steps"), a.get("rejected")) == (b.get("steps"), b.get("rejected"))
            for a, b in pairs)
        data[name] = entry
        print(name, json.dumps(entry, indent=1), flush=True)
        _save(OUT / "linalg_accuracy.json", data)
    return data


def short_steps(limit: float, t1: float) -> dict[str, list[float]]:
    """The fixed steps of ``--parts short`` over T = ``t1``: forward Euler and RK2 at ``limit``,
    the implicit schemes at steps of T = :data:`SHORT_T` scaled by ``t1 / SHORT_T`` (the same
    number of steps), to 3 significant digits."""
    steps = {"ros2": [2.5e-4, 1.25e-4, 6.25e-5],
             "ros34pw2": [1e-3, 5e-4, 2.5e-4, 1.25e-4, 6.25e-5],
             "ros2-krylov": [2.5e-4, 1.25e-4],
             "ros34pw2-krylov": [5e-4, 2.5e-4, 1.25e-4]}
    return {"euler": [limit], "rk2": [limit],
            **{k: [float(f"{v * t1 / SHORT_T:.3g}") for v in vs] for k, vs in steps.items()}}


def short_part(rods: list[str]) -> dict[str, Any]:
    """Work-precision over T = :data:`SHORT_T` on the rods ``rods`` of :data:`SHORT_RODS`
    (:data:`SHORT_T1201` on the rod of :data:`SHORT_ROD1201`): forward Euler and RK2 just below
    forward Euler's limit, ROS2, ROS34PW2 (Jacobian every 5 and 10 steps), ROS2-Krylov and
    ROS34PW2-Krylov at fixed steps, and ROS2, ROS34PW2 and ROS34PW2-Krylov adaptive across
    tolerances (atol = rtol/10 μm), against RK4 at half the limit; rows as
    ``work_precision``'s plus ``rtol``. The implicit steps and the adaptive runs' first step
    are those of T = :data:`SHORT_T` scaled by ``T / SHORT_T``."""
    out = {}
    for name in rods:
        m, eps, limit = {**SHORT_RODS, **SHORT_ROD1201}[name]
        t1 = SHORT_T1201 if name in SHORT_ROD1201 else SHORT_T
        scale = t1 / SHORT_T
        rod = models.rod_swimmer(n_points=m, epsilon=eps, n_threads=1)
        key = f"short_{name}"
        data = work_precision(key, rod, t1, float(f"{0.5 * limit:.2g}"), short_steps(limit, t1),
                              {"ros34pw2": [5, 10]})
        reference = np.load(OUT / f".{key}_reference.npy")
        x0 = rod.initial_state()
        done = {(r["scheme"], r.get("rtol")) for r in data["rows"]}
        for scheme in ("ros2", "ros34pw2", "ros34pw2-krylov"):
            for rtol in (1e-2, 1e-3, 1e-4, 1e-5):
                if (scheme, rtol) in done:
                    continue
                result, cpu = _timed(lambda s=scheme, r=rtol, body=rod, y=x0, t=t1, h=scale * 1e-4:
                                     integrate.run(body, y, 0.0, t, s, h, rtol=r, atol=0.1 * r))
                row = {"scheme": scheme, "rtol": rtol, "dt": None, "refresh": stepper.REFRESH,
                       "error": _relative_error(result.state, reference, x0), "cpu": cpu,
                       "steps": result.n_steps, "rejected": result.n_rejected}
                data["rows"].append(row)
                print(key, row, flush=True)
                _save(OUT / f"{key}.json", data)
        data["summary"] = summary(data)
        _save(OUT / f"{key}.json", data)
        out[name] = data
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", nargs="+", default=["rod", "vesicle", "parareal"],
                        choices=["rod", "rod601", "vesicle", "parareal", "parareal601",
                                 "best_serial", "linalg", "linalg_accuracy", "short",
                                 "short1201"])
    parser.add_argument("--rods", nargs="+", default=list(SHORT_RODS), choices=list(SHORT_RODS),
                        help="the rods of the parts linalg, linalg_accuracy and short "
                             "(default: both)")
    args = parser.parse_args(argv)
    for part in args.parts:
        if part in ("linalg", "linalg_accuracy", "short"):
            {"linalg": linalg_part, "linalg_accuracy": linalg_accuracy_part,
             "short": short_part}[part](args.rods)
            continue
        {"rod": rod_part, "rod601": fine_rod_part, "vesicle": vesicle_part,
         "parareal": parareal_part, "parareal601": fine_parareal_part,
         "best_serial": best_serial_part,
         "short1201": lambda: short_part(list(SHORT_ROD1201))}[part]()
        figure()
    return 0


if __name__ == "__main__":
    sys.exit(main())
