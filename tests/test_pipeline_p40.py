"""``benchmarks/pipeline.py --sections p40``: eta^k read from the reproduction records (both
formats of validation.reproduce), the choice between full-scale records and the shortened
analogues, and the speedups fed to the figure. The measurement itself is not run (minutes)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from bench_modules import benchmark_module

from parastokes import parareal


@pytest.fixture(scope="module")
def bench():
    with benchmark_module("pipeline") as module:
        yield module


def result(name: str, errors: list, n_slices: int = 40) -> dict:
    """A finished run's summary as validation.reproduce.result_summary writes it (the keys read)."""
    return {"name": name, "errors": errors, "problem": {"parareal": {"n_slices": n_slices}}}


def progress(errors: list) -> dict:
    rows = [{"k": k, "increment": 1.0, "error": e} for k, e in enumerate(errors, start=1)]
    return {"phase": "parareal", "done": 0, "total": 4, "iterations": rows}


def write(path: Path, data) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data))
    return path


def test_records_of_both_formats_in_docs_and_runs_folders(bench, tmp_path):
    docs, runs = tmp_path / "docs", tmp_path / "runs"
    write(docs / "table7_g4.json", result("table7_g4", [4e-9, 1e-12, 2e-15, 3e-15]))
    write(docs / "fig12.json", {"not": "a record"})  # skipped in a folder
    write(runs / "table7_g4" / "progress.json", progress([4e-9]))  # loses to the finished run
    write(runs / "table7_g3" / "progress.json", progress([5.6e-9, 2e-12, None]))
    write(runs / "table7_g3" / "probe.json", {"gamma_F": 1.0})
    write(runs / "table8_g1" / "result.json", result("table8_g1", [3.5e-4, 5.5e-5]))
    write(runs / "table5_g1" / "result.json", result("table5_g1", [1e-3], n_slices=4))
    found = bench.read_errors([docs, runs])
    assert set(found) == {"table7_g4", "table7_g3", "table8_g1", "table5_g1"}
    assert found["table7_g4"].values == [4e-9, 1e-12, 2e-15, 3e-15]
    assert found["table7_g4"].source == bench.FULL
    assert found["table7_g4"].where == str(docs / "table7_g4.json")
    assert found["table7_g3"].values == [5.6e-9, 2e-12]  # up to the first missing one
    assert found["table7_g3"].source == bench.RUNNING
    assert found["table8_g1"].source == bench.FULL
    assert found["table5_g1"].source == "record with 4 slices"


def test_more_iterations_win_among_records_of_one_rank(bench, tmp_path):
    one = write(tmp_path / "a" / "table8_g3" / "progress.json", progress([1.2e-6]))
    two = write(tmp_path / "b" / "table8_g3" / "progress.json", progress([1.2e-6, 3e-8]))
    assert bench.read_errors([one, two])["table8_g3"].values == [1.2e-6, 3e-8]
    assert bench.read_errors([two, one])["table8_g3"].values == [1.2e-6, 3e-8]


def test_a_named_file_that_is_no_record_is_an_error(bench, tmp_path):
    bad = write(tmp_path / "costs.json", {"costs": {}})
    with pytest.raises(ValueError, match="not a reproduction record"):
        bench.read_errors([bad])
    with pytest.raises(ValueError, match="does not exist"):
        bench.read_errors([tmp_path / "missing.json"])


def test_full_scale_records_before_given_before_shortened_analogues(bench):
    records = {"table4_g1": bench.Errors([1e-9], bench.FULL, "x.json")}
    given = {"table4_g2": [1e-5, 1e-6]}
    chosen = bench.choose_errors(["table4_g1", "table4_g2", "table4_g3", "nothing"], records, given)
    assert chosen["table4_g1"].source == bench.FULL
    assert chosen["table4_g2"].source == bench.GIVEN and chosen["table4_g2"].values == [1e-5, 1e-6]
    assert chosen["table4_g3"].source == f"{bench.SHORT}, 4 slices over T = 0.004"
    assert chosen["table4_g3"].where == "experiments/quick/table4_g3.toml"
    assert chosen["table4_g3"].values == bench.ERRORS["table4_g3"]
    assert "nothing" not in chosen


def test_speedups_are_the_simulation_and_the_formulas_at_p40(bench):
    found = bench.speedups(0.05, 1, [1, 2])
    # plain solver, alpha = 0.05: the closed formulas by hand
    assert found["standard_formula"][1] == pytest.approx(1 / (3 * 0.05 + 2 / 40))
    assert found["pipelined_formula"][1] == pytest.approx(1 / ((1 + 2 / 40) * 0.05 + 2 / 40))
    assert found["pipelined"][0] == parareal.simulate("pipelined", 40, 1, 40, 0.05).speedup
    assert all(p >= s for p, s in zip(found["pipelined"], found["standard"], strict=True))
