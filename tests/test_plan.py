"""``parastokes plan`` and the fastest serial run as the baseline (docs/planning.md).

What is asserted: the baseline search measures families from cheap to dear and picks the
cheapest run reaching η* (synthetic measurements), F the cheapest fixed-step run reaching
η*/10; the stability intervals of the tableaux are their closed forms; every route's wall time
is its formula (eq. 14, the pipelined form, the spatial model); the cache is hit for the same
problem and target and missed when one parameter changes; ``predict --serial`` refuses runs of
another problem and files without a fingerprint; bad input exits 2 before any work; a real plan
writes PLAN.json with the fixed keys and a PLAN.toml that ``check`` and ``run`` accept, and the
run's report names the fastest serial run; the shipped best-serial configs pass ``check``.
"""

from __future__ import annotations

import json
import math
import tomllib
from argparse import Namespace
from pathlib import Path

import numpy as np
import pytest

from parastokes import cli, config, integrate
from parastokes.parareal.best_serial import best_known, cache_path, load_serial_runs
from parastokes.parareal.speedup import speedup as eq14_speedup
from parastokes.planning import baseline, routes
from parastokes.planning.baseline import Baseline, Run, choose_runs
from parastokes.planning.command import PlanError, prepare, resolvable

EXPERIMENTS = Path(__file__).resolve().parent.parent / "experiments"

#: A small rod (21 nodes, σ_f = 0.2) over a short time: a plan takes seconds.
CONFIG = """
title = "small rod for plan"
[model]
kind = "rod"
n_points = 21
length = 4.0
epsilon = 5.0
[time]
t1 = 0.002
[fine]
dt = 1e-6
[coarse]
dt_ratio = 10
[parareal]
n_slices = 2
[execution]
executor = "serial"
[output]
formats = ["png"]
[tune]
schemes = ["euler"]
parameters = ["epsilon"]
reach = [1]
nodes = [2]
step_fractions = [1.0]
"""


# ---- the search's decisions, on synthetic measurements ------------------------------------
def synthetic(table: dict[tuple, tuple[float, float]]):
    """A ``measure`` that reads (error, CPU) from ``table``; records what it measured."""
    measured = []

    def measure(run: Run, cap: float) -> None:
        error, cpu = table[run.scheme, run.dt]
        measured.append((run.scheme, run.dt))
        if cpu > cap:
            run.status, run.note = "abandoned", "dearer"
            return
        run.status, run.error, run.cpu_seconds = "measured", error, cpu

    return measure, measured


def test_the_search_picks_the_cheapest_run_reaching_the_target():
    runs = [Run("euler", 4.0, family="e"), Run("euler", 2.0, family="e"),
            Run("euler", 1.0, family="e"), Run("rk2", 4.0, family="r"),
            Run("rk2", 2.0, family="r"), Run("ros2", 8.0, family="i"),
            Run("ros2", 4.0, family="i")]
    table = {("euler", 4.0): (1e-3, 1.0), ("euler", 2.0): (5e-7, 2.0),
             ("euler", 1.0): (2e-7, 4.0), ("rk2", 4.0): (8e-8, 2.5),
             ("rk2", 2.0): (2e-8, 5.0), ("ros2", 8.0): (1e-9, 3.0),
             ("ros2", 4.0): (1e-10, 6.0)}
    measure, measured = synthetic(table)
    target = 1e-6
    assert choose_runs(runs, measure, target / baseline.F_FACTOR, lambda: False) is None
    # euler reaches η* at 2.0 but not η*/10: its family goes on to 1.0, dearer than rk2 at 4.0?
    # no: rk2 was not measured yet, so euler 1.0 is measured; rk2 at 4.0 reaches η*/10 and
    # stops its family; ros2 at 8.0 costs 3.0 > 2.5 and is abandoned, its finer step skipped
    assert measured == [("euler", 4.0), ("euler", 2.0), ("euler", 1.0), ("rk2", 4.0),
                        ("ros2", 8.0)]
    assert [r.status for r in runs] == ["measured", "measured", "measured", "measured",
                                        "skipped", "abandoned", "skipped"]
    found = Baseline("k", target, 0.0, 1.0, 1.0, Run("rk2", 0.5, None, "F", "reference", 0.0,
                                                     9.0, 9.0), 0.0, 4.0, runs, 10.0, 1.0)
    assert (found.best().scheme, found.best().dt) == ("euler", 2.0)  # 2.0 s < rk2's 2.5 s
    assert (found.fine().scheme, found.fine().dt) == ("rk2", 4.0)  # the cheapest <= η*/10
    assert found.best(1e-12) is found.reference  # nothing else reaches it: F itself
    # a family stops once a run of it is dearer than the cheapest reaching η*/10
    runs = [Run("rk2", 4.0, family="r"), Run("euler", 4.0, family="e"),
            Run("euler", 2.0, family="e")]
    table = {("rk2", 4.0): (1e-8, 1.5), ("euler", 4.0): (1e-3, 1.6), ("euler", 2.0): (1, 1)}
    measure, measured = synthetic(table)
    choose_runs(runs, measure, 1e-7, lambda: False)
    assert measured == [("rk2", 4.0), ("euler", 4.0)] and runs[1].status == "abandoned"
    # the budget and the candidate count stop the search
    runs = [Run("euler", 4.0, family="e"), Run("rk2", 4.0, family="r")]
    measure, measured = synthetic({("euler", 4.0): (1, 1), ("rk2", 4.0): (1, 1)})
    assert choose_runs(runs, measure, 1e-7, lambda: bool(measured)) == "budget"
    assert runs[1].status == "skipped" and "budget" in runs[1].note
    runs = [Run("euler", 4.0, family="e"), Run("rk2", 4.0, family="r")]
    measure, measured = synthetic({("euler", 4.0): (1, 1), ("rk2", 4.0): (1, 1)})
    assert choose_runs(runs, measure, 1e-7, lambda: False, most=1) == "candidates"


def test_fine_is_a_fixed_step_run_and_never_dearer_than_the_reference():
    reference = Run("rk2", 1e-6, None, "F", "reference", 1e-10, 10.0, 10.0)
    adaptive = Run("ros2", 1e-5, 1e-7, "a", "measured", 1e-9, 1.0, 1.0)
    fixed = Run("rk4", 1e-5, None, "f", "measured", 1e-8, 3.0, 3.0)
    found = Baseline("k", 1e-6, 0.0, 1.0, 1.0, reference, 1e-10, 1e-5, [adaptive, fixed],
                     10.0, 1.0)
    assert found.best() is adaptive and found.fine() is fixed
    fixed.cpu_seconds = 11.0
    assert found.fine() is reference


@pytest.mark.parametrize(("name", "interval"), [("euler", 2.0), ("rk2", 2.0),
                                                ("rk4", 2.785293563405)])
def test_stability_intervals_are_the_closed_forms(name, interval):
    # |1 - y| = 1; |1 - y + y²/2| = 1; the real root of 1 - y + y²/2 - y³/6 + y⁴/24 = 1 (2.7853)
    value = baseline.real_stability_interval(integrate.SCHEMES[name])
    assert value == pytest.approx(interval, abs=1e-6)
    assert baseline.real_stability_interval(integrate.SCHEMES["ros2"]) is None


def test_candidates_scale_the_limit_by_the_intervals_and_cover_every_family():
    runs = baseline.candidates(1e-5, 1e-6, span=1.0)
    by = {(r.scheme, r.dt, r.rtol) for r in runs}
    assert ("rk2", 9e-6, None) in by and ("euler", 9e-6, None) in by
    assert ("rk4", float(f"{0.9 * 1e-5 * 2.785293563405 / 2:.3g}"), None) in by
    assert ("ros2-krylov", 2e-4, None) in by  # 20 times Euler's limit
    assert ("ros2", 1e-5, 1e-6) in by and ("ros2", 1e-5, 1e-8) in by  # rtol = η*, η*/100
    for name in integrate.SCHEMES:  # every scheme of SCHEMES has a family
        assert any(r.scheme == name for r in runs), name
    # fixed steps keep MIN_STEPS steps over the measured span
    assert max(r.dt for r in baseline.candidates(1e-5, 1e-6, span=1e-3)) <= 1e-4


# ---- the routes' arithmetic -------------------------------------------------------------
def test_route_wall_times_are_their_formulas():
    # eq. 14 (eq. 12 with its P - k coarse calls): 40 / (0.5 * 3 * 78 * 0.1 + 2) = 2.9197
    assert routes.parareal_wall(100.0, 0.1, 2, 40, "standard") == pytest.approx(
        100.0 / (40 / (117 * 0.1 + 2)))
    assert routes.parareal_wall(100.0, 0.1, 2, 40, "standard") == pytest.approx(
        100.0 / eq14_speedup(0.1, 1.0, 2, 40))
    # pipelined: 1 / ((1 + K/P) α + K/P) = 1 / (0.105 + 0.05) = 6.4516 (anchors.md: 6.5)
    assert routes.parareal_wall(100.0, 0.1, 2, 40, "pipelined") == pytest.approx(100 * 0.155)
    with pytest.raises(ValueError, match="schedule"):
        routes.parareal_wall(1.0, 0.1, 1, 4, "other")
    # spatial: 1 / (0.1 + 0.9 / (0.95 n)), n at most points / 16
    assert routes.spatial_speedup(1, 301) == 1.0
    assert routes.spatial_speedup(2, 301) == pytest.approx(1 / (0.1 + 0.9 / 1.9))
    assert routes.spatial_speedup(8, 40) == routes.spatial_speedup(2, 301)  # 40 // 16 = 2
    assert routes.spatial_speedup(40, 15) == 1.0
    serial = routes.serial_route(60.0, "rk2")
    spatial = routes.spatial_route(60.0, "rk2", 4, 301)
    assert spatial.predicted_wall_seconds == pytest.approx(60.0 * (0.1 + 0.9 / 3.8))
    assert spatial.speedup_vs_best_serial == pytest.approx(60.0 / spatial.predicted_wall_seconds)
    assert serial.speedup_vs_best_serial == 1.0 and serial.predicted_wall_seconds == 60.0
    par = routes.parareal_route(60.0, 100.0, 0.1, 2, 40, "pipelined", "")
    assert par.speedup_vs_best_serial == pytest.approx(60.0 / 15.5)
    # combined: the split P x t with the least wall time; (α, K) asked for each P
    asked = []

    def at(slices: int):
        asked.append(slices)
        return (0.1, 1) if slices >= 4 else None

    both = routes.combined_route(60.0, 100.0, 8, 301, "pipelined", at, "")
    assert asked == [2, 3, 4]  # P = 2 (t = 4), 3 (t = 2), 4 (t = 2)
    assert both.settings == {"slices": 4, "threads": 2, "schedule": "pipelined",
                             "iterations": 1, "alpha": 0.1}
    s_sp = routes.spatial_speedup(2, 301)
    assert both.predicted_wall_seconds == pytest.approx(100.0 / s_sp * ((1 + 0.25) * 0.1
                                                                        + 0.25))
    assert routes.combined_route(60.0, 100.0, 3, 301, "pipelined", at, "") is None


# ---- the cache and the problem fingerprint ----------------------------------------------
def test_cache_is_hit_for_the_same_problem_and_missed_when_a_parameter_changes(tmp_path):
    source = tmp_path / "rod.toml"
    source.write_text(CONFIG)
    cfg, _ = config.load(source)
    key = config.problem_key(cfg)
    other = config.problem_key(config.load(source, ["model.bending=1.1"])[0])
    assert other != key
    assert config.problem_key(config.load(source, ["parareal.n_slices=4"])[0]) == key
    assert config.problem_key(config.load(source, ["fine.dt=2e-6"])[0]) != key
    reference = Run("rk2", 1e-6, None, "F", "reference", 0.0, 4.0, 8.0)
    fast = Run("rk2", 1e-5, None, "r", "measured", 1e-8, 0.5, 1.0)
    found = Baseline(key, 1e-6, 0.0, 0.002, 0.001, reference, 1e-10, 1e-5, [fast], 5.0, 2.0)
    cache = cache_path(source)
    assert cache == tmp_path / "rod.best_serial.json"
    baseline.store(cache, found)
    again = baseline.cached(cache, key, 1e-6)
    assert again is not None and again.as_dict() == found.as_dict()
    assert baseline.cached(cache, other, 1e-6) is None  # another parameter: a miss
    assert baseline.cached(cache, key, 1e-7) is None  # another target: a miss
    known = best_known(cache, key, 1e-6)
    assert known.row["dt"] == 1e-5 and known.fine_over == 8.0
    assert best_known(cache, other, 1e-6) is None


def test_predict_serial_refuses_another_problem_and_files_without_a_fingerprint(tmp_path,
                                                                                  capsys):
    source = tmp_path / "rod.toml"
    source.write_text(CONFIG)
    cfg, _ = config.load(source)
    case = {"t1": 0.002, "reference": {"scheme": "rk2", "dt": 1e-6, "cpu": 10.0},
            "rows": [{"scheme": "rk2", "dt": 4e-6, "error": 1e-7, "cpu": 2.5, "fine_cpu": 10.0}]}
    serial = tmp_path / "serial.json"
    base = ["predict", str(source), "--cores", "4", "--ratio", "0.05", "--iterations", "2",
            "--serial", str(serial), "--target", "1e-6"]
    serial.write_text(json.dumps({"cases": {"rod": case}}))  # no fingerprint
    assert cli.main(base) == cli.ExitCode.CONFIG
    assert "records no problem fingerprint" in capsys.readouterr().err
    other = config.problem_key(config.load(source, ["model.bending=1.1"])[0])
    serial.write_text(json.dumps({"cases": {"rod": {**case, "problem": other}}}))
    assert cli.main(base) == cli.ExitCode.CONFIG  # same F and T, another bending stiffness
    assert "was measured on another problem" in capsys.readouterr().err
    serial.write_text(json.dumps({"cases": {"rod": {**case,
                                                    "problem": config.problem_key(cfg)}}}))
    assert cli.main(base) == 0
    assert "rk2 at dt = 4e-06 (error 1e-07), 4x less CPU than F" in capsys.readouterr().out
    assert load_serial_runs(serial).problem == config.problem_key(cfg)


def test_committed_serial_runs_carry_the_fingerprints_of_their_configs():
    path = Path(__file__).resolve().parent.parent / "docs/figures/stiff/best_serial.json"
    cases = json.loads(path.read_text())["cases"]
    for name, case in cases.items():
        cfg, _ = config.load(Path(__file__).resolve().parent.parent / case["config"])
        load_serial_runs(path, name).check_problem(config.problem_key(cfg))


def test_predict_without_a_baseline_says_none_was_measured(tmp_path, capsys):
    source = tmp_path / "rod.toml"
    source.write_text(CONFIG)
    assert cli.main(["predict", str(source), "--cores", "4", "--ratio", "0.05",
                     "--iterations", "1"]) == 0
    out = capsys.readouterr().out
    assert "speedups against F (rk2 at dt = 1e-06)" in out
    assert "none measured for this problem" in out and "parastokes plan" in out


# ---- bad input ----------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("flags", "message"),
    [
        (["--cores", "2", "--target", "0"], "--target: the relative error η* must be"),
        (["--cores", "2", "--target=-1e-6"], "--target: the relative error η* must be"),
        (["--cores", "2", "--target", "inf"], "--target: the relative error η* must be"),
        (["--cores", "2", "--target", "nan"], "--target: the relative error η* must be"),
        (["--cores", "2", "--target", "1.5"], "--target: the relative error η* must be"),
        (["--cores", "0", "--target", "1e-6"], "--cores must be at least 1"),
        (["--cores", "2", "--target", "1e-6", "--budget", "0"],
         "--budget must be a positive number"),
        (["--cores", "2", "--target", "1e-6", "--set", 'execution.executor="gpu"'],
         'execution.executor = "gpu"'),
    ],
)
def test_bad_input_exits_2_before_any_work(tmp_path, capsys, monkeypatch, flags, message):
    # a GPU as if present, so that plan's own refusal of the gpu executor is what answers
    from parastokes.gpu import device

    monkeypatch.setattr(device, "missing", lambda: None)
    source = tmp_path / "rod.toml"
    source.write_text(CONFIG)
    code = cli.main(["plan", str(source), *flags, "--out", str(tmp_path / "PLAN.toml")])
    assert code == cli.ExitCode.CONFIG
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rod.toml"]  # nothing written


def test_a_missing_target_and_an_out_of_another_kind_exit_2(tmp_path, capsys):
    source = tmp_path / "rod.toml"
    source.write_text(CONFIG)
    with pytest.raises(SystemExit) as stop:
        cli.main(["plan", str(source), "--cores", "2", "--out", str(tmp_path / "P.toml")])
    assert stop.value.code == 2 and "--target" in capsys.readouterr().err
    assert cli.main(["plan", str(source), "--cores", "2", "--target", "1e-6", "--out",
                     str(tmp_path / "P.json")]) == cli.ExitCode.CONFIG
    assert "give a name ending in .toml" in capsys.readouterr().err


@pytest.mark.parametrize("path", sorted(EXPERIMENTS.rglob("*.toml")),
                         ids=lambda p: str(p.relative_to(EXPERIMENTS)))
def test_every_shipped_experiment_passes_plans_input_checks(path, tmp_path):
    """Every check plan makes before its work, on every shipped config, quick and full (the
    searches take seconds to minutes per config, so only the representative ones below run it
    whole; the full-scale plans are docs/planning.md's)."""
    args = Namespace(config=str(path), set=[], cores=4, target=1e-6, budget=None,
                     out=str(tmp_path / "PLAN.toml"), overwrite=False)
    cfg, _ = prepare(args)
    assert cfg.fine.dt > 0


# ---- a real plan --------------------------------------------------------------------------
def test_plan_writes_a_route_that_check_and_run_accept(tmp_path, capsys):
    source = tmp_path / "rod.toml"
    source.write_text(CONFIG)
    out = tmp_path / "PLAN.toml"
    target = 1e-6
    assert cli.main(["plan", str(source), "--cores", "2", "--target", f"{target:g}", "--out",
                     str(out), "--budget", "6"]) == 0
    printed = capsys.readouterr().out
    plan = json.loads(out.with_suffix(".json").read_text())
    best = plan["best_serial"]
    assert {"scheme", "dt", "rtol", "error", "cpu_seconds"} <= set(best)
    assert best["error"] <= target and best["cpu_seconds"] > 0
    assert best["complete"] == (plan["baseline"]["stopped"] is None)
    assert (best["warning"] is None) == best["complete"]
    assert (best["warning"] or "") in printed
    # the baseline is the cheapest measured run reaching η*
    rows = plan["baseline"]["rows"]
    reaching = [r for r in rows if r["error"] <= target]
    assert best["cpu_seconds"] == min(r["cpu_seconds"] for r in reaching)
    assert plan["fine"]["error"] <= target / baseline.F_FACTOR
    names = [r["route"] for r in plan["routes"]]
    assert names[:2] == ["serial", "spatial"]
    for route in plan["routes"]:
        assert set(route) >= {"route", "predicted_wall_seconds", "speedup_vs_best_serial",
                              "rests_on"}
        assert route["speedup_vs_best_serial"] == pytest.approx(
            best["cpu_seconds"] / route["predicted_wall_seconds"])
        assert route["rests_on"]
    assert plan["chosen"] == min(plan["routes"],
                                 key=lambda r: r["predicted_wall_seconds"])["route"]
    assert "measured now and cached in" in printed and plan["chosen"] in printed
    # the cache beside the configuration is reused the next time
    assert cli.main(["plan", str(source), "--cores", "1", "--target", f"{target:g}", "--out",
                     str(tmp_path / "ONE.toml"), "--budget", "6"]) == 0
    assert "cached in" in capsys.readouterr().out and "reused" in \
        json.loads((tmp_path / "ONE.json").read_text())["best_serial"]["source"]
    one = json.loads((tmp_path / "ONE.json").read_text())
    assert [r["route"] for r in one["routes"]] == ["serial"] and one["chosen"] == "serial"
    assert one["best_serial"]["cpu_seconds"] == best["cpu_seconds"]
    # PLAN.toml as written: check accepts it, and run runs it and names the baseline
    assert cli.main(["check", str(out), "-q"]) == 0
    planned = tomllib.loads(out.read_text())
    assert planned["fine"]["scheme"] in integrate.SCHEMES
    run_dir = tmp_path / "run"
    assert cli.main(["run", str(tmp_path / "ONE.toml"), "--out", str(run_dir), "-q",
                     "--set", "output.figures=false"]) == 0
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["speedup"] is None  # the serial route: the fastest serial run alone


def test_the_run_report_names_the_fastest_serial_run(tmp_path, capsys):
    source = tmp_path / "rod.toml"
    source.write_text(CONFIG.replace('[tune]', '[run]\nmode = "both"\n[tune]'))
    cfg, _ = config.load(source)
    reference = Run("rk2", 1e-6, None, "F", "reference", 0.0, 4.0, 8.0)
    fast = Run("rk2", 1e-5, None, "r", "measured", 0.0, 0.5, 2.0)  # reaches any η^K
    baseline.store(cache_path(source), Baseline(config.problem_key(cfg), 1e-6, 0.0, 0.002,
                                                0.002, reference, 0.0, 1e-5, [fast], 1, 1))
    assert cli.main(["run", str(source), "--out", str(tmp_path / "r"), "--set",
                     "output.figures=false", "--set", "output.trajectory=false"]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if "vs best serial" in x)
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())
    value = float(line.split()[3])
    assert value == pytest.approx(summary["speedup"]["measured"] / 4.0, abs=2e-3)  # F: 4x
    assert "rk2 at dt = 1e-05" in line


@pytest.mark.parametrize("path", sorted((EXPERIMENTS / "best_serial").glob("*.toml")),
                         ids=lambda p: p.stem)
def test_shipped_best_serial_configs_pass_check(path):
    assert cli.main(["check", str(path), "-q"]) == 0
    cfg, _ = config.load(path)
    assert cfg.run.mode == "serial" and cfg.execution.threads == 1
    assert not math.isnan(cfg.fine.dt)


def test_best_serial_folder_holds_one_config_per_problem_of_the_target_table(monkeypatch,
                                                                              tmp_path):
    from parastokes.gpu import device

    monkeypatch.setattr(device, "missing", lambda: None)  # plan's refusal, not check's
    names = sorted(p.stem for p in (EXPERIMENTS / "best_serial").glob("*.toml"))
    assert names == ["rod601", "table4_rod301", "table5_rod301_eps7", "table7_vesicle"]
    with pytest.raises(PlanError, match="gpu"):
        prepare(Namespace(config=str(EXPERIMENTS / "quick/table4_g1.toml"),
                          set=['execution.executor="gpu"'], cores=2, target=1e-6, budget=None,
                          out=str(tmp_path / "x.toml"), overwrite=True))


@pytest.mark.slow
@pytest.mark.parametrize("name", ["table4_g1", "table7_g1"])
def test_plan_runs_on_quick_experiments(name, tmp_path):
    """A whole plan on two shipped quick configs (a rod, a vesicle): about a minute each on the
    shared 2-core machine (loading the compiled loops and tune's pilot), so marked slow; the
    tiny rod above runs the same code in the default suite. The config is copied so that its
    cache is written beside the copy, not into experiments/."""
    text = (EXPERIMENTS / "quick" / f"{name}.toml").read_text()
    source = tmp_path / f"{name}.toml"
    source.write_text(text.replace(f'base = "../{name}.toml"',
                                   f'base = "{(EXPERIMENTS / name).with_suffix(".toml")}"'))
    out = tmp_path / "PLAN.toml"
    assert cli.main(["plan", str(source), "--cores", "2", "--target", "1e-6", "--out", str(out),
                     "--budget", "10", "-q"]) == 0
    plan = json.loads(out.with_suffix(".json").read_text())
    assert plan["best_serial"]["error"] <= 1e-6 and plan["routes"][0]["route"] == "serial"
    assert cli.main(["check", str(out), "-q"]) == 0


def test_a_target_the_reference_cannot_judge_is_refused():
    reference = Run("rk2", 1e-6, None, "F", "reference", 2e-9, 1.0, 1.0)
    found = Baseline("k", 1e-6, 0.0, 1.0, 1.0, reference, 0.9e-8, 1e-5, [], 1.0, 1.0)
    resolvable(found)  # η*/10 = 1e-7 is 11 times F's 0.9e-8
    found.fine_error = 1.1e-8  # 9 times: refused
    with pytest.raises(PlanError, match="reference's own error"):
        resolvable(found)
    found.fine_error = None  # F with adaptive steps: not estimated, not checked
    resolvable(found)


def test_own_error_falls_back_to_half_the_step_where_twice_it_blows_up(monkeypatch):
    from types import SimpleNamespace

    from parastokes.tuning import pilot

    state = np.array([1.0, 0.0, 0.0])
    answers = {2e-6: state + [0.0, 3e-6, 0.0], 5e-7: state + [0.0, 1e-6, 0.0]}

    def propagate(system, x0, t0, t1, scheme, dt):
        if dt not in answers:
            raise integrate.BlowUpError(t1, 1, math.inf, x0, "unstable")
        return answers[dt]

    monkeypatch.setattr(pilot.integrate, "propagate", propagate)
    system = SimpleNamespace(positions=lambda x: x.reshape(-1, 3))
    # RK2 (p = 2): |F_τ - F_2τ| / 3 = 1e-6
    assert pilot.own_error(system, state, 0.0, 1.0, "rk2", 1e-6, state) == pytest.approx(1e-6)
    del answers[2e-6]  # 2τ unstable: 4 |F_τ - F_τ/2| / 3
    assert pilot.own_error(system, state, 0.0, 1.0, "rk2", 1e-6, state) == pytest.approx(4e-6 / 3)


def test_a_parareal_route_is_written_as_a_config_that_runs(tmp_path):
    """The Parareal route's PLAN.toml (plan_config with tune's choice), as check and run read
    it: F, the coarse solver, slices, K, the schedule and the threads of the route."""

    from parastokes.planning.command import plan_config
    from parastokes.tuning import Settings
    from parastokes.tuning.report import toml_dumps

    source = tmp_path / "rod.toml"
    source.write_text(CONFIG)
    cfg, _ = config.load(source)
    fine = Run("rk2", 5e-6, None, "r", "measured", 1e-8, 1.0, 1.0)
    coarse = Settings("euler", lagrange=(("epsilon", (1.1, 1.2)),), dt=1e-5)
    route = routes.parareal_route(1.0, 1.0, 0.1, 1, 2, "pipelined", "")
    data = plan_config(cfg, route, fine, fine, coarse)
    path = tmp_path / "PLAN.toml"
    path.write_text(toml_dumps(data))
    planned, _ = config.load(path)
    assert (planned.fine.scheme, planned.fine.dt) == ("rk2", 5e-6)
    assert planned.parareal.n_slices == 2 and planned.parareal.max_iterations == 1
    assert planned.parareal.schedule == "pipelined" and planned.run.mode == "parareal"
    assert planned.coarse.dt == 1e-5 and planned.execution.threads == 1
    assert cli.main(["run", str(path), "--out", str(tmp_path / "run"), "-q", "--set",
                     "output.figures=false", "--set", "output.trajectory=false"]) == 0
    assert json.loads((tmp_path / "run" / "summary.json").read_text())["iterations"] == 1


@pytest.mark.parametrize("rtol", [None, 1e-5])
def test_tune_gets_f_with_the_chosen_runs_tolerance(tmp_path, monkeypatch, rtol):
    """An adaptive F chosen by the search reaches tune with its rtol (the same F the baseline
    measured), a fixed one without."""
    import parastokes.tuning as tuning
    from parastokes.planning import command

    source = tmp_path / "rod.toml"
    source.write_text(CONFIG)
    cfg, resolved = config.load(source)
    seen = {}

    def fake_tune(fine, **_):
        seen["scheme"], seen["rtol"] = fine.scheme, fine.rtol
        raise tuning.TuningError("stop here")

    monkeypatch.setattr(tuning, "tune", fake_tune)
    scheme = "rk2" if rtol is None else "rk23"
    result, why = command._tune(cfg, resolved, None, Run(scheme, 1e-6, rtol), 2, 1e-4, 1.0)
    assert result is None and why == "tune: stop here"
    assert seen == {"scheme": scheme, "rtol": rtol}


def test_candidates_go_rank_by_rank_across_families():
    """Every family's cheapest run comes before any family's second (a search cut by its
    budget has tried each family), each family still from cheap to dear."""
    runs = [Run("euler", 4.0, family="e"), Run("euler", 2.0, family="e"),
            Run("euler", 1.0, family="e"), Run("rk2", 4.0, family="r"),
            Run("rk2", 2.0, family="r"), Run("ros2", 8.0, family="i")]
    order = [(r.family, r.dt) for r in baseline.by_rank(runs)]
    assert order == [("e", 4.0), ("r", 4.0), ("i", 8.0), ("e", 2.0), ("r", 2.0), ("e", 1.0)]
    built = baseline.candidates(1e-3, 1e-6, 1.0)
    ranks = {}
    for run in built:
        ranks.setdefault(run.family, []).append(run)
    firsts = [rows[0] for rows in ranks.values()]
    assert built[:len(firsts)] == firsts


def test_a_search_cut_by_its_budget_says_so():
    from parastokes.planning.command import cut_short

    reference = Run("rk2", 1e-6, None, "F", "reference", 0.0, 4.0, 8.0)
    done = Baseline("k", 1e-6, 0.0, 1.0, 1.0, reference, 0.0, 1e-5, [], 10.0, 5.0)
    assert cut_short(done) is None
    left = [Run("rk4", 1e-5, None, "rk4 fixed", "skipped", note="search stopped (budget)"),
            Run("rk2", 5e-6, None, "rk2 fixed", "skipped", note="search stopped (budget)"),
            Run("rk2", 2e-6, None, "rk2 fixed", "skipped", note="a cheaper run reaches it")]
    cut = Baseline("k", 1e-6, 0.0, 1.0, 1.0, reference, 0.0, 1e-5, left, 10.0, 12.0, "budget")
    text = cut_short(cut)
    assert "stopped at its budget with 2 candidate(s) not measured (rk2 fixed, rk4 fixed)" in text
    assert "overstated" in text and "--budget" in text


def test_refinements_halve_f_until_it_can_judge_the_target():
    """F's step is halved until its own error, falling like the step to the order, lies
    RESOLUTION times below η*/F_FACTOR: goal 1e-10 for η* = 1e-8."""
    assert baseline.refinements(1e-10, 1e-8, 2) == 0  # there already
    assert baseline.refinements(1.01e-10, 1e-8, 2) == 1
    assert baseline.refinements(4e-10, 1e-8, 2) == 1  # one halving: / 4 at order 2
    assert baseline.refinements(4.1e-10, 1e-8, 2) == 2
    assert baseline.refinements(6.28e-9, 1e-8, 2) == 3  # / 64 needed, / 8 in the step
    assert baseline.refinements(1e-3, 1e-8, 1) == baseline.MOST_HALVINGS
    assert baseline.refinements(math.nan, 1e-8, 2) == 0  # (no estimate: nothing to refine)


def test_an_f_too_coarse_for_the_target_is_refined_into_the_reference(tmp_path):
    """A configuration whose F is itself near the target (as experiments/best_serial/'s are)
    is planned against F's scheme at a finer step, F becoming an ordinary measured row whose
    CPU time stays F's in the cache."""
    source = tmp_path / "rod.toml"
    source.write_text(CONFIG.replace("dt = 1e-6", "dt = 4e-6"))
    cfg, _ = config.load(source)
    system = cfg.model.build(1)
    fine = integrate.Propagator(system, "rk2", 4e-6)
    found = baseline.search(system, system.initial_state(), 0.0, cfg.time.t1, fine, 1e-8, "k",
                            budget=3.0)
    halvings = round(math.log2(4e-6 / found.reference.dt))
    assert found.reference.dt == 4e-6 / 2**halvings and halvings >= 1
    assert found.fine_error <= 1e-8 / (baseline.F_FACTOR * baseline.RESOLUTION)
    resolvable(found)  # the refined reference can judge it
    own = found.own
    assert own in found.runs and (own.scheme, own.dt, own.status) == ("rk2", 4e-6, "measured")
    assert 0.0 < own.error < 1e-6 and own.cpu_seconds > 0.0
    entry = found.as_dict()
    assert entry["fine"] == own.as_dict()  # best_known's F CPU is F's, not the reference's
    again = Baseline.from_dict(json.loads(json.dumps(entry)))
    assert again.own == own and again.reference == found.reference


def _found(runs):
    reference = Run("rk4", 5e-5, None, "F", "reference", 1e-9, 28.0, 28.0)
    return Baseline("k", 1e-6, 0.0, 1.0, 1.0, reference, 1e-9, 4e-5, runs, 10.0, 5.0)


def test_explicit_alpha_is_eulers_cpu_at_its_largest_measured_step_over_fs():
    from parastokes.planning.command import explicit_alpha

    runs = [Run("euler", 3.6e-5, None, "euler fixed", "measured", 7e-4, 10.0, 10.0),
            Run("euler", 1.8e-5, None, "euler fixed", "measured", 3e-4, 20.0, 20.0),
            Run("euler", 7.2e-5, None, "euler fixed", "blew up"),
            Run("rk2", 3.6e-5, None, "rk2 fixed", "measured", 9e-7, 20.0, 20.0)]
    found = _found(runs)
    assert explicit_alpha(found, found.reference) == pytest.approx(10.0 / 28.0)
    assert explicit_alpha(found, runs[3]) == pytest.approx(0.5)  # over the F given
    # no Euler run measured: F's step over Euler's limit (4e-5) over F's evaluations per step
    assert explicit_alpha(_found(runs[2:]), found.reference) == pytest.approx(5e-5 / 4e-5 / 4)
    assert explicit_alpha(_found(runs[2:]), runs[3]) == pytest.approx(3.6e-5 / 4e-5 / 2)
    unknown = _found(runs[2:])
    unknown.euler_limit = None
    assert explicit_alpha(unknown, found.reference) is None
    assert explicit_alpha(_found([]), Run("ros2", 1e-4, None, "F", "reference")) is None
    assert explicit_alpha(_found([]), Run("rk23", 1e-6, 1e-6, "F", "reference")) is None


@pytest.mark.parametrize(("euler_cpu", "added"), [(2.8, False), (2.81, True), (10.0, True)])
def test_plan_adds_the_implicit_coarse_scheme_where_euler_costs_more_than_a_tenth_of_f(
        tmp_path, euler_cpu, added):
    from parastokes.planning import command

    source = tmp_path / "rod.toml"
    source.write_text(CONFIG.replace('schemes = ["euler"]\n', ""))  # tune's default schemes
    cfg, _ = config.load(source)
    found = _found([Run("euler", 3.6e-5, None, "euler fixed", "measured", 7e-4, euler_cpu,
                        euler_cpu)])
    schemes, why = command.coarse_schemes(cfg, found, found.reference)
    if added:
        assert schemes == ("euler", "rk2", "ros34pw2") and "ros34pw2: forward Euler" in why
    else:
        assert schemes is None and why == "tune's default schemes"
    given = cfg.model_copy(update={"tune": cfg.tune.model_copy(update={"schemes": ["rk2"]})})
    assert command.coarse_schemes(given, found, found.reference) == (
        None, "the configuration's [tune] schemes")


def test_tune_searches_the_schemes_plan_gives_it(tmp_path, monkeypatch):
    import parastokes.tuning as tuning
    from parastokes.planning import command

    source = tmp_path / "rod.toml"
    source.write_text(CONFIG)
    cfg, resolved = config.load(source)
    seen = []

    def fake_tune(fine, *, space, **_):
        seen.append(space.schemes)
        raise tuning.TuningError("stop here")

    monkeypatch.setattr(tuning, "tune", fake_tune)
    fine = Run("rk2", 1e-6)
    command._tune(cfg, resolved, None, fine, 2, 1e-4, 1.0, ("euler", "ros34pw2"))
    command._tune(cfg, resolved, None, fine, 2, 1e-4, 1.0)
    assert seen == [("euler", "ros34pw2"), ("euler",)]  # then the config's [tune] schemes
