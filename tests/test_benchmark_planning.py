"""``benchmarks/planning.py``: the records of full-scale ``plan`` runs and their table."""

from __future__ import annotations

import json
import math
import sys

import pytest
from bench_modules import benchmark_module


@pytest.fixture(scope="module")
def planning():
    with benchmark_module("planning") as module:
        yield module


PLAN = {
    "best_serial": {"scheme": "rk4", "dt": 5.45e-5, "rtol": None, "error": 1e-9,
                    "cpu_seconds": 27.44},
    "fine": {"scheme": "rk4"},
    "routes": [
        {"route": "serial", "speedup_vs_best_serial": 1.0},
        {"route": "parareal", "speedup_vs_best_serial": 3.5},
        {"route": "spatial", "speedup_vs_best_serial": 6.55},
    ],
    "unavailable": {}, "chosen": "parareal", "baseline": {"stopped": "budget"}, "tune": None,
    "config": "ignored", "cores": 40,
}


def test_the_command_is_plans_with_every_setting(planning, tmp_path):
    argv = planning.command("a.toml", 40, 1e-5, 600.0, tmp_path / "P.toml")
    assert argv[1:] == ["-m", "parastokes", "plan", "a.toml", "--cores", "40", "--target",
                        "1e-05", "--out", str(tmp_path / "P.toml"), "--budget", "600", "-q"]
    assert argv[0] == sys.executable


def test_a_record_keeps_plans_keys_and_the_runs_facts(planning):
    argv = planning.command("a.toml", 40, 1e-6, 60.0, planning.WORK / "a" / "PLAN.toml")
    record = planning.record_of(argv, "a.toml", 1e-6, 40, 0, "", PLAN, 12.5, 30.0, (1.0, 2.0),
                                planning.commit())
    assert set(planning.PLAN_KEYS) <= set(record)
    assert "config" not in planning.PLAN_KEYS and record["config"] == "a.toml"
    assert record["command"].startswith("parastokes plan a.toml --cores 40")
    assert (record["cpu_seconds_children"], record["wall_seconds"]) == (12.5, 30.0)
    assert record["load_average"] == [1.0, 2.0] and "error" not in record
    assert len(record["commit"]) >= 7 and int(record["commit"], 16) >= 0


def test_child_cpu_is_user_plus_system_time_between_two_readings(planning):
    from types import SimpleNamespace as Usage

    assert planning.child_cpu(Usage(ru_utime=1.0, ru_stime=0.5),
                              Usage(ru_utime=4.0, ru_stime=1.25)) == 3.75


def test_a_refused_plan_keeps_its_last_error_line(planning):
    stderr = "searching ...\nparastokes: --target: η*/10 is not 10 times above F's error\n\n"
    record = planning.record_of(["py", "-m", "parastokes", "plan"], "a.toml", 1e-6, 40, 2,
                                stderr, None, 1.0, 1.0, (0.5, 0.5), "abc1234")
    assert record["error"] == "parastokes: --target: η*/10 is not 10 times above F's error"
    assert record["exit_status"] == 2 and "routes" not in record
    assert planning.last_error_line("") == ""


def test_the_chosen_route_is_the_row_named_by_chosen(planning):
    assert planning.chosen_route(PLAN)["speedup_vs_best_serial"] == 3.5
    assert planning.chosen_route({**PLAN, "chosen": "both"}) is None


def test_a_summary_row_gives_the_chosen_routes_speedup(planning):
    record = {**PLAN, "target": 1e-6, "exit_status": 0, "load_average": [1.25, 2.0]}
    row = planning.summary_row("table5", record)
    cells = [cell.strip() for cell in row.strip("|").split("|")]
    assert cells == ["table5", "1e-06", "0", "rk4 dt = 5.45e-05, 27.4 s", "parareal", "3.50",
                     "budget", "1.2-2.0"]
    refused = {"target": 1e-6, "exit_status": 2, "error": "no", "load_average": [1.0, 1.0]}
    assert "| 2 | no |" in planning.summary_row("x", refused)
    assert math.isnan(float(planning.summary_row(
        "y", {**record, "chosen": "both"}).split("|")[6]))


def test_existing_records_are_skipped_and_tabled(planning, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(planning, "RECORDS", tmp_path)
    (tmp_path / "a.json").write_text(json.dumps({**PLAN, "target": 1e-6, "exit_status": 0,
                                                 "load_average": [1.0, 1.0]}))
    monkeypatch.setattr(planning, "run_one", lambda *a: pytest.fail("a record was measured again"))
    assert planning.main(["a.toml"]) == 0
    assert "| a | 1e-06 | 0 | rk4" in capsys.readouterr().out
    (tmp_path / "table5_full.json").write_text((tmp_path / "a.json").read_text())
    assert planning.main(["--only", "table5_full"]) == 0
    assert "| table5_full |" in capsys.readouterr().out


def test_a_records_tune_report_lists_measured_candidates_and_counts_the_rest(planning):
    report = {"chosen": "x", "candidates": [
        {"scheme": "euler", "status": "accepted"}, {"scheme": "euler", "status": "pruned"},
        {"scheme": "ros34pw2", "status": "not reached"}, {"scheme": "ros34pw2",
                                                          "status": "rejected"},
        {"scheme": "euler", "status": "pruned"}]}
    kept = planning.measured_only(report)
    assert [c["status"] for c in kept["candidates"]] == ["accepted", "rejected"]
    assert kept["candidate_counts"] == {"euler accepted": 1, "euler pruned": 2,
                                        "ros34pw2 not reached": 1, "ros34pw2 rejected": 1}
    assert kept["chosen"] == "x" and planning.measured_only(None) is None
    record = planning.record_of(["py", "-m", "parastokes", "plan"], "a.toml", 1e-6, 40, 0, "",
                                {**PLAN, "tune": report}, 1.0, 1.0, (0.5, 0.5), "abc1234")
    assert len(record["tune"]["candidates"]) == 2


def test_a_tag_names_new_records_beside_the_earlier_ones(planning, tmp_path, monkeypatch,
                                                         capsys):
    monkeypatch.setattr(planning, "RECORDS", tmp_path)
    earlier = {**PLAN, "target": 1e-6, "exit_status": 0, "load_average": [1.0, 1.0]}
    (tmp_path / "rod601_full.json").write_text(json.dumps(earlier))
    measured = []

    def run_one(name, *_):
        measured.append(name)
        return {**earlier, "chosen": "spatial"}

    monkeypatch.setattr(planning, "run_one", run_one)
    assert planning.main(["--only", "rod601_full", "--tag", "plan4"]) == 0
    assert measured == ["rod601_full_plan4"]
    assert json.loads((tmp_path / "rod601_full.json").read_text())["chosen"] == "parareal"
    assert json.loads((tmp_path / "rod601_full_plan4.json").read_text())["chosen"] == "spatial"
    assert "| rod601_full_plan4 |" in capsys.readouterr().out
    assert planning.main(["--only", "rod601_full", "--tag", "plan4"]) == 0  # resumed: kept
    assert measured == ["rod601_full_plan4"]
    assert "coarse" in planning.PLAN_KEYS
