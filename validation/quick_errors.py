"""The first Parareal iterate of each quick variant (``experiments/quick/``), as a run computes it.

For a configuration (and optional ``--set`` overrides) this builds the system, F and G exactly as
``parastokes run`` does (:func:`parastokes.config.build.build`), runs the serial fine solution when
the run mode has one, and one Parareal iteration (eq. 34's eta^1 against the serial solution,
and the increment eta~^1), in this process on the serial executor: the iterates do not depend on
the executor (docs/parallel.md), so these are the eta^1 and eta~^1 that ``parastokes run`` writes
to ``summary.json`` for the same configuration. Serial-only configurations report the largest
monitor value (rod length / vesicle area change) of the serial solution instead.

The recorded values live in ``docs/numbers.toml`` (``[quick_eta1]``, ``[quick_eta1_twins]``, and
groups of their own for variants added later, e.g. ``[quick_eta1_scene_coarse]``;
see docs/validation.md); ``tests/test_numbers_quick_runs.py`` recomputes them. Usage (from the
repository root): ``python -m validation.quick_errors [--twins] [--sensitivity] [NAME ...]``
prints each configuration's ``[eta1, increment1, monitor]`` as the registry's TOML lines (every
quick variant, or with ``--twins`` every CI-sized twin, when no name is given).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from parastokes import config, parareal
from parastokes.config.build import build

ROOT = Path(__file__).resolve().parents[1]
QUICK = ROOT / "experiments" / "quick"

#: The quick variants that keep the paper's slice length T/N_c (docs/validation.md section 2).
PAPER_SLICES = frozenset(
    {"table5_g1", "table5_g2", "table7_g1", "table7_g2", "table8_g1", "table8_g2", "table8_g3"}
)
#: Quick variants too long for the default test run (tens of seconds each: those seven and the
#: scene): they are recomputed in full by a slow test, and in the default run by their CI-sized
#: twins below.
EXPENSIVE = ("scene_rod_passes_vesicle", *sorted(PAPER_SLICES))
#: The CI-sized twin of each expensive variant: the same configuration over two short slices (for
#: the seven, the former quick slices over which their coarse solver is not yet stable, so their
#: eta^1 is large; it is a fingerprint of the whole configuration, not an accuracy claim).
CI_TWINS: dict[str, tuple[str, ...]] = {
    "scene_rod_passes_vesicle": ("time.t1=0.0005", "parareal.n_slices=2"),
    "table5_g1": ("time.t1=0.005", "parareal.n_slices=2"),
    "table5_g2": ("time.t1=0.005", "parareal.n_slices=2"),
    "table7_g1": ("time.t1=0.25", "parareal.n_slices=2"),
    "table7_g2": ("time.t1=0.25", "parareal.n_slices=2"),
    "table8_g1": ("time.t1=0.5", "parareal.n_slices=2"),
    "table8_g2": ("time.t1=0.5", "parareal.n_slices=2"),
    "table8_g3": ("time.t1=0.5", "parareal.n_slices=2"),
}

#: The quick variants whose eta^2, eta^3 docs/validation.md section 2 quotes: their runs of
#: ``max_iterations`` = 3 iterations are slow tests, and their CI-sized twins below (three short
#: slices, two iterations: eta^2 is not yet exact, as it is on two slices) run by default.
ITERATED = ("table5_g1", "table7_g1", "table8_g1")
ITERATED_TWINS: dict[str, tuple[str, ...]] = {
    "table5_g1": ("time.t1=0.015", "parareal.n_slices=3"),
    "table7_g1": ("time.t1=1.5", "parareal.n_slices=3"),
    "table8_g1": ("time.t1=7.5", "parareal.n_slices=3", "fine.dt=0.01", "coarse.dt_ratio=7"),
}

#: Reference solutions already computed, by the fine problem they solve (shared by the coarse
#: solvers of one table).
_REFERENCES: dict[tuple, np.ndarray] = {}


def _fine_key(cfg, overrides: Sequence[str]) -> tuple:
    """What the serial fine solution depends on: model, fine solver, time span, slices."""
    return (repr(cfg.model), repr(cfg.fine), cfg.time.t0, cfg.time.t1, cfg.parareal.n_slices,
            cfg.execution.threads)


def first_iterate(
    name: str, overrides: Sequence[str] = (), perturb: float = 0.0
) -> dict[str, float]:
    """``{"eta1", "increment1", "monitor"}`` of ``experiments/quick/NAME.toml`` with ``overrides``.

    ``eta1`` is eq. 34 after one iteration (NaN in ``run.mode = "parareal"``, which has no serial
    solution), ``increment1`` eta~^1, ``monitor`` the largest monitor value over the states at
    T_1..T_N of the first iterate (of the serial solution in ``run.mode = "serial"``).
    ``perturb`` > 0 multiplies every initial position coordinate by 1 + perturb z (z standard
    normal, seed 0): with perturb = 1e-15, the change of the results is their sensitivity to
    round-off, which sets the registry's tolerances.
    """
    found = iterates(name, overrides, perturb, 1)
    return {"eta1": found["errors"][0], "increment1": found["increments"][0],
            "monitor": found["monitor"]}


def perturbed(x0: np.ndarray, perturb: float) -> np.ndarray:
    """``x0`` with every position coordinate (its first three columns) multiplied by
    1 + perturb z, z standard normal (seed 0); ``x0`` itself when ``perturb`` is 0."""
    if not perturb:
        return x0
    x0 = x0.copy()
    x0[:, :3] *= 1 + perturb * np.random.default_rng(0).standard_normal(x0[:, :3].shape)
    return x0


def config_path(name: str) -> Path:
    """``experiments/quick/NAME.toml``, or ``name`` itself (from the repository root) when it
    ends in ``.toml`` (any configuration, e.g. ``experiments/hodmd/authors_rod.toml``)."""
    return ROOT / name if name.endswith(".toml") else QUICK / f"{name}.toml"


def iterates(
    name: str, overrides: Sequence[str] = (), perturb: float = 0.0, iterations: int = 1
) -> dict[str, Any]:
    """``{"errors", "increments", "monitor"}`` after ``iterations`` Parareal iterations of the
    configuration ``name`` (as :func:`config_path` reads it) with ``overrides`` (``perturb`` as in
    :func:`first_iterate`).

    ``errors`` are eta^1..eta^K (eq. 34; NaN without a serial solution), ``increments``
    eta~^1..eta~^K, ``monitor`` the largest monitor value over the states at T_1..T_N of X^K (of
    the serial solution, with one NaN error and increment, in ``run.mode = "serial"``). With K =
    ``parareal.max_iterations`` and ``tol = 0`` of the configuration, these are the ``errors``
    and ``monitor["max"]`` that ``parastokes run`` writes to ``summary.json``.
    """
    cfg, resolved = config.load(config_path(name), list(overrides))
    setup = build(cfg, resolved)
    system = setup.system
    x0 = perturbed(system.initial_state(), perturb)
    p, mode = cfg.parareal, cfg.run.mode
    reference = None
    if mode in ("serial", "both"):
        key = (*_fine_key(cfg, overrides), perturb)
        if key not in _REFERENCES:
            _REFERENCES[key] = parareal.serial_solution(
                setup.fine, x0, cfg.time.t0, cfg.time.t1, p.n_slices
            )
        reference = _REFERENCES[key]
    if mode == "serial":
        assert reference is not None
        monitor = max(system.monitor(x) for x in reference)
        return {"errors": [float("nan")], "increments": [float("nan")], "monitor": monitor}
    result = parareal.run(
        setup.fine,
        setup.coarse,
        x0,
        cfg.time.t0,
        cfg.time.t1,
        p.n_slices,
        stopping=parareal.Stopping(tol=0.0, max_iterations=iterations),
        reference=reference,
        project=system.project,
        positions=system.positions,
        allow_oversubscribe=True,
        schedule=p.schedule,
    )
    errors = [float("nan")] * iterations if result.errors is None else result.errors
    return {
        "errors": [float(e) for e in errors],
        "increments": [float(e) for e in result.increments],
        "monitor": max(system.monitor(x) for x in result.states[1:]),
    }


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", help="quick variants (default: all)")
    parser.add_argument("--twins", action="store_true", help="the CI-sized twins (CI_TWINS)")
    parser.add_argument(
        "--iterations",
        type=int,
        default=1,
        help="K > 1: [eta^1..eta^K, largest monitor of X^K] of ITERATED (their twins: "
        "ITERATED_TWINS) instead of the first iterate",
    )
    parser.add_argument(
        "--sensitivity",
        action="store_true",
        help="also the relative change of each value when the initial positions are perturbed by "
        "1e-15 relative (round-off)",
    )
    args = parser.parse_args(argv)
    if args.iterations < 1:
        parser.error(f"--iterations must be at least 1, not {args.iterations}")
    twins = CI_TWINS if args.iterations == 1 else ITERATED_TWINS
    everything = sorted(p.stem for p in QUICK.glob("*.toml")) if args.iterations == 1 else ITERATED
    names = args.names or (sorted(twins) if args.twins else list(everything))
    for name in names:
        start = time.perf_counter()
        overrides = twins[name] if args.twins else ()
        values = _row(name, overrides, 0.0, args.iterations)
        row = ", ".join(repr(v) for v in values)
        note = f"{time.perf_counter() - start:.1f} s"
        if args.sensitivity:
            moved = _row(name, overrides, 1e-15, args.iterations)
            changes = [abs(m / v - 1) if v else abs(m)
                       for m, v in zip(moved, values, strict=True)]  # (absolute where v is 0)
            note += "; round-off sensitivity " + " ".join(f"{c:.1e}" for c in changes)
        print(f"{name} = [{row}]  # {note}", flush=True)


def _row(name: str, overrides: Sequence[str], perturb: float, iterations: int) -> list[float]:
    """The registry's row: [eta^1, eta~^1, monitor of X^1] for one iteration, else
    [eta^1..eta^K, monitor of X^K]."""
    if iterations == 1:
        found = first_iterate(name, overrides, perturb)
        return [found["eta1"], found["increment1"], found["monitor"]]
    run = iterates(name, overrides, perturb, iterations)
    return [*run["errors"], run["monitor"]]


if __name__ == "__main__":
    main()
