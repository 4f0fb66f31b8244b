"""The HODMD-Parareal numbers of docs/hodmd.md and docs/validation.md section 8, recomputed and
compared with ``docs/numbers.toml``.

- The authors' rod (``validation/hodmd_rod.py``, ``[hodmd_rod]``): its full-scale run (about an
  hour on two cores) is not a test; its command is the slow check, and by default the record it
  wrote (``docs/figures/hodmd_rod.json``) must hold the registered values. The scaled runs (61
  nodes, 10 slices) run under ``-m slow``, and by default their twin over 4 slices
  (``[hodmd_rod_twin]``) with the same solvers and HODMD settings.
- The comparison with parameter extrapolation (``validation/hodmd_compare.py``,
  ``[hodmd_compare]``): every rod case (quick Table 4 rod, a few seconds each) by default, the
  vesicle's (quick Table 7, minutes each) under ``-m slow``; the operation-count estimates
  gamma_G/gamma_F of every case by default.

The runs are in-process on the serial executor (``validation.quick_errors.iterates``): the
iterates of every executor and both schedules are the same bit for bit
(tests/test_parareal_tracing.py), so these are the eta^k that ``parastokes run`` records.
"""

from __future__ import annotations

import json

import pytest
from documented import ROOT, check, values

from parastokes import config, integrate, parallel
from validation import hodmd_compare, hodmd_rod, quick_errors

ITERATIONS = 3


def _rod(scaled: bool, initial: str, twin: bool = False) -> dict:
    overrides = hodmd_rod.run_overrides(scaled, initial, twin)
    return quick_errors.iterates(hodmd_rod.CONFIG, overrides, iterations=ITERATIONS)


def test_authors_rod_twin():
    run = _rod(True, "sweep", twin=True)
    check("hodmd_rod_twin", "errors", run["errors"])
    check("hodmd_rod_twin", "increments", run["increments"])


@pytest.mark.slow
@pytest.mark.parametrize("initial", ["sweep", "global"])
def test_authors_rod_scaled(initial):
    check("hodmd_rod", f"scaled_{initial}_errors", _rod(True, initial)["errors"])


def test_the_authors_rod_records_are_the_registered_values():
    """The full-scale run is ``python -m validation.hodmd_rod --initial sweep`` (about an hour):
    what it recorded, and what the scaled runs recorded, is what the pages print."""
    records = json.loads((ROOT / "docs" / "figures" / "hodmd_rod.json").read_text())
    for name in ("full_sweep", "scaled_sweep", "scaled_global"):
        check("hodmd_rod", f"{name}_errors", records[name]["errors"])
        check("hodmd_rod", f"{name}_gamma_estimate", records[name]["gamma_ratio_estimated"])
    check("hodmd_rod", "full_sweep_increments", records["full_sweep"]["increments"])


def test_authors_rod_gamma_estimates():
    """The family's operation-count estimate gamma_G/gamma_F at 50 cores (``parastokes
    predict``'s), full scale and scaled."""
    for scaled, name in ((False, "full_sweep"), (True, "scaled_sweep")):
        overrides = hodmd_rod.run_overrides(scaled, "sweep")
        cfg, resolved = config.load(ROOT / hodmd_rod.CONFIG, overrides)
        check("hodmd_rod", f"{name}_gamma_estimate", cfg.coarse.gamma_ratio(cfg, resolved, 50))


def _compare_case(problem: str, index: int) -> None:
    path, overrides = list(hodmd_compare.CASES[problem].values())[index]
    expected = [values("hodmd_compare")[f"{problem}_eta{k}"][index] for k in (1, 2, 3)]
    if expected[0] != expected[0]:  # NaN: the case blew up (docs/hodmd.md)
        with pytest.raises((integrate.BlowUpError, parallel.TaskError), match="blow-up"):
            quick_errors.iterates(path, [*hodmd_compare.COMMON, *overrides], iterations=ITERATIONS)
        return
    run = quick_errors.iterates(path, [*hodmd_compare.COMMON, *overrides], iterations=ITERATIONS)
    for k in (1, 2, 3):
        check("hodmd_compare", f"{problem}_eta{k}", run["errors"][k - 1], index)


@pytest.mark.parametrize("index", range(len(hodmd_compare.CASES["rod"])))
def test_compare_rod_case(index):
    _compare_case("rod", index)


@pytest.mark.slow
@pytest.mark.parametrize("index", range(len(hodmd_compare.CASES["vesicle"])))
def test_compare_vesicle_case(index):
    _compare_case("vesicle", index)


@pytest.mark.parametrize("problem", sorted(hodmd_compare.CASES))
def test_compare_gamma_estimates(problem):
    estimates = []
    for path, overrides in hodmd_compare.CASES[problem].values():
        cfg, resolved = config.load(ROOT / path, [*hodmd_compare.COMMON, *overrides])
        estimates.append(cfg.coarse.gamma_ratio(cfg, resolved, hodmd_compare.CORES))
    check("hodmd_compare", f"{problem}_gamma_estimate", estimates)
