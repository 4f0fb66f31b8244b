"""The eta^k of docs/benchmarks.md's "P = 40" comparison (``benchmarks/pipeline.py --sections
p40``) against where they come from.

The full-scale eta^k are runs of hours (``python -m validation.reproduce``): the page's table must
print what their committed records (``docs/reproduction/NAME.json``) hold, so the page cannot
drift from them. The shortened analogues' eta^k that the script falls back on (``ERRORS``, used
for a solver without a full-scale record) must be the quick runs' that the registry pins and
tests recompute (``[quick_eta_k]``, ``[quick_eta_k_slow]``, ``[hodmd_compare]``). The simulated
speedups of the table are model figures of measured gamma ratios (timings) and are not pinned.

The EMULATION table's model columns (closed formulas and the simulation with the nominal alpha,
``[pipeline_model]``) are recomputed; its emulated speedups and wall ratios are timings.
"""

from __future__ import annotations

import pytest
from bench_modules import benchmark_module
from documented import ROOT, check, printed_as, values


@pytest.fixture(scope="module")
def bench():
    with benchmark_module("pipeline") as module:
        yield module


def p40_rows() -> list[tuple[str, str, list[str]]]:
    """(solver, source, printed eta^k) of each row of the P = 40 speedup table."""
    lines = (ROOT / "docs" / "benchmarks.md").read_text().splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("### P = 40"))
    header = next(i for i in range(start, len(lines)) if "| η^k source |" in lines[i])
    rows = []
    for line in lines[header + 2 :]:
        if not line.startswith("|"):
            break
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        rows.append((cells[1].removesuffix(" (plain)"), cells[2], cells[3].split()))
    return rows


def test_the_p40_table_prints_the_full_scale_records(bench):
    records = bench.read_errors([ROOT / "docs" / "reproduction"])
    rows = p40_rows()
    assert len(rows) == sum(len(extra) + (plain is not None)
                            for plain, extra in bench.TABLES.values())
    for solver, source, printed in rows:
        record = records[solver]
        assert source == record.source == bench.FULL, solver
        shown = record.values[:4]  # the table's eta^1 .. eta^4
        assert len(printed) == len(shown), solver
        for text, value in zip(printed, shown, strict=True):
            assert printed_as(text, value), f"{solver}: prints {text}, record {value!r}"


# Which registered runs are the shortened analogues: [quick_eta_k] and [quick_eta_k_slow] by
# name; the rod of Table 4 and Table 7 G^2 are cases of validation.hodmd_compare (same configs,
# three iterations), by their index in its CASES.
COMPARE = {"table4_g1": ("rod", 0), "table4_g2": ("rod", 1), "table4_g3": ("rod", 2),
           "table4_g4": ("rod", 3), "table7_g1": ("vesicle", 0), "table7_g2": ("vesicle", 1)}


def _registered(name: str) -> list[float] | None:
    for group in ("quick_eta_k", "quick_eta_k_slow"):
        if name in values(group):
            return values(group)[name][:3]
    if name in COMPARE:
        problem, index = COMPARE[name]
        return [values("hodmd_compare")[f"{problem}_eta{k}"][index] for k in (1, 2, 3)]
    return None


def test_the_shortened_analogues_are_the_registered_quick_runs(bench):
    checked = 0
    for name, errors in bench.ERRORS.items():
        registered = _registered(name)
        if registered is None:  # table5_g2, table5_g3: not registered
            continue
        checked += 1
        for given, value in zip(errors, registered, strict=True):
            assert given == pytest.approx(value, rel=1e-4), name  # ERRORS: 5 digits
    assert checked == len(bench.ERRORS) - 2


def test_emulation_model_speedups(bench):
    rows = [bench.model_speedups(*case) for case in bench.emulation_grid(quick=False)]
    for schedule, short in (("standard", "std"), ("pipelined", "pipe")):
        for kind in ("formula", "simulated"):
            check("pipeline_model", f"{short}_{kind}", [r[schedule][kind] for r in rows])
