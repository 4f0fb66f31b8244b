"""Coarse solvers against an F at its stability limit: the measured frontier.

For each problem of the target table (docs/benchmarks.md, "Parareal against the fastest serial
run (round 5)") this script measures, on a documented shortened analogue (P_s slices of a given
length, one process, one kernel thread, CPU time):

- ``serial``: candidate serial runs over the analogue's interval (explicit schemes at their
  stability limit, implicit ones), each one's error eq. 34 against an accurate reference and its
  CPU time; F is the cheapest of them whose error stays well below the target;
- ``candidates``: per coarse solver G (a ``[coarse]`` table of the configuration schema, so that a
  winner ships as a config as it is), gamma_G / gamma_F (``parareal.measure_slice_costs``, CPU
  clock, the slowest auxiliary solve plus the combination over one fine slice) and eta^k of a real
  Parareal run over the analogue's P_s slices against F's serial solution;
- the predicted speedups at P = 40 slices on 40 cores, standard (1 / ((1 + K) alpha + K / P)) and
  pipelined (1 / ((1 + K / P) alpha + K / P), with N_G > 1 the simulated schedule), against F and
  against the fastest serial run reaching the same error, with K the first iteration whose eta^K
  plus F's own error reaches the target.

Results: ``docs/figures/frontier/PROBLEM.json``, one entry per measured candidate, written as
each one finishes (a rerun skips what is there: ``--redo LABEL`` measures one again).

    PYTHONPATH=. NUMBA_NUM_THREADS=1 python benchmarks/frontier.py --problems table4
    PYTHONPATH=. python benchmarks/frontier.py --table           # the tables of docs/benchmarks.md

``--k40 PROBLEM LABEL K`` checks an analogue's K on P = 40 slices of the same length: eta^1..eta^K
of a real Parareal run against F's serial solution, both resumable (``out/k40/PROBLEM/``), summed
up in ``docs/figures/frontier/k40_PROBLEM.json`` (docs/planning.md, "K at 40 slices").

``--serial-ratios PROBLEM ROUNDS SCHEME DT ...`` measures serial runs' CPU per slice against the
first one's in interleaved rounds (``PROBLEM_serial_ratios.json``: the fastest serial run's cost
over F's where it is not F, which the speedups against it then use), and ``--full-serial PROBLEM
SCHEME DT ...`` their errors at the full T against the problem's reference
(``PROBLEM_full_serial.json``); DT ``rtol=R`` is an adaptive run (docs/benchmarks.md, "The target
table"). ``--checkpointed PROBLEM SCHEME DT`` runs one serial run over the full T keeping its state
and CPU at ``--checkpoints`` (resumable; F timed in the same process), ``--checkpoint-errors
PROBLEM REFERENCE`` compares them, and ``--implicit-fine PROBLEM RTOL L P K LABEL ...`` runs
Parareal with an adaptive ``ros34pw2-krylov`` F (docs/benchmarks.md, "The rod of 601 points
against its fastest serial run").
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import pathlib
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

OUT = pathlib.Path("docs/figures/frontier")
#: The core count of the target table.
CORES = 40


@dataclass(frozen=True)
class Problem:
    """One row of the target table and its shortened analogue.

    ``model`` is the config's ``[model]`` table; ``fine`` (scheme, dt) the F of the Parareal runs
    (the fastest serial run well below the target, see ``serial``); ``slice_length`` the analogue's
    slice (the full problem's T / 40 where affordable), ``slices`` its P_s; ``serial`` the serial
    candidates (scheme, dt) and ``reference`` the accurate run the errors are measured against;
    ``full_t1`` the full problem's T.
    """

    title: str
    model: dict[str, Any]
    fine: tuple[str, float]
    slice_length: float
    slices: int
    target: float
    full_t1: float
    reference: tuple[str, float]
    serial: tuple[tuple[str, float], ...]
    max_iterations: int = 6
    #: The fastest serial run over the FULL interval where the analogue's is not it (an error
    #: that grows with T: experiments/best_serial/), else None (the analogue's cheapest row).
    best: tuple[str, float] | None = None

    @property
    def t1(self) -> float:
        return self.slice_length * self.slices


ROD = {"kind": "rod", "n_points": 301, "epsilon": 5, "epsilon_unit": "sigma_f"}
VESICLE = {"kind": "vesicle", "subdivisions": 3, "epsilon": 0.3, "epsilon_unit": "l_max",
           "stiffness": 0.1, "viscosity": 1e-3, "shear_rate": 0.1}

#: Forward Euler's stability limits (docs/benchmarks.md, "Stiff bodies" and "Speedup against the
#: best serial run"): rod 301 ε = 5σ_f 1.22e-5 s; ε = 7σ_f 4.19e-5 s; rod 601 7.97e-7 s;
#: vesicle (Table 7) 3.99e-3.
PROBLEMS: dict[str, Problem] = {
    "table4": Problem(
        "Table 4's rod (M = 301, ε⁰ = 5σ_f)", ROD, ("rk2", 1.16e-5), 0.025, 8, 1e-6, 1.0,
        ("rk4", 6.1e-6), (("euler", 1.16e-5), ("rk2", 1.16e-5), ("rk4", 1.59e-5))),
    "table5": Problem(
        "Table 5's rod (ε⁰ = 7σ_f)", {**ROD, "epsilon": 7}, ("rk4", 5.45e-5), 0.025, 8, 1e-6,
        1.0, ("rk4", 2.1e-5),
        (("euler", 3.98e-5), ("rk2", 3.98e-5), ("rk4", 5.45e-5), ("rk2", 3.74e-5)),
        # over T = 1 RK2 at 0.95 of Euler's limit misses 1e-6 (1.05e-6), at 0.9 reaches it
        # (`plan`: 9.3e-7 against F; docs/benchmarks.md, "The target table")
        best=("rk2", 3.74e-5)),
    "rod601": Problem(
        "rod refined to M = 601 (ε⁰ = 5σ_f)", {**ROD, "n_points": 601}, ("rk2", 7.58e-7),
        0.0005, 8, 1e-5, 1.0, ("rk4", 5e-7),
        (("euler", 7.58e-7), ("rk2", 7.58e-7)), best=("rk2", 7.58e-7)),
    "table7": Problem(
        "Table 7's vesicle (T = 100)", VESICLE, ("rk2", 0.00379), 2.5, 40, 1e-6, 100.0,
        ("rk4", 0.002), (("euler", 0.00379), ("rk2", 0.00379)),
        max_iterations=5),
    # the 601-point rod's winner again on slices 5 times longer (a fifth of the full one's)
    "rod601_long": Problem(
        "rod refined to M = 601 (ε⁰ = 5σ_f), longer slices", {**ROD, "n_points": 601},
        ("rk2", 7.58e-7), 0.0025, 4, 1e-5, 1.0, ("rk2", 3.79e-7), (("rk2", 7.58e-7),),
        max_iterations=3, best=("rk2", 7.58e-7)),
    # a smoke run (`--problems quick`, a minute): Table 4's rod cut to a fifth (L = 12, M = 61)
    "quick": Problem(
        "a fifth of Table 4's rod (M = 61, L = 12)", {**ROD, "n_points": 61, "length": 12},
        ("rk2", 1.16e-5), 0.001, 4, 1e-6, 0.004, ("rk4", 6.1e-6), (("rk2", 1.16e-5),),
        max_iterations=3),
}


@dataclass(frozen=True)
class Candidate:
    """A coarse solver: its family (the frontier keeps the best of each) and ``[coarse]`` table."""

    family: str
    coarse: dict[str, Any] = field(default_factory=dict)


def _grid(factor: int, eps_nodes: Sequence[float], scheme: str, dt: float,
          unit: str = "absolute") -> dict[str, Any]:
    """An extrapolated G on a grid ``factor`` times coarser (1: the fine grid), Lagrange in ε over
    ``eps_nodes`` (in ``unit``; one node: that ε, no extrapolation)."""
    table: dict[str, Any] = {"scheme": scheme, "dt": dt, "lagrange": {
        "epsilon": {"nodes": list(eps_nodes), "unit": unit}}}
    if factor > 1:
        table["grid_factor"] = factor
    return table


def _implicit(scheme: str, dt: float, every: int | None, hold: bool,
              eps_nodes: Sequence[float] | None = None) -> dict[str, Any]:
    """A linearly implicit G on the fine grid: ``A`` rebuilt every ``every`` steps
    (``coarse.jacobian_every``; None: the default), f_t held with it (``hold``), optionally
    Lagrange in ε over ``eps_nodes`` (μm)."""
    table: dict[str, Any] = {"scheme": scheme, "dt": dt}
    if every is not None:
        table["jacobian_every"] = every
    if hold:
        table["hold_time_derivative"] = True
    if eps_nodes:
        table["lagrange"] = {"epsilon": {"nodes": list(eps_nodes), "unit": "absolute"}}
    return table


def _cheaper(text: str, dt: float, every: int | None, hold: bool) -> dict[str, Candidate]:
    """The implicit candidate of :func:`_implicit` with ``ros34pw2`` at ``dt`` (written ``text``
    in its label), under its label: "ros34pw2 TEXT[, A every N][, f_t held]"."""
    label = f"ros34pw2 {text}" + (f", A every {every}" if every else "") + (
        ", f_t held" if hold else "")
    return {label: Candidate("implicit", _implicit("ros34pw2", dt, every, hold))}


#: Candidate coarse solvers per problem, cheapest families first. Labels name the construction.
CANDIDATES: dict[str, dict[str, Candidate]] = {
    "table4": {
        "grid 3, eps 3, euler 4e-4": Candidate(
            "coarse grid, ε scaled", _grid(3, [3.0], "euler", 4e-4)),
        "grid 3, eps [2, 3], euler 1.4e-4": Candidate(
            "coarse grid, Lagrange in ε", _grid(3, [2.0, 3.0], "euler", 1.4e-4)),
        "grid 3, eps [1.2, 1.4], euler 2.2e-5": Candidate(
            "coarse grid, Lagrange in ε", _grid(3, [1.2, 1.4], "euler", 2.2e-5)),
        "fine grid, eps [1.4, 1.6, 1.8], euler 4e-5": Candidate(
            "fine grid, Lagrange in ε (wide)", _grid(1, [1.4, 1.6, 1.8], "euler", 4e-5)),
        "grid 3, eps 1, euler 1.3e-5": Candidate(
            "coarse grid, ε fixed", {"scheme": "euler", "dt": 1.3e-5, "grid_factor": 3}),
        "grid 3, eps [1.2, 1.4, 1.6], euler 2.2e-5": Candidate(
            "coarse grid, Lagrange in ε", _grid(3, [1.2, 1.4, 1.6], "euler", 2.2e-5)),
        "grid 3, eps [2, 2.5, 3], rk2 1.4e-4": Candidate(
            "coarse grid, Lagrange in ε", _grid(3, [2.0, 2.5, 3.0], "rk2", 1.4e-4)),
        "ros34pw2 1.25e-3": Candidate("implicit", {"scheme": "ros34pw2", "dt": 1.25e-3}),
        "grid 3, eps 1, ros34pw2 1.25e-3": Candidate(
            "implicit on a coarse grid", {"scheme": "ros34pw2", "dt": 1.25e-3, "grid_factor": 3}),
        "grid 3, eps 1, ros34pw2 6.25e-4": Candidate(
            "implicit on a coarse grid", {"scheme": "ros34pw2", "dt": 6.25e-4, "grid_factor": 3}),
        "ros34pw2 6.25e-4": Candidate("implicit", {"scheme": "ros34pw2", "dt": 6.25e-4}),
        # round 5, session 2: the cheaper step (A rebuilt less often, f_t held with A)
        **_cheaper("6.25e-4", 6.25e-4, 10, True),
        **_cheaper("6.25e-4", 6.25e-4, 20, True),
        **_cheaper("6.25e-4", 6.25e-4, 10, False),
        **_cheaper("6.25e-4", 6.25e-4, None, True),
        "ros2 6.25e-4": Candidate("implicit", {"scheme": "ros2", "dt": 6.25e-4}),
        **_cheaper("8.33e-4", 0.025 / 30, 10, True),
        "eps [1.1, 1.2], ros34pw2 1.25e-3, A every 10, f_t held": Candidate(
            "implicit, Lagrange in ε", _implicit("ros34pw2", 1.25e-3, 10, True, [1.1, 1.2])),
        "eps [1.1, 1.2], ros34pw2 6.25e-4, A every 10, f_t held": Candidate(
            "implicit, Lagrange in ε", _implicit("ros34pw2", 6.25e-4, 10, True, [1.1, 1.2])),
    },
    "rod601_long": {
        "ros34pw2 1.25e-4": Candidate("implicit", {"scheme": "ros34pw2", "dt": 1.25e-4}),
        # round 5, fourth session: the G `parastokes plan` chose (0.3 of its pilot's safe step)
        "ros34pw2 2.14e-4 (plan's)": Candidate("implicit", {"scheme": "ros34pw2",
                                                            "dt": 0.025 / 117}),
        # G of an implicit, adaptive F (--implicit-fine: slices of 0.025 s, the full problem's)
        "ros34pw2 6.25e-4": Candidate("implicit", {"scheme": "ros34pw2", "dt": 6.25e-4}),
        "ros34pw2 1.25e-3": Candidate("implicit", {"scheme": "ros34pw2", "dt": 1.25e-3}),
        "ros34pw2 2.5e-4": Candidate("implicit", {"scheme": "ros34pw2", "dt": 2.5e-4}),
        "ros34pw2 3.125e-4": Candidate("implicit", {"scheme": "ros34pw2", "dt": 3.125e-4}),
        "ros34pw2 5e-4": Candidate("implicit", {"scheme": "ros34pw2", "dt": 5e-4}),
        "ros34pw2 rtol 1e-3": Candidate("implicit, adaptive",
                                        {"scheme": "ros34pw2", "dt": 1.25e-4, "rtol": 1e-3}),
        "ros34pw2 rtol 1e-2": Candidate("implicit, adaptive",
                                        {"scheme": "ros34pw2", "dt": 1.25e-4, "rtol": 1e-2}),
    },
    "quick": {
        "grid 3, eps [1.2, 1.4], euler 2.2e-5": Candidate(
            "coarse grid, Lagrange in ε", _grid(3, [1.2, 1.4], "euler", 2.2e-5)),
    },
    "table5": {
        "grid 3, eps [1.6, 1.8], euler 5e-5": Candidate(
            "coarse grid, Lagrange in ε", _grid(3, [1.6, 1.8], "euler", 5e-5)),
        "fine grid, eps [2, 2.2], euler 1.3e-4": Candidate(
            "fine grid, Lagrange in ε (wide)", _grid(1, [2.0, 2.2], "euler", 1.3e-4)),
        "fine grid, eps [2, 2.2, 2.4], euler 1.3e-4": Candidate(
            "fine grid, Lagrange in ε (wide)", _grid(1, [2.0, 2.2, 2.4], "euler", 1.3e-4)),
        "grid 3, eps 1.4, euler 3.8e-5": Candidate(
            "coarse grid, ε fixed", {"scheme": "euler", "dt": 3.8e-5, "grid_factor": 3}),
        "grid 2, eps 1.4, euler 3.8e-5": Candidate(
            "coarse grid, ε fixed", {"scheme": "euler", "dt": 3.8e-5, "grid_factor": 2}),
        "ros34pw2 2.5e-3": Candidate("implicit", {"scheme": "ros34pw2", "dt": 2.5e-3}),
        "ros34pw2 1.25e-3": Candidate("implicit", {"scheme": "ros34pw2", "dt": 1.25e-3}),
        **_cheaper("1.25e-3", 1.25e-3, 10, True),
        **_cheaper("2.5e-3", 2.5e-3, 10, True),
        "ros34pw2 6.25e-4": Candidate("implicit", {"scheme": "ros34pw2", "dt": 6.25e-4}),
        **_cheaper("6.25e-4", 6.25e-4, 10, True),
        **_cheaper("1.25e-3", 1.25e-3, 20, True),
        **_cheaper("1.25e-3", 1.25e-3, 10, False),
        **_cheaper("1.25e-3", 1.25e-3, None, True),
        "ros34pw2 1e-3": Candidate("implicit", {"scheme": "ros34pw2", "dt": 1e-3}),
    },
    "rod601": {
        "grid 2, eps [0.8, 1], euler 5e-6": Candidate(
            "coarse grid, Lagrange in ε", _grid(2, [0.8, 1.0], "euler", 5e-6)),
        "ros34pw2 2.5e-4": Candidate("implicit", {"scheme": "ros34pw2", "dt": 2.5e-4}),
        "ros34pw2 1.25e-4": Candidate("implicit", {"scheme": "ros34pw2", "dt": 1.25e-4}),
        "grid 2, eps 0.5, ros34pw2 2.5e-4": Candidate(
            "implicit on a coarse grid", {"scheme": "ros34pw2", "dt": 2.5e-4, "grid_factor": 2}),
        "ros2-krylov 1.25e-4": Candidate("implicit", {"scheme": "ros2-krylov", "dt": 1.25e-4}),
        "grid 2, eps 1, euler 1.16e-5": Candidate(
            "coarse grid, ε scaled", _grid(2, [1.0], "euler", 1.16e-5)),
    },
    "table7": {
        "mesh 2, eps 0.6 l_max, euler 0.008": Candidate(
            "coarse mesh, ε scaled", _grid(2, [0.6], "euler", 0.008, "l_max")),
        "mesh 2, eps [0.6, 0.8] l_max, euler 0.008": Candidate(
            "coarse mesh, Lagrange in ε", _grid(2, [0.6, 0.8], "euler", 0.008, "l_max")),
        "mesh 2, eps 0.3 l_max, euler 0.0028": Candidate(
            "coarse mesh, ε fixed", {"scheme": "euler", "dt": 0.0028, "grid_factor": 2}),
        "eps [0.5, 0.6] l_max, euler 0.01": Candidate(
            "fine mesh, Lagrange in ε (wide)", _grid(1, [0.5, 0.6], "euler", 0.01, "l_max")),
    },
}


# ---- the arithmetic of the frontier ------------------------------------------------------------

def iterations_to_reach(errors: Sequence[float] | None, target: float, own_error: float = 0.0
                        ) -> int | None:
    """The first K whose eta^K + F's own error is at most ``target`` (None: not within the run)."""
    for k, error in enumerate(errors or (), start=1):
        if error + own_error <= target:
            return k
    return None


def hopeless(errors: Sequence[float], target: float, max_iterations: int) -> bool:
    """Whether eta^k, contracting from now on at most at the rate of its last iteration, stays
    above ``target`` through ``max_iterations`` (a run can stop there: it will not reach it).
    Needs two iterations; a rate of 1 or more (stalled) is hopeless at once."""
    if len(errors) < 2 or errors[-1] <= target:
        return False
    rate = errors[-1] / errors[-2]
    left = max_iterations - len(errors)
    return rate >= 1.0 or errors[-1] * rate**left > target


def predicted_speedups(alpha: float, iterations: int, n_auxiliary: int = 1,
                       cores: int = CORES) -> dict[str, float]:
    """Speedups against F at P = ``cores`` slices on as many cores. ``standard``: Algorithm 1's
    closed formula (its coarse sweep runs the N_G auxiliary solves at once on idle cores, so alpha
    is the slowest one plus the combination). ``pipelined``: the pipelined closed formula for a
    plain G (N_G = 1); with N_G > 1 the pipelined schedule simulated with the auxiliary solves
    as tasks of their own (``pipelined_simulated``: they compete with the fine solves for the
    cores, which the closed formula, kept as ``pipelined_formula``, does not see)."""
    from parastokes import parareal

    simulated = cores / parareal.simulate("pipelined", cores, iterations, cores, alpha,
                                          n_auxiliary=n_auxiliary).wall
    formula = parareal.speedup_pipelined(alpha, iterations, cores)
    return {"standard": parareal.speedup_standard(alpha, iterations, cores),
            "pipelined": formula if n_auxiliary == 1 else simulated,
            "pipelined_formula": formula, "pipelined_simulated": simulated}


def best_serial(rows: Sequence[dict[str, Any]], target: float) -> dict[str, Any] | None:
    """The serial row of least CPU time per unit of simulated time whose error reaches
    ``target`` (None when none does)."""
    reaching = [r for r in rows if r.get("error") is not None and r["error"] <= target]
    return min(reaching, key=lambda r: r["cpu_per_time"], default=None)


def assess(entry: dict[str, Any], target: float, own_error: float, fine_cost: float,
           best_cost: float, cores: int = CORES) -> dict[str, Any] | None:
    """K and the speedups of a measured candidate: against F, and against the fastest serial run
    (times ``best_cost / fine_cost``, their CPU per unit of simulated time). None when the run did
    not reach the target."""
    k = iterations_to_reach(entry.get("errors"), target, own_error)
    if k is None:
        return None
    vs_f = predicted_speedups(entry["alpha"], k, entry.get("n_auxiliary", 1), cores)
    factor = best_cost / fine_cost
    return {"K": k, "vs_F": vs_f, "vs_best": {name: s * factor for name, s in vs_f.items()}}


def frontier(entries: dict[str, dict[str, Any]], target: float, own_error: float,
             fine_cost: float, best_cost: float, schedule: str = "pipelined"
             ) -> dict[str, dict[str, Any]]:
    """Per family, its best candidate by the ``schedule``'s speedup against the fastest serial run
    (families whose candidates all miss the target keep their smallest alpha, with K None)."""
    best: dict[str, dict[str, Any]] = {}
    for label, entry in entries.items():
        if "alpha" not in entry:
            continue
        verdict = assess(entry, target, own_error, fine_cost, best_cost)
        row = {"label": label, "alpha": entry["alpha"], "n_auxiliary": entry.get("n_auxiliary", 1),
               "K": None if verdict is None else verdict["K"], "assessment": verdict}
        score = -math.inf if verdict is None else verdict["vs_best"][schedule]
        held = best.get(entry["family"])
        held_score = (-math.inf if held is None or held["assessment"] is None
                      else held["assessment"]["vs_best"][schedule])
        if (held is None or score > held_score
                or (score == held_score == -math.inf and row["alpha"] < held["alpha"])):
            best[entry["family"]] = row
    return best


# ---- measurements ------------------------------------------------------------------------------

def _load(path: pathlib.Path) -> dict[str, Any]:
    return json.loads(path.read_text()) if path.exists() else {}


def _save(path: pathlib.Path, data: dict[str, Any]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=1) + "\n")
    tmp.replace(path)


def _cpu(function: Callable[[], Any]) -> tuple[Any, float]:
    start = time.process_time()
    value = function()
    return value, time.process_time() - start


def config_data(problem: Problem, coarse: dict[str, Any], *, t1: float | None = None,
                slices: int | None = None) -> dict[str, Any]:
    """The configuration (as TOML data) of a Parareal run of ``problem`` with G = ``coarse``: the
    analogue by default, the full problem with ``t1`` and ``slices``."""
    scheme, dt = problem.fine
    return {"title": f"{problem.title}: F = {scheme} at {dt:g}",
            "model": dict(problem.model), "time": {"t1": t1 or problem.t1},
            "fine": {"scheme": scheme, "dt": dt}, "coarse": coarse,
            "parareal": {"n_slices": slices or problem.slices, "tol": 0.0,
                         "max_iterations": problem.max_iterations},
            "execution": {"executor": "serial", "threads": 1}}


def build(problem: Problem, coarse: dict[str, Any]) -> Any:
    """The system, F and G of the analogue (``parastokes.config``'s own build)."""
    from parastokes import config

    cfg = config.parse(config_data(problem, coarse), "frontier")
    return config.build(cfg, config.resolve(cfg, "frontier"))


def _reference(problem: Problem, system: Any, x0: np.ndarray, t1: float, cache: pathlib.Path,
               record: dict[str, Any], save: Callable[[], None]) -> np.ndarray:
    """``problem.reference``'s state at ``t1`` from ``x0`` at 0, from the ``cache`` file, or run
    and kept there (its scheme, step and CPU time put in ``record["reference"]``, then
    ``save()``)."""
    from parastokes import integrate

    if not cache.exists():
        scheme, dt = problem.reference
        state, cpu = _cpu(lambda: integrate.propagate(system, x0, 0.0, t1, scheme, dt))
        np.save(cache, state)
        record["reference"] = {"scheme": scheme, "dt": dt, "cpu": cpu}
        save()
    return np.load(cache)


def measure_serial(name: str, problem: Problem, data: dict[str, Any], path: pathlib.Path
                   ) -> None:
    """The reference and each serial candidate over the analogue's interval (resumable)."""
    from parastokes import integrate
    from parastokes.parareal import relative_change

    setup = build(problem, {"scheme": "euler", "dt": problem.fine[1]})
    system, x0, t1 = setup.system, setup.system.initial_state(), problem.t1
    reference = _reference(problem, system, x0, t1, OUT / f".{name}_reference.npy", data,
                           lambda: _save(path, data))
    rows = data.setdefault("serial", [])
    done = {(r["scheme"], r["dt"]) for r in rows}
    for scheme, dt in problem.serial:
        if (scheme, dt) in done:
            continue
        try:
            state, cpu = _cpu(lambda s=scheme, h=dt: integrate.propagate(system, x0, 0.0, t1, s, h))
            error = relative_change(state, reference, system.positions)
        except integrate.BlowUpError as exc:
            rows.append({"scheme": scheme, "dt": dt, "error": None, "blowup": str(exc)[:200]})
        else:
            rows.append({"scheme": scheme, "dt": dt, "cpu": cpu, "cpu_per_time": cpu / t1,
                         "error": error})
        print(name, rows[-1], flush=True)
        _save(path, data)


def fine_solution(name: str, problem: Problem, setup: Any) -> np.ndarray:
    """F's serial solution at the slice ends of the analogue (cached beside the results)."""
    from parastokes import parareal

    cache = OUT / f".{name}_fine.npy"
    if not cache.exists():
        x0 = setup.system.initial_state()
        np.save(cache, parareal.serial_solution(setup.fine, x0, 0.0, problem.t1, problem.slices))
    return np.load(cache)


def measure_candidate(name: str, problem: Problem, candidate: Candidate, own_error: float
                      ) -> dict[str, Any]:
    """alpha (``measure_slice_costs``, CPU clock, 2 repeats) and eta^k of a Parareal run of the
    analogue, stopped at the first k whose eta^k + F's ``own_error`` reaches the target (or at
    ``problem.max_iterations``); a G that blows up or breaks its monitor is recorded as such."""
    from parastokes import integrate, parareal
    from parastokes.parallel import TaskError

    setup = build(problem, candidate.coarse)
    x0 = setup.system.initial_state()
    reference = fine_solution(name, problem, setup)
    entry: dict[str, Any] = {"family": candidate.family, "coarse": candidate.coarse}
    try:
        costs = parareal.measure_slice_costs(setup.fine, setup.coarse, 0.0, problem.slice_length,
                                             x0, repeats=2, clock=time.process_time)
        entry.update(alpha=costs.task_ratio(), n_auxiliary=costs.n_auxiliary,
                     gamma_F=float(np.median(costs.fine)), costs=costs.as_dict())
        errors, increments = [], []

        def report(it: Any) -> None:
            errors.append(it.error)
            increments.append(it.increment)
            if it.error + own_error <= problem.target:
                raise _Reached  # K is known: later iterations cannot change it
            if hopeless(errors, problem.target, problem.max_iterations):
                raise _Reached

        start = time.process_time()
        try:
            parareal.run(setup.fine, setup.coarse, x0, t0=0.0, t1=problem.t1,
                         n_slices=problem.slices, tol=0.0, max_iterations=problem.max_iterations,
                         reference=reference, on_iteration=report)
        except _Reached:
            pass
    except (integrate.BlowUpError, TaskError, FloatingPointError) as exc:
        entry.pop("alpha", None)
        entry["blowup"] = str(exc)[:300]
    else:
        entry.update(errors=errors, increments=increments, run_cpu=time.process_time() - start)
    return entry


class _Reached(Exception):
    """Raised by the iteration report once eta^k reaches the target."""


def measure(name: str, labels: Sequence[str] | None, redo: Sequence[str], tag: str = ""
            ) -> dict[str, Any]:
    """Measure ``name``'s serial runs and candidates (``labels``: only those) into
    ``OUT/NAME.json``, or ``OUT/NAME@TAG.json`` with a ``tag`` (a second process measuring other
    candidates of the same problem at once; :func:`load_problem` merges them)."""
    problem = PROBLEMS[name]
    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / (f"{name}@{tag}.json" if tag else f"{name}.json")
    data = _load(path)
    if tag:  # the serial runs are the main file's
        main = _load(OUT / f"{name}.json")
        data.update({k: main[k] for k in ("serial", "reference") if k in main})
    data["problem"] = {"title": problem.title, "model": problem.model, "fine": problem.fine,
                       "slice_length": problem.slice_length, "slices": problem.slices,
                       "t1": problem.t1, "target": problem.target, "full_t1": problem.full_t1,
                       "best": problem.best}
    measure_serial(name, problem, data, path)
    entries = data.setdefault("candidates", {})
    for label, candidate in CANDIDATES.get(name, {}).items():
        if (labels and label not in labels) or (label in entries and label not in redo):
            continue
        entries[label] = measure_candidate(name, problem, candidate, _fine_row(data)["error"])
        print(name, label, {k: v for k, v in entries[label].items() if k != "costs"}, flush=True)
        _save(path, data)
    return data


# ---- where a coarse slice's CPU goes --------------------------------------------------------

#: The pieces of a linearly implicit step that :func:`profile_slice` times, outermost first: a
#: call inside another timed one counts as the outer one's (the loads and advances of the
#: Jacobian's coloured differences count as the Jacobian, the rates of f_t as f_t).
PIECES = ("stage rates", "f_t", "jacobian", "factorization", "stage solves", "brackets",
          "advance")


class _PieceTimer:
    """CPU time (``time.process_time``) and calls per piece, of the outermost timed call only."""

    def __init__(self) -> None:
        self.seconds = dict.fromkeys(PIECES, 0.0)
        self.calls = dict.fromkeys(PIECES, 0)
        self._depth = 0

    def wrap(self, piece: str, function: Callable[..., Any]) -> Callable[..., Any]:
        def timed(*args: Any, **kw: Any) -> Any:
            if self._depth:
                return function(*args, **kw)
            self._depth += 1
            start = time.process_time()
            try:
                return function(*args, **kw)
            finally:
                self.seconds[piece] += time.process_time() - start
                self.calls[piece] += 1
                self._depth -= 1
        return timed


def profile_slice(name: str, label: str, repeats: int = 3, evaluations: int = 200
                  ) -> dict[str, Any]:
    """Where the CPU of one coarse slice of ``label`` (an implicit G) goes: the outermost CPU of
    each of :data:`PIECES` (``stepper``'s calls patched for the measurement), the rest of the slice
    (monitor, projection, Python), all per step and in rate evaluations at the initial state
    (``evaluations`` of them timed in the same process); the median slice of ``repeats``, each
    after an untimed fine slice (as a worker runs them: G's data evicted by F's)."""
    from unittest import mock

    from parastokes.stiff import solve, stepper

    problem = PROBLEMS[name]
    setup = build(problem, CANDIDATES[name][label].coarse)
    system, x0 = setup.system, setup.system.initial_state()
    kind = type(system)
    setup.coarse(0.0, problem.slice_length, x0)  # warm-up (compilation, caches)
    _, rate_cpu = _cpu(lambda: [system.rates(0.0, x0) for _ in range(evaluations)])
    rate = rate_cpu / evaluations
    runs = []
    for _ in range(repeats):
        setup.fine(0.0, problem.slice_length, x0)  # as in Parareal: G's caches cold after F's
        timer = _PieceTimer()
        patches = [mock.patch.object(kind, "rates", timer.wrap("stage rates", kind.rates)),
                   mock.patch.object(kind, "advance", timer.wrap("advance", kind.advance)),
                   mock.patch.object(stepper.Stepper, "_time_derivative",
                                     timer.wrap("f_t", stepper.Stepper._time_derivative)),
                   mock.patch.object(stepper, "local_jacobian",
                                     timer.wrap("jacobian", stepper.local_jacobian)),
                   mock.patch.object(solve.Factorization, "__init__",
                                     timer.wrap("factorization", solve.Factorization.__init__)),
                   mock.patch.object(solve.StageSolver, "solve",
                                     timer.wrap("stage solves", solve.StageSolver.solve))]
        if getattr(kind, "bracket", None) is not None:
            patches.append(mock.patch.object(kind, "bracket",
                                             staticmethod(timer.wrap("brackets", kind.bracket))))
        for patch in patches:
            patch.start()
        try:
            _, total = _cpu(lambda: setup.coarse(0.0, problem.slice_length, x0))
        finally:
            for patch in reversed(patches):
                patch.stop()
        runs.append((total, timer))
    total, timer = sorted(runs, key=lambda run: run[0])[len(runs) // 2]
    steps = round(problem.slice_length / CANDIDATES[name][label].coarse["dt"])
    rows = {piece: {"calls": timer.calls[piece], "seconds": timer.seconds[piece]}
            for piece in PIECES}
    rows["rest"] = {"calls": 0, "seconds": total - sum(timer.seconds.values())}
    for row in rows.values():
        row["evaluations_per_step"] = row["seconds"] / rate / steps
    return {"label": label, "steps": steps, "slice_cpu": total, "rate_evaluation": rate,
            "evaluations_per_step": total / rate / steps, "pieces": rows,
            "load_average": load_average()}


#: A label ending with this names its candidate with the linearly implicit schemes' banded LU
#: in float64 (``parastokes.stiff.solve.BAND_PRECISION``; float32 by default): a smooth G, not a
#: ``[coarse]`` option (docs/benchmarks.md, "Learned corrections").
DOUBLE_LU = ", float64 LU"


def split_variant(label: str) -> tuple[str, type | None]:
    """(the candidate's label in ``CANDIDATES``, the band LU's dtype to patch in or None) of a
    label that may end with :data:`DOUBLE_LU`."""
    if label.endswith(DOUBLE_LU):
        return label[: -len(DOUBLE_LU)], np.float64
    return label, None


@contextlib.contextmanager
def band_precision(dtype: type | None) -> Iterator[None]:
    """``parastokes.stiff.solve.BAND_PRECISION`` set to ``dtype`` inside, restored after (None:
    left as it is)."""
    from parastokes.stiff import solve

    saved = solve.BAND_PRECISION
    if dtype is not None:
        solve.BAND_PRECISION = dtype
    try:
        yield
    finally:
        solve.BAND_PRECISION = saved


def interleaved_alphas(name: str, labels: Sequence[str], rounds: int = 5) -> dict[str, Any]:
    """alpha of each candidate ``label`` measured in ``rounds`` interleaved rounds (each round
    one ``measure_slice_costs`` per candidate, F timed beside each G): the median ratio per
    candidate. Under a shared machine's changing load a candidate's alpha from its own
    frontier run moves by tens of percent; interleaved, the candidates see the same load. A
    label ending with :data:`DOUBLE_LU` is its candidate measured with the band LU in double."""
    from parastokes import parareal

    problem = PROBLEMS[name]
    variants = {label: split_variant(label) for label in labels}
    setups = {label: build(problem, CANDIDATES[name][base].coarse)
              for label, (base, _) in variants.items()}
    ratios: dict[str, list[float]] = {label: [] for label in labels}
    loads = [load_average()]
    for _ in range(rounds):
        for label, setup in setups.items():
            with band_precision(variants[label][1]):
                costs = parareal.measure_slice_costs(setup.fine, setup.coarse, 0.0,
                                                     problem.slice_length,
                                                     setup.system.initial_state(), repeats=1,
                                                     clock=time.process_time)
            ratios[label].append(costs.task_ratio())
        loads.append(load_average())
    return {label: {"ratios": r, "median": float(np.median(r)), "load_average": loads}
            for label, r in ratios.items()}


def run_key(scheme: str, dt: float, rtol: float | None) -> str:
    """A serial run's name in the JSON records: "SCHEME DT", or "SCHEME rtol R" if adaptive."""
    return f"{scheme} {dt:g}" if rtol is None else f"{scheme} rtol {rtol:g}"


def serial_run(system: Any, x0: np.ndarray, t1: float, scheme: str, dt: float,
               rtol: float | None) -> np.ndarray:
    """The state at ``t1`` of a serial run from ``x0`` at 0: fixed steps ``dt`` where ``rtol`` is
    None, else adaptive from a first step ``dt`` with atol = rtol / 10 (as the work-precision
    diagrams' runs, benchmarks/adaptive.py)."""
    from parastokes import integrate

    return integrate.propagate(system, x0, 0.0, t1, scheme, dt, rtol=rtol,
                               atol=None if rtol is None else rtol / 10)


def interleaved_serial(name: str, runs: Sequence[tuple[str, float, float | None]],
                       rounds: int = 5) -> dict[str, Any]:
    """CPU time of one slice (``slice_length`` from the initial state) of each serial run
    (scheme, dt, rtol: fixed steps where rtol is None, else adaptive from a first step dt with
    atol = rtol / 10) in ``rounds`` interleaved rounds after one untimed warm-up each, and each
    one's median ratio of CPU per slice to the first run's (the ratio of their CPU per unit
    time, for fixed steps), with the load average after each round."""

    problem = PROBLEMS[name]
    setup = build(problem, {"scheme": "euler", "dt": problem.fine[1]})
    system, x0 = setup.system, setup.system.initial_state()

    def one(scheme: str, dt: float, rtol: float | None) -> float:
        return _cpu(lambda: serial_run(system, x0, problem.slice_length, scheme, dt, rtol))[1]

    for run in runs:
        one(*run)
    seconds: dict[str, list[float]] = {run_key(*run): [] for run in runs}
    loads = [load_average()]
    for _ in range(rounds):
        for run, key in zip(runs, seconds, strict=True):
            seconds[key].append(one(*run))
        loads.append(load_average())
    first = seconds[next(iter(seconds))]
    return {key: {"cpu_per_slice": values,
                  "median_ratio": float(np.median(np.divide(values, first))),
                  "load_average": loads} for key, values in seconds.items()}


def full_serial(name: str, runs: Sequence[tuple[str, float, float | None]],
                t1: float | None = None) -> dict[str, Any]:
    """Serial runs (scheme, dt, rtol: None for fixed steps, else adaptive from a first step dt
    with atol = rtol / 10) over [0, ``t1``] (default the FULL problem's T): eq. 34 at t1 against
    ``problem.reference`` run over the same interval (cached in ``OUT/.NAME_reference_tT.npy``),
    over the positions (as the analogue's serial rows and ``plan``) and over the whole state (as
    eta^k), with each run's CPU time; written to ``OUT/NAME_full_serial.json`` under "T = t1"
    after each run."""
    from parastokes.parareal import relative_change

    problem = PROBLEMS[name]
    setup = build(problem, {"scheme": "euler", "dt": problem.fine[1]})
    system, x0 = setup.system, setup.system.initial_state()
    t1 = problem.full_t1 if t1 is None else t1
    path, cache = OUT / f"{name}_full_serial.json", OUT / f".{name}_reference_t{t1:g}.npy"
    data = _load(path)
    entry = data.setdefault(f"T = {t1:g}", {})
    reference = _reference(problem, system, x0, t1, cache, entry, lambda: _save(path, data))
    rows = entry.setdefault("runs", {})
    for scheme, dt, rtol in runs:
        state, cpu = _cpu(lambda s=scheme, h=dt, r=rtol: serial_run(system, x0, t1, s, h, r))
        key = run_key(scheme, dt, rtol)
        rows[key] = {"scheme": scheme, "dt": dt, "rtol": rtol, "cpu": cpu,
                     "error_positions": relative_change(state, reference, system.positions),
                     "error_state": relative_change(state, reference),
                     "load_average": load_average()}
        print(name, key, rows[key], flush=True)
        _save(path, data)
    return data


def next_checkpoint(done: dict[str, Any], checkpoints: Sequence[float]
                    ) -> tuple[float, float, float] | None:
    """Where a checkpointed run goes on: ``(t, first step, CPU so far)`` of the last of
    ``checkpoints`` recorded in ``done`` ("T" -> {"last_step", "cpu"}), ``(0, NaN, 0)`` where
    none is (the run's own first step then), None where the last checkpoint is recorded."""
    recorded = [t for t in checkpoints if f"{t:g}" in done]
    if len(recorded) == len(checkpoints):
        return None
    if not recorded:
        return 0.0, math.nan, 0.0
    last = done[f"{recorded[-1]:g}"]
    return recorded[-1], last["last_step"], last["cpu"]


#: The interval of F's run that times F's CPU per unit time in the process of a checkpointed run.
YARDSTICK = 1e-3


def checkpointed_serial(name: str, scheme: str, dt: float, rtol: float | None,
                        checkpoints: Sequence[float]) -> dict[str, Any]:
    """One serial run (fixed steps ``dt`` where ``rtol`` is None, else adaptive from a first step
    ``dt`` with atol = rtol / 10) over [0, max(checkpoints)] in segments ending at each
    checkpoint, each adaptive segment from the last step the one before it tried (a solver's
    output points: the steps are those of one run but for the cut to end on each checkpoint).
    Each checkpoint's state goes to ``OUT/.NAME_state_KEY_tT.npy`` and its cumulative CPU time,
    steps and last step to ``OUT/NAME_checkpoints.json`` under KEY, as it is reached: a rerun
    goes on from the last one (resumable; :func:`checkpoint_errors` compares the states). F's
    CPU over [0, YARDSTICK] is timed in the same process before it (under "yardsticks"): the
    run's CPU over F's per unit time (:func:`cost_over_fine`) without a clock across processes."""
    from parastokes import integrate

    problem = PROBLEMS[name]
    setup = build(problem, {"scheme": "euler", "dt": problem.fine[1]})
    system = setup.system
    key = run_key(scheme, dt, rtol)
    done = _load(OUT / f"{name}_checkpoints.json").get(key, {})
    start = next_checkpoint(done, checkpoints)
    if start is None:
        return done
    t, step, cpu = start
    step = dt if math.isnan(step) else step
    fine_scheme, fine_dt = problem.fine
    yardstick = _cpu(lambda: integrate.propagate(system, system.initial_state(), 0.0,
                                                 YARDSTICK, fine_scheme, fine_dt))[1]
    yardsticks = done.setdefault("yardsticks", [])
    yardsticks.append({"fine": f"{fine_scheme} {fine_dt:g}", "t1": YARDSTICK, "cpu": yardstick,
                       "from": t, "load_average": load_average()})
    x = (system.initial_state() if t == 0.0
         else np.load(OUT / f".{name}_state_{key.replace(' ', '_')}_t{t:g}.npy"))
    for t_next in (c for c in checkpoints if c > t):
        result, seconds = _cpu(lambda a=t, b=t_next, y=x, h=step: integrate.run(
            system, y, a, b, scheme, h, rtol=rtol, atol=None if rtol is None else rtol / 10))
        x, t, cpu = result.state, t_next, cpu + seconds
        step = result.dt if rtol is not None else dt
        np.save(OUT / f".{name}_state_{key.replace(' ', '_')}_t{t:g}.npy", x)
        done[f"{t:g}"] = {"cpu": cpu, "steps": result.n_steps, "rejected": result.n_rejected,
                          "last_step": step, "load_average": load_average()}
        print(name, key, t, done[f"{t:g}"], flush=True)
        _store(name, "checkpoints", key, done)   # (re-read: other runs write the file too)
    return done


def cost_over_fine(cpu: float, t1: float, yardstick_cpu: float,
                   yardstick_t1: float = YARDSTICK) -> float:
    """A serial run's CPU per unit time over F's: ``cpu`` over [0, ``t1``] against F's
    ``yardstick_cpu`` over [0, ``yardstick_t1``] (fixed steps: F's CPU grows with t)."""
    return (cpu / t1) / (yardstick_cpu / yardstick_t1)


def checkpoint_errors(name: str, reference: str) -> dict[str, Any]:
    """Eq. 34 at each checkpoint of each checkpointed run of ``OUT/NAME_checkpoints.json``
    against the run keyed ``reference`` there (its state at the same T), over the positions and
    over the whole state, and against ``problem.reference`` where its cache
    ``OUT/.NAME_reference_tT.npy`` (:func:`full_serial`) is there, with each run's CPU over F's
    per unit time (:func:`cost_over_fine`, the median of its yardsticks); written to
    ``OUT/NAME_checkpoint_errors.json``."""
    from parastokes.parareal import relative_change

    problem = PROBLEMS[name]
    positions = build(problem, {"scheme": "euler", "dt": problem.fine[1]}).system.positions
    runs = _load(OUT / f"{name}_checkpoints.json")

    def state(key: str, t: str) -> np.ndarray:
        return np.load(OUT / f".{name}_state_{key.replace(' ', '_')}_t{t}.npy")

    out: dict[str, Any] = {"reference": reference, "fine_reference": list(problem.reference)}
    for key, done in runs.items():
        sticks = [y["cpu"] for y in done.get("yardsticks", [])]
        rows = out.setdefault(key, {})
        for t, row in done.items():
            if t == "yardsticks":
                continue
            x = state(key, t)
            entry = {"cpu": row["cpu"], "cost_over_fine": cost_over_fine(
                row["cpu"], float(t), float(np.median(sticks))) if sticks else None}
            if key != reference and t in runs.get(reference, {}):
                ref = state(reference, t)
                entry["error_positions"] = relative_change(x, ref, positions)
                entry["error_state"] = relative_change(x, ref)
            fine_cache = OUT / f".{name}_reference_t{t}.npy"
            if fine_cache.exists():
                entry["error_positions_vs_fine_reference"] = relative_change(
                    x, np.load(fine_cache), positions)
            rows[t] = entry
    _save(OUT / f"{name}_checkpoint_errors.json", out)
    return out


def implicit_fine_config(problem: Problem, coarse: dict[str, Any], rtol: float,
                         slice_length: float, slices: int) -> dict[str, Any]:
    """``problem``'s configuration over ``slices`` slices of ``slice_length`` with G =
    ``coarse`` and an adaptive F: ``ros34pw2-krylov`` at ``rtol`` (atol rtol / 10, the serial
    runs' tolerances) from a first step of F's fixed step."""
    data = config_data(problem, coarse, t1=slice_length * slices, slices=slices)
    data["fine"] = {"scheme": "ros34pw2-krylov", "dt": problem.fine[1], "rtol": rtol,
                    "atol": rtol / 10}
    return data


def implicit_fine(name: str, labels: Sequence[str], rtol: float, slice_length: float,
                  slices: int, iterations: int, rounds: int = 2) -> dict[str, Any]:
    """Parareal with an implicit, adaptive F (:func:`implicit_fine_config`) and each G of
    ``labels`` (``CANDIDATES[name]``): eta^1..eta^``iterations`` against F's serial solution
    over ``slices`` slices of ``slice_length``, and alpha = gamma_G / gamma_F of whole slices
    (an adaptive F has no step count to scale by) in ``rounds`` interleaved rounds, over the
    first slice (F's start from its tiny first step) and over the second (from F's serial state);
    written to ``OUT/NAME_implicit_fine.json`` under "rtol R, P x L" (merged into the labels
    of an earlier run of the same F there)."""
    from parastokes import config, parareal
    from parastokes.parallel import TaskError

    problem = PROBLEMS[name]

    def setup(label: str) -> Any:
        cfg = config.parse(implicit_fine_config(problem, CANDIDATES[name][label].coarse, rtol,
                                                slice_length, slices), "frontier")
        return config.build(cfg, config.resolve(cfg, "frontier"))

    setups = {label: setup(label) for label in labels}
    first = next(iter(setups.values()))
    x0 = first.system.initial_state()
    reference, serial_cpu = _cpu(lambda: parareal.serial_solution(
        first.fine, x0, 0.0, slice_length * slices, slices))
    key = f"rtol {rtol:g}, {slices} x {slice_length:g}"
    result: dict[str, Any] = {"serial_cpu": serial_cpu, "labels": {}}
    for label, s in list(setups.items()):
        errors: list[float] = []
        try:
            parareal.run(s.fine, s.coarse, x0, t0=0.0, t1=slice_length * slices,
                         n_slices=slices, tol=0.0, max_iterations=iterations,
                         reference=reference, on_iteration=lambda it, e=errors: e.append(it.error))
        except TaskError as exc:   # (a G that breaks the rod: recorded, not timed)
            result["labels"][label] = {"blowup": str(exc)[:300]}
            del setups[label]
        else:
            result["labels"][label] = {"errors": errors, "alpha_first": [], "alpha_second": []}
        print(label, result["labels"][label], flush=True)
    loads = [load_average()]
    for _ in range(rounds):
        for label, s in setups.items():
            for piece, (t, x) in (("alpha_first", (0.0, x0)),
                                  ("alpha_second", (slice_length, reference[1]))):
                costs = parareal.measure_slice_costs(s.fine, s.coarse, t, t + slice_length, x,
                                                     repeats=1, fine_steps=None,
                                                     coarse_steps=None, clock=time.process_time)
                result["labels"][label][piece].append(costs.task_ratio())
        loads.append(load_average())
    result["load_average"] = loads
    earlier = _load(OUT / f"{name}_implicit_fine.json").get(key, {})   # (other G, same F)
    if earlier:
        result = {**earlier, "labels": {**earlier.get("labels", {}), **result["labels"]},
                  f"runs of {', '.join(labels)}": {k: result[k] for k in
                                                   ("serial_cpu", "load_average")}}
    _store(name, "implicit_fine", key, result)
    return result


# ---- tables -------------------------------------------------------------------------------------

def load_problem(name: str) -> dict[str, Any]:
    """``OUT/NAME.json`` with the candidates of every ``OUT/NAME@TAG.json`` merged in."""
    data = _load(OUT / f"{name}.json")
    for extra in sorted(OUT.glob(f"{name}@*.json")):
        data.setdefault("candidates", {}).update(_load(extra).get("candidates", {}))
    return data


def _fine_row(data: dict[str, Any]) -> dict[str, Any]:
    scheme, dt = data["problem"]["fine"]
    return next(r for r in data["serial"] if r["scheme"] == scheme and r["dt"] == dt)


def interleaved_cost_ratio(name: str, fine: dict[str, Any], best: dict[str, Any]
                           ) -> float | None:
    """The CPU of ``best`` over F's measured interleaved in one process
    (``OUT/NAME_serial_ratios.json``, :func:`interleaved_serial`: the last record whose first
    run is F and which has ``best``), None where none was."""
    def key(row: dict[str, Any]) -> str:
        return f"{row['scheme']} {row['dt']:g}"

    found = None
    for record in _load(OUT / f"{name}_serial_ratios.json").values():
        if next(iter(record), None) == key(fine) and key(best) in record:
            found = float(record[key(best)]["median_ratio"])
    return found


def summary(data: dict[str, Any]) -> dict[str, Any]:
    """F, the fastest serial run reaching the target, its CPU over F's (``cost_ratio``:
    measured interleaved where it was, :func:`interleaved_cost_ratio`, else the ratio of the
    analogue's rows) and the per-family frontier of a problem."""
    target = data["problem"]["target"]
    fine = _fine_row(data)
    name = next((n for n, p in PROBLEMS.items() if p.title == data["problem"]["title"]), None)
    named = None if name is None else PROBLEMS[name].best
    best = (next(r for r in data["serial"] if [r["scheme"], r["dt"]] == list(named)) if named
            else best_serial(data["serial"], target) or fine)
    ratio = (1.0 if best is fine else
             (name and interleaved_cost_ratio(name, fine, best))
             or best["cpu_per_time"] / fine["cpu_per_time"])
    return {"fine": fine, "best": best, "cost_ratio": ratio,
            "frontier": frontier(data.get("candidates", {}), target, fine["error"], 1.0, ratio)}


def _g(value: float | None, digits: int = 2) -> str:
    return "-" if value is None else f"{value:.{digits}g}"


def table(data: dict[str, Any]) -> str:
    """The markdown tables of a problem: serial runs, then every candidate with its K and
    speedups (standard / pipelined simulated, against F and against the fastest serial run)."""
    s = summary(data)
    p = data["problem"]
    lines = [f"{p['title']}, analogue: {p['slices']} slices of {p['slice_length']:g} s "
             f"(T = {p['t1']:g}), target η* = {p['target']:g}",
             "", "| serial run | step | error at T (eq. 34) | CPU (s) |", "|---|---|---|---|"]
    for r in data["serial"]:
        lines.append(f"| `{r['scheme']}` | {r['dt']:g} | {_g(r.get('error'))} | "
                     f"{_g(r.get('cpu'), 3)} |")
    lines += ["", "| G | family | N_G | α | η¹ .. η^K | K | vs F std / pipe | vs best std / pipe |",
              "|---|---|---|---|---|---|---|---|"]
    for label, e in data.get("candidates", {}).items():
        if "alpha" not in e:
            lines.append(f"| {label} | {e['family']} | | | blew up | | | |")
            continue
        v = assess(e, p["target"], s["fine"]["error"], 1.0, s["cost_ratio"])
        etas = " ".join(f"{x:.1e}" for x in e["errors"])
        if v is None:
            lines.append(f"| {label} | {e['family']} | {e['n_auxiliary']} | {e['alpha']:.3g} | "
                         f"{etas} | > {len(e['errors'])} | - | - |")
            continue
        f, b = v["vs_F"], v["vs_best"]
        lines.append(f"| {label} | {e['family']} | {e['n_auxiliary']} | {e['alpha']:.3g} | "
                     f"{etas} | {v['K']} | {f['standard']:.2f} / {f['pipelined']:.2f} "
                     f"| {b['standard']:.2f} / {b['pipelined']:.2f} |")
    return "\n".join(lines)


#: Coarse systems whose forward-Euler limit ``--limits`` measures: (grid factor, ε μm, bending).
ROD_LIMITS = ((1, 1.4, 1.0), (1, 2.0, 1.0), (1, 1.0, 0.5), (2, 1.5, 1.0), (2, 2.0, 1.0),
              (3, 2.0, 1.0), (3, 3.0, 1.0), (3, 3.0, 0.5), (5, 5.0, 1.0), (6, 6.0, 1.0))
#: (levels down, ε in the fine mesh's l_max) of the vesicle of Table 7.
VESICLE_LIMITS = ((0, 0.3), (0, 0.5), (0, 0.7), (1, 0.3), (1, 0.6), (2, 1.2))


def limits() -> dict[str, dict[str, float]]:
    """Forward Euler's largest stable step of each coarse system (rods over one beat, 3 %
    bisection; vesicles over 1 s, 5 %, area relative to its own change)."""
    from parastokes import integrate, models

    out: dict[str, dict[str, float]] = {"rod": {}, "vesicle": {}}
    rod = models.rod_swimmer(n_points=301, epsilon=1.0, n_threads=1)
    for factor, eps, bending in ROD_LIMITS:
        system = rod.coarsened(factor)[0] if factor > 1 else rod
        system = system.with_params(epsilon=eps, bending=bending)
        out["rod"][f"grid {factor}, eps {eps}, bending {bending}"] = (
            integrate.largest_stable_step(system, "euler", 0.05, 5e-6, 2e-3, rtol=0.03))
    ves = models.vesicle(subdivisions=3, n_threads=1)
    l_max = ves.epsilon / 0.3
    for down, eps in VESICLE_LIMITS:
        system = (ves.coarsened(2**down)[0] if down else ves).with_params(epsilon=eps * l_max)
        out["vesicle"][f"level {3 - down}, eps {eps} l_max"] = integrate.largest_stable_step(
            system, "euler", 1.0, 1e-3, 1.0, rtol=0.05, relative=True)
    return out


# ---- shipped configurations and real runs ----------------------------------------------------

SHIPPED = pathlib.Path("experiments/round5")


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {_toml_value(v)}" for k, v in value.items()) + " }"
    return repr(value)


def toml_text(data: dict[str, Any], comment: str = "") -> str:
    """TOML of a configuration: top-level scalars, then one table per dict (its dicts of dicts as
    sub-tables, deeper dicts inline)."""
    lines = [f"# {line}" for line in comment.splitlines()]
    lines += [f"{k} = {_toml_value(v)}" for k, v in data.items() if not isinstance(v, dict)]

    def table(name: str, body: dict[str, Any]) -> None:
        lines.extend(["", f"[{name}]"])
        lines.extend(f"{k} = {_toml_value(v)}" for k, v in body.items()
                     if not (isinstance(v, dict) and all(isinstance(x, dict) for x in v.values())
                             and v))
        for k, v in body.items():
            if isinstance(v, dict) and v and all(isinstance(x, dict) for x in v.values()):
                lines.extend(["", f"[{name}.{k}]"])
                lines.extend(f"{key} = {_toml_value(x)}" for key, x in v.items())

    for key, value in data.items():
        if isinstance(value, dict):
            table(key, value)
    return "\n".join(lines) + "\n"


def shipped_config(name: str, label: str, iterations: int) -> dict[str, Any]:
    """The full problem with the candidate ``label`` as G: P = 40 slices on 40 worker processes,
    the pipelined schedule, ``iterations`` iterations (the K its analogue needed)."""
    problem = PROBLEMS[name]
    data = config_data(problem, CANDIDATES[name][label].coarse, t1=problem.full_t1, slices=CORES)
    data["title"] = f"{problem.title}, round 5's best coarse solver: {label}"
    data["parareal"].update(max_iterations=iterations, schedule="pipelined")
    data["execution"] = {"executor": "processes", "workers": CORES, "threads": 1}
    data["run"] = {"mode": "both"}
    return data


def ship(name: str, label: str, iterations: int) -> pathlib.Path:
    """Write ``experiments/round5/NAME_best.toml`` (see :func:`shipped_config`)."""
    problem = PROBLEMS[name]
    path = SHIPPED / f"{name}_best.toml"
    path.parent.mkdir(parents=True, exist_ok=True)
    comment = (f"docs/benchmarks.md, \"Parareal against the fastest serial run (round "
               f"5)\": {problem.title}.\nF = {problem.fine[0]} at {problem.fine[1]:g} (the fastest "
               f"serial run, experiments/best_serial/); G = {label}; K = {iterations} (measured on "
               f"the shortened analogue,\nbenchmarks/frontier.py). Written by "
               f"`python benchmarks/frontier.py --ship {name} '{label}' {iterations}`.")
    path.write_text(toml_text(shipped_config(name, label, iterations), comment))
    return path


def _mean(tasks: Sequence[Sequence[Any]], kinds: set[str]) -> float:
    durations = [t[4] - t[3] for t in tasks if t[0] in kinds]
    return float(np.mean(durations))


def real_runs(name: str, label: str, iterations: int, slices: int = 4, workers: int = 2,
              repeats: int = 2) -> list[dict[str, Any]]:
    """``parastokes run`` of the analogue's first ``slices`` slices with G = ``label`` on
    ``workers`` worker processes, K = ``iterations``, each schedule ``repeats`` times (interleaved),
    and the wall time of its Parareal part against the simulated schedule fed with that run's
    measured gamma_F and auxiliary solve time (as benchmarks/pipeline.py's real runs)."""
    import subprocess
    import tempfile

    from parastokes import parareal

    problem = PROBLEMS[name]
    data = config_data(problem, CANDIDATES[name][label].coarse,
                       t1=slices * problem.slice_length, slices=slices)
    data["parareal"]["max_iterations"] = iterations
    data["execution"] = {"executor": "processes", "workers": workers, "threads": 1}
    data["run"] = {"mode": "parareal"}
    data["output"] = {"trajectory": False, "figures": False}
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for repeat in range(repeats):
            for schedule in ("standard", "pipelined"):
                data["parareal"]["schedule"] = schedule
                path = pathlib.Path(tmp) / f"{schedule}.toml"
                path.write_text(toml_text(data))
                out = pathlib.Path(tmp) / f"{schedule}_{repeat}"
                load = load_average()
                done = subprocess.run([sys.executable, "-m", "parastokes", "run", str(path),
                                       "--out", str(out), "--overwrite"], capture_output=True,
                                      text=True)
                if done.returncode:
                    raise RuntimeError(f"parastokes run exited {done.returncode}: "
                                       f"{done.stderr[-2000:]}")
                summary = json.loads((out / "summary.json").read_text())
                timings = parareal.Timings(**{k: v for k, v in summary["timings"].items()
                                              if k in parareal.Timings.__dataclass_fields__})
                gamma_f = timings.gamma_f
                n_aux = summary["config"]["resolved"]["n_auxiliary"]
                aux = timings.gamma_g if schedule == "standard" else _mean(
                    timings.tasks, {"auxiliary", "coarse"})
                sim = parareal.simulate(schedule, slices, iterations, workers, aux / gamma_f, 1.0,
                                        n_aux)
                rows.append({"schedule": schedule, "repeat": repeat, "wall": timings.total,
                             "gamma_F": gamma_f, "gamma_aux": aux, "n_auxiliary": n_aux,
                             "simulated_wall": sim.wall * gamma_f,
                             "wall_vs_simulation": timings.total / (sim.wall * gamma_f),
                             "load_average": [load, load_average()],
                             "errors": summary["errors"]})
                print(name, label, rows[-1], flush=True)
    return rows


def emulate(name: str, label: str, iterations: int, fine_s: float = 1.0) -> dict[str, Any]:
    """EMULATION, not a speedup of the physics: both schedules on 40 threads whose propagators
    sleep gamma_F = ``fine_s`` and alpha gamma_F (``label``'s measured alpha and N_G), P = 40
    (benchmarks/pipeline.py's ``emulation_case``)."""
    from benchmarks.pipeline import emulation_case

    entry = load_problem(name)["candidates"][label]
    return emulation_case(CORES, entry["alpha"], iterations, fine_s, entry["n_auxiliary"])


# ---- K at 40 slices: the analogue's K checked on the full slice count ---------------------------

#: Where ``--k40`` keeps its resumable state (F's serial solution, the Parareal checkpoint, the
#: iterates X_N^k); git ignores ``out/``.
K40_WORK = pathlib.Path("out/k40")


def k40_problem(name: str) -> Problem:
    """``name``'s analogue stretched to P = 40 slices of the same length (T = 40 x slice): Table
    4's rod over its full T = 1, ``rod601_long`` over T = 0.1."""
    problem = PROBLEMS[name]
    return Problem(problem.title, problem.model, problem.fine, problem.slice_length, CORES,
                   problem.target, problem.full_t1, problem.reference, problem.serial,
                   problem.max_iterations, problem.best)


def k40_reference(setup: Any, problem: Problem, work: pathlib.Path) -> np.ndarray:
    """F's serial solution at T_0..T_40 (``parareal.serial_solution``'s slices, bit for bit),
    saved after every slice so that a killed run continues from its last slice."""
    from parastokes import parareal

    times = parareal.time_points(0.0, problem.t1, problem.slices)
    path, log = work / "reference.npy", work / "reference.json"
    x0 = setup.system.initial_state()
    states = np.load(path) if path.exists() else np.full((problem.slices + 1, *x0.shape), np.nan)
    states[0] = x0
    progress = _load(log) or {"slices_done": 0, "cpu": 0.0}
    for n in range(progress["slices_done"] + 1, problem.slices + 1):
        states[n], cpu = _cpu(lambda n=n: setup.fine(times[n - 1], times[n], states[n - 1]))
        np.save(work / "reference.tmp.npy", states)
        (work / "reference.tmp.npy").replace(path)
        progress = {"slices_done": n, "cpu": progress["cpu"] + cpu}
        _save(log, progress)
    return states


def k40_parareal(setup: Any, problem: Problem, iterations: int, work: pathlib.Path,
                 identity: dict[str, Any], workers: int = 1) -> None:
    """Parareal over the 40 slices (tol 0, ``iterations`` iterations; the fine solves in this
    process, or on ``workers`` > 1 worker processes: the same iterates, bit for bit) with a
    checkpoint that a rerun resumes (one of another ``identity`` is refused); each iterate
    X_N^k at T is kept as ``iterate_K.npy``, its increment and the CPU time so far in
    ``iterates.json``."""
    from parastokes import parareal

    log = work / "iterates.json"
    record = _load(log)
    start = time.process_time() - record.get("cpu", 0.0)

    def keep(it: Any) -> None:
        np.save(work / f"iterate_{it.iteration}.npy", it.final_state)
        record.setdefault("increments", {})[str(it.iteration)] = it.increment
        record["cpu"] = time.process_time() - start
        _save(log, record)

    from parastokes.parallel import make_executor

    with make_executor("processes" if workers > 1 else "serial", workers) as pool:
        parareal.run(setup.fine, setup.coarse, setup.system.initial_state(), t0=0.0,
                     t1=problem.t1, n_slices=problem.slices, tol=0.0, max_iterations=iterations,
                     executor=pool, checkpoint=parareal.Checkpoint(work / "parareal.npz", identity),
                     on_iteration=keep)


def k40_errors(reference: np.ndarray, iterates: Sequence[np.ndarray]) -> list[float]:
    """eta^k = eq. 34's relative error at T of each iterate against F's serial solution (over the
    whole state, as ``measure_candidate``'s runs)."""
    from parastokes.parareal import relative_change

    return [relative_change(x, reference[-1]) for x in iterates]


def k40_summary(name: str, label: str, work: pathlib.Path) -> dict[str, Any]:
    """What is known so far: eta^k at 40 slices (once F's serial solution is complete), K, the
    analogue's eta^k and alpha, and the predicted speedups with the 40-slice K (alpha carries
    over: a ratio of costs per slice of the same length)."""
    problem = k40_problem(name)
    analogue = load_problem(name)
    entry = analogue["candidates"][label]
    done = summary(analogue)
    own = done["fine"]["error"]
    reference = _load(work / "reference.json")
    record = _load(work / "iterates.json")
    ks = sorted(int(k) for k in record.get("increments", {}))
    complete = reference.get("slices_done") == problem.slices
    errors = (k40_errors(np.load(work / "reference.npy"),
                         [np.load(work / f"iterate_{k}.npy") for k in ks]) if complete else None)
    measured = {"alpha": entry["alpha"], "n_auxiliary": entry.get("n_auxiliary", 1),
                "errors": errors}
    return {
        "problem": name, "label": label, "coarse": entry["coarse"],
        "slices": problem.slices, "slice_length": problem.slice_length, "t1": problem.t1,
        "fine": list(problem.fine), "target": problem.target, "fine_own_error": own,
        "analogue": {"slices": PROBLEMS[name].slices, "t1": PROBLEMS[name].t1,
                     "errors": entry["errors"],
                     "K": iterations_to_reach(entry["errors"], problem.target, own)},
        "alpha": entry["alpha"], "iterations": ks,
        "increments": [record["increments"][str(k)] for k in ks], "errors": errors,
        "K": iterations_to_reach(errors, problem.target, own),
        "speedups": None if errors is None else assess(
            measured, problem.target, own, 1.0, done["cost_ratio"]),
        "cpu": {"reference": reference.get("cpu"), "reference_slices": reference.get(
            "slices_done", 0), "parareal_main_process": record.get("cpu")},
        "load_average": load_average(),
    }


def k40(name: str, label: str, iterations: int, part: str = "all", workers: int = 1
        ) -> dict[str, Any]:
    """``--k40``: F's serial solution (``part`` "reference"), the Parareal run ("parareal") or
    both ("all") over 40 slices of ``name``'s slice length with G = ``label``, resumable (the
    fine solves of the iterations on ``workers`` processes where > 1); then
    ``OUT/k40_NAME.json`` from what is on disk (``part`` "summary": only that)."""
    problem = k40_problem(name)
    work = K40_WORK / name
    work.mkdir(parents=True, exist_ok=True)
    if part != "summary":
        setup = build(problem, CANDIDATES[name][label].coarse)
        if part in ("reference", "all"):
            k40_reference(setup, problem, work)
        if part in ("parareal", "all"):
            k40_parareal(setup, problem, iterations, work,
                         {"problem": name, "label": label, "fine": list(problem.fine)},
                         workers)
    result = k40_summary(name, label, work)
    _save(OUT / f"k40_{name}.json", result)
    return result


def _store(name: str, key: str, label: str, value: Any) -> None:
    """Into ``OUT/NAME_KEY.json`` under ``label`` (beside the candidates' file, which a
    measuring process rewrites whole)."""
    path = OUT / f"{name}_{key}.json"
    data = _load(path)
    data[label] = value
    _save(path, data)


def load_average() -> float:
    """The one-minute load average, NaN where /proc is not there."""
    try:
        return float(pathlib.Path("/proc/loadavg").read_text().split()[0])
    except OSError:
        return math.nan


def _runs(words: Sequence[str]) -> list[tuple[str, float | None, float | None]]:
    """(scheme, dt, rtol) from the words SCHEME DT SCHEME DT ... of the command line, where DT
    is a step (rtol None) or "rtol=R" (dt None: adaptive)."""
    if not words or len(words) % 2:
        raise SystemExit(f"expected SCHEME DT pairs, got {' '.join(words)!r}")
    out: list[tuple[str, float | None, float | None]] = []
    for scheme, step in zip(words[::2], words[1::2], strict=True):
        if step.startswith("rtol="):
            out.append((scheme, None, float(step.removeprefix("rtol="))))
        else:
            out.append((scheme, float(step), None))
    return out


def problem_step(name: str, dt: float | None) -> float:
    """``dt``, or where None (an adaptive run's first step) the problem's F step."""
    return PROBLEMS[name].fine[1] if dt is None else dt


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problems", nargs="+", default=list(PROBLEMS), choices=list(PROBLEMS))
    parser.add_argument("--only", nargs="+", help="measure only these candidate labels")
    parser.add_argument("--redo", nargs="+", default=[], help="measure these labels again")
    parser.add_argument("--table", action="store_true", help="print the tables, measure nothing")
    parser.add_argument("--tag", default="", help="measure into PROBLEM@TAG.json (a 2nd process)")
    parser.add_argument("--ship", nargs=3, metavar=("PROBLEM", "LABEL", "K"),
                        help="write experiments/round5/PROBLEM_best.toml: G = LABEL, K iterations")
    parser.add_argument("--real", nargs=3, metavar=("PROBLEM", "LABEL", "K"),
                        help="real runs of G = LABEL on 2 worker processes (parastokes run)")
    parser.add_argument("--emulate", nargs=3, metavar=("PROBLEM", "LABEL", "K"),
                        help="EMULATION at 40 threads with LABEL's measured alpha (sleeping "
                        "propagators, benchmarks/pipeline.py)")
    parser.add_argument("--profile", nargs=2, metavar=("PROBLEM", "LABEL"),
                        help="where one coarse slice of LABEL's CPU goes (PROBLEM_profile.json)")
    parser.add_argument("--alphas", nargs="+", metavar="PROBLEM ROUNDS LABEL",
                        help="alpha of these candidates in ROUNDS interleaved rounds "
                        "(PROBLEM_alphas.json)")
    parser.add_argument("--alphas-key", default="", metavar="PREFIX",
                        help="with --alphas: store each median under 'PREFIXLABEL' (keeps the "
                        "earlier measurements of LABEL)")
    parser.add_argument("--serial-ratios", nargs="+", metavar="PROBLEM ROUNDS SCHEME DT",
                        help="CPU per slice of these serial runs (SCHEME DT pairs) in ROUNDS "
                        "interleaved rounds, each over the first's (PROBLEM_serial_ratios.json)")
    parser.add_argument("--full-serial", nargs="+", metavar="PROBLEM SCHEME DT",
                        help="errors at the full T of these serial runs (SCHEME DT pairs; DT "
                        "rtol=R: adaptive) against the problem's reference over the same T "
                        "(PROBLEM_full_serial.json)")
    parser.add_argument("--serial-t1", type=float, default=None,
                        help="with --full-serial: over [0, T] instead of the full problem's T")
    parser.add_argument("--checkpointed", nargs=3, metavar=("PROBLEM", "SCHEME", "DT"),
                        help="one serial run (DT rtol=R: adaptive) with its state and CPU at "
                        "each of --checkpoints (resumable; PROBLEM_checkpoints.json)")
    parser.add_argument("--checkpoints", nargs="+", type=float,
                        default=[0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0],
                        help="with --checkpointed: the times its states are kept at")
    parser.add_argument("--checkpoint-errors", nargs=2, metavar=("PROBLEM", "REFERENCE"),
                        help="errors of the checkpointed runs against the one keyed REFERENCE "
                        "(e.g. 'ros34pw2-krylov rtol 1e-08'; PROBLEM_checkpoint_errors.json)")
    parser.add_argument("--implicit-fine", nargs="+",
                        metavar="PROBLEM RTOL SLICE_LENGTH SLICES K LABEL",
                        help="Parareal with F = adaptive ros34pw2-krylov at RTOL and G = each "
                        "LABEL: eta^1..eta^K and alpha (PROBLEM_implicit_fine.json)")
    parser.add_argument("--k40", nargs=3, metavar=("PROBLEM", "LABEL", "K"),
                        help="eta^1..eta^K of G = LABEL over 40 slices of PROBLEM's slice length "
                        "against F's serial solution (resumable; OUT/k40_PROBLEM.json)")
    parser.add_argument("--k40-part", choices=("all", "reference", "parareal", "summary"),
                        default="all", help="with --k40: only F's serial solution, only the "
                        "Parareal run (two processes at once), or only the summary")
    parser.add_argument("--k40-workers", type=int, default=1,
                        help="with --k40: worker processes for the fine solves (1: in-process)")
    parser.add_argument("--limits", action="store_true",
                        help="forward Euler's limits of the coarse systems (limits_measured.json)")
    args = parser.parse_args(argv)
    if args.limits:
        _save(OUT / "limits_measured.json", limits())
        return
    if args.alphas:
        name, rounds, *labels = args.alphas
        for label, value in interleaved_alphas(name, labels, int(rounds)).items():
            print(label, value, flush=True)
            _store(name, "alphas", args.alphas_key + label, value)
        return
    if args.full_serial:
        name, *pairs = args.full_serial
        full_serial(name, [(s, problem_step(name, h), rtol) for s, h, rtol in _runs(pairs)],
                    args.serial_t1)
        return
    if args.checkpointed:
        name, scheme, step = args.checkpointed
        [(_, h, rtol)] = _runs([scheme, step])
        checkpointed_serial(name, scheme, problem_step(name, h), rtol, sorted(args.checkpoints))
        return
    if args.checkpoint_errors:
        print(json.dumps(checkpoint_errors(*args.checkpoint_errors), indent=1))
        return
    if args.implicit_fine:
        name, rtol, length, slices, k, *labels = args.implicit_fine
        implicit_fine(name, labels, float(rtol), float(length), int(slices), int(k))
        return
    if args.serial_ratios:
        name, rounds, *pairs = args.serial_ratios
        result = interleaved_serial(
            name, [(s, problem_step(name, h), rtol) for s, h, rtol in _runs(pairs)], int(rounds))
        print(json.dumps(result, indent=1), flush=True)
        _store(name, "serial_ratios", args.alphas_key + " / ".join(result), result)
        return
    if args.profile:
        name, label = args.profile
        result = profile_slice(name, label)
        print(json.dumps(result, indent=1))
        _store(name, "profile", label, result)
        return
    if args.k40:
        name, label, k = args.k40
        print(json.dumps(k40(name, label, int(k), args.k40_part, args.k40_workers), indent=1))
        return
    if args.emulate:
        name, label, k = args.emulate
        _store(name, "emulation", label, emulate(name, label, int(k)))
        return
    if args.real:
        name, label, k = args.real
        _store(name, "real_runs", label, real_runs(name, label, int(k)))
        return
    if args.ship:
        print(ship(args.ship[0], args.ship[1], int(args.ship[2])))
        return
    for name in args.problems:
        if args.table:
            if (OUT / f"{name}.json").exists():
                print(table(load_problem(name)), "\n")
            continue
        measure(name, args.only, args.redo, args.tag)
        print(table(load_problem(name)), "\n", flush=True)


if __name__ == "__main__":
    sys.exit(main())
