"""Adaptive coarse candidates in ``parastokes tune`` (docs/tuning.md, "Adaptive coarse
candidates"): the rtol ladder, the refusal boundary (Richardson needs fixed steps), the steps per
slice, a measured search on a 21-node rod, TUNED.toml with ``coarse.rtol`` accepted by ``check``
and ``run``, and ``plan`` writing an adaptive G."""

from __future__ import annotations

import json
import tomllib
from types import SimpleNamespace

import pytest
from test_tune import CONFIG, Spy, small_rod

from parastokes import cli, config, integrate, tuning
from parastokes.tuning import Settings, Space, TuningError
from parastokes.tuning.report import config_text, steps_cell, table
from parastokes.tuning.search import Candidate, steps_per_slice
from parastokes.tuning.space import COARSE_RTOLS, adaptive_only, settings_from_config, takes_rtol

THETA0 = {"epsilon": 1.0, "bending": 1.0}


def test_which_schemes_take_rtol_and_which_take_it_only():
    assert [s for s in ("euler", "rk2", "rk4", "lieuler") if takes_rtol(s)] == []
    assert all(takes_rtol(s) for s in ("rk23", "rk45", "ros2", "ros34pw2", "auto"))
    assert [s for s in ("rk23", "rk45", "ros2", "ros34pw2", "auto") if adaptive_only(s)] == [
        "rk23", "rk45", "auto"]


def test_the_rtol_ladder_gives_one_adaptive_candidate_per_rtol_without_richardson():
    space = Space(schemes=("euler", "rk45", "ros2", "auto"), parameters=("epsilon",), reach=(1,),
                  nodes=(2,), richardson=(0, 1), step_fractions=(1.0, 0.6),
                  coarse_rtols=(1e-2, 1e-3))
    space.check(THETA0, lambda factor: True)
    found = list(space.candidates(THETA0))
    by_scheme = {name: [c for c in found if c.scheme == name]
                 for name in ("euler", "rk45", "ros2", "auto")}
    # 2 structures (plain, ε) x 2 depths x 2 fractions fixed; 2 structures x 2 rtols adaptive
    assert [len(by_scheme[n]) for n in ("euler", "rk45", "ros2", "auto")] == [8, 4, 12, 4]
    adaptive = [c for c in found if c.adaptive]
    assert {(c.scheme, c.rtol) for c in adaptive} == {
        (s, r) for s in ("rk45", "ros2", "auto") for r in (1e-2, 1e-3)}
    assert all(c.m == 0 and c.step_fraction == 1.0 and c.atol is None for c in adaptive)
    assert not any(c.scheme in ("rk45", "auto") and not c.adaptive for c in found)
    assert len({c.label() for c in found}) == len(found)  # each labelled apart (rtol shown)
    # the default ladder: for the schemes that take adaptive steps only; a Rosenbrock scheme
    # gets adaptive candidates only from a ladder given (its fixed-step search as it was)
    default = Space(schemes=("rk23", "ros2"), parameters=(), richardson=(0,),
                    step_fractions=(1.0,))
    assert [(c.scheme, c.rtol) for c in default.candidates(THETA0)] == [
        *(("rk23", r) for r in COARSE_RTOLS), ("ros2", None)]


@pytest.mark.parametrize(
    ("space", "message"),
    [
        (Space(schemes=("rk45",), richardson=(1,)), "take adaptive steps only.*add 0"),
        (Space(schemes=("euler", "auto"), richardson=(1, 2)), r"\['auto'\] take adaptive"),
        (Space(schemes=("euler",), coarse_rtols=(1e-3,)), "none of the schemes"),
        (Space(schemes=("rk23",), coarse_rtols=()), "nothing to choose from in coarse_rtols"),
        (Space(schemes=("rk23",), coarse_rtols=(1.0,)), "must lie below 1"),
        (Space(schemes=("rk23",), coarse_rtols=(1e-20,)), "coarse rtol 1e-20: rtol"),
        (Space(schemes=("rk23",), coarse_rtols=(-1e-3,)), "finite number > 0"),
        (Space(schemes=("rk9",)), "unknown scheme 'rk9'"),
    ],
)
def test_what_adaptive_candidates_cannot_take_is_refused_before_any_work(space, message):
    spy = Spy()
    fine = integrate.Propagator(small_rod(), "rk2", 1e-6)
    with pytest.raises(TuningError, match=message):
        tuning.tune(fine, t0=0.0, t1=2e-3, n_slices=2, cores=2, target=1e-3, space=space,
                    progress=spy)
    assert not spy.started


def test_the_refusal_boundary_is_a_scheme_left_without_candidates():
    # a Rosenbrock scheme keeps its fixed-step candidates with m = 1: nothing to refuse
    Space(schemes=("ros2",), richardson=(1,)).check(THETA0, lambda factor: True)
    # an adaptive-only scheme with m = 0 among the depths: its candidates take m = 0
    Space(schemes=("rk45",), richardson=(1, 0)).check(THETA0, lambda factor: True)


def test_steps_per_slice_divide_by_calls_and_auxiliary_solvers():
    counts = {"accepted": 30, "rejected": 6, "switches": 3}
    assert steps_per_slice(counts, 3, 2) == {"accepted": 5.0, "rejected": 1.0, "switches": 0.5}
    assert steps_cell({"adaptive_steps": {"accepted": 12.4, "rejected": 2.6}, "dt": 1e-4},
                      1e-3) == "12/3"
    assert steps_cell({"adaptive_steps": None, "dt": 2.5e-4}, 1e-3) == "4"


def test_an_adaptive_candidate_builds_and_writes_its_tolerances():
    s = Settings("ros2", (("epsilon", (1.03, 1.06)),), dt=1e-5, rtol=1e-3, atol=1e-6)
    assert s.adaptive and "rtol 0.001 atol 1e-06" in s.label()
    assert s.coarse_table() == {"scheme": "ros2", "dt": 1e-5, "rtol": 1e-3, "atol": 1e-6,
                                "lagrange": {"epsilon": {"nodes": [1.03, 1.06],
                                                         "unit": "absolute"}}}
    assert Settings("rk23", dt=1e-5, rtol=1e-2).coarse_table() == {
        "scheme": "rk23", "dt": 1e-5, "rtol": 1e-2}
    g = s.build(small_rod())
    assert g.adaptive and g.auxiliary[0][0].rtol == 1e-3 and g.auxiliary[0][0].atol == 1e-6
    assert not Settings("ros2", dt=1e-5).build(small_rod()).adaptive


def _adaptive_search(**changes):
    fine = integrate.Propagator(small_rod(), "rk2", 1e-6)
    space = Space(schemes=("euler", "rk23"), parameters=(), richardson=(0,), step_fractions=(1.0,),
                  coarse_rtols=(1e-4,))
    options = dict(t0=0.0, t1=8e-3, n_slices=4, cores=4, target=1e-4, space=space,
                   exhaustive=True, budget=300.0) | changes
    return tuning.tune(fine, **options)


@pytest.fixture(scope="module")
def searched():
    return _adaptive_search()


def test_an_adaptive_candidate_is_measured_like_the_fixed_ones(searched):
    (row,) = [c for c in searched.report["candidates"] if c["scheme"] == "rk23"]
    assert row["rtol"] == 1e-4 and row["status"] == "accepted"
    # the screen's steps are those of the same solver run directly over the pilot's 2nd slice
    pilot = searched.pilot
    direct = integrate.run(pilot.system, pilot.reference[1], pilot.times[1], pilot.times[2],
                           "rk23", row["base_dt"], rtol=1e-4)
    assert row["screen"]["steps"] == {"accepted": direct.n_steps, "rejected": direct.n_rejected,
                                      "switches": 0}
    steps = row["adaptive_steps"]  # (their bookkeeping: the next test)
    assert steps["accepted"] > 0
    assert row["pilot"]["eta"] and row["predicted"]["gamma_ratio"] > 0
    assert row["stability"]["spectral_radius"] is not None  # ρ(DG) judged it
    assert row["stability"]["step_limit"] is None  # no step limit: its controller's steps
    text = table(searched.report, rows=20)
    line = next(li for li in text.splitlines() if "rk23, rtol 0.0001" in li)
    assert f"{steps['accepted']:.0f}/{steps['rejected']:.0f}" in line


def test_the_pilot_counts_are_the_screen_and_the_pilot_calls(monkeypatch):
    """The steps per slice average the screen's call and the pilot's own calls, not the calls of
    ρ(DG) (made between them on the same solver)."""
    from parastokes.tuning import pilot as pilot_module

    seen = []
    real = pilot_module.Pilot.measure

    def measure(self, coarse, iterations, known=None):
        seen.append(dict(zip(("accepted", "rejected", "switches"), coarse.step_counts,
                             strict=True)))
        run = real(self, coarse, iterations, known)
        seen.append((run.calls, list(coarse.step_counts)))
        return run

    monkeypatch.setattr(pilot_module.Pilot, "measure", measure)
    res = _adaptive_search()
    (row,) = [c for c in res.report["candidates"] if c["scheme"] == "rk23"]
    before, (calls, after) = seen[-2], seen[-1]
    assert before == {"accepted": 0, "rejected": 0, "switches": 0}  # ρ(DG)'s calls discarded
    # P = 3, K = 2: 3 + 2 + 1 coarse calls in sweeps 0, 1, 2; slice 2 of sweep 1 starts from
    # the reference state, the screen's call, reused
    assert calls == 5
    screen = row["screen"]["steps"]
    assert row["adaptive_steps"] == {key: (after[i] + screen[key]) / (calls + 1)
                                     for i, key in enumerate(("accepted", "rejected",
                                                              "switches"))}


def test_a_tuned_adaptive_coarse_solver_passes_check_and_runs(tmp_path):
    source = tmp_path / "rod.toml"
    source.write_text(CONFIG)
    cfg, _ = config.load(source)
    chosen = Candidate(Settings("ros2", dt=2e-5, rtol=1e-4), status="accepted", speedup=2.0,
                       iterations=2, gamma_ratio=0.1)
    result = SimpleNamespace(chosen=chosen, report={"problem": {"target": 1e-6},
                                                    "caution": None})
    dumped = {k: v for k, v in cfg.model_dump(mode="json", exclude_none=True).items()
              if k != "model"} | cfg.model.tables()
    out = tmp_path / "TUNED.toml"
    out.write_text(config_text(dumped, result, 4, str(source)))
    tuned = tomllib.loads(out.read_text())
    assert tuned["coarse"] == {"scheme": "ros2", "dt": 2e-5, "rtol": 1e-4}
    assert cli.main(["check", str(out), "-q"]) == 0
    other, resolved = config.load(out)
    assert settings_from_config(other, resolved) == replace_dt(chosen.settings, resolved)
    run_dir = tmp_path / "run"
    assert cli.main(["run", str(out), "--out", str(run_dir), "-q", "--set", "time.t1=0.0004",
                     "--set", "output.trajectory=false", "--set", "output.figures=false"]) == 0
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["timings"]["coarse_steps"][0]["accepted"] > 0


def replace_dt(settings, resolved):
    from dataclasses import replace

    return replace(settings, dt=resolved.coarse_base_dt)


def test_tune_command_refuses_adaptive_only_schemes_with_richardson_only(tmp_path, capsys):
    source = tmp_path / "rod.toml"
    source.write_text(CONFIG)
    out = tmp_path / "TUNED.toml"
    code = cli.main(["tune", str(source), "--cores", "4", "--target", "1e-6", "--out", str(out),
                     "-q", "--schemes", "auto", "--richardson", "1"])
    assert code == cli.ExitCode.CONFIG
    assert "add 0 to the Richardson depths" in capsys.readouterr().err
    assert not list(tmp_path.glob("TUNED*"))


def test_plan_writes_an_adaptive_coarse_solver_that_check_accepts(tmp_path):
    from parastokes.planning import routes
    from parastokes.planning.baseline import Run
    from parastokes.planning.command import plan_config
    from parastokes.tuning.report import toml_dumps

    source = tmp_path / "rod.toml"
    source.write_text(CONFIG)
    cfg, _ = config.load(source)
    route = routes.parareal_route(1.0, 2.0, 0.1, 1, 2, "standard", "tuned")
    fine = Run("rk2", 1e-6, None, "F", "reference", 0.0, 0.3, 0.6)
    data = plan_config(cfg, route, fine, fine, Settings("auto", dt=2e-5, rtol=1e-3))
    assert data["coarse"] == {"scheme": "auto", "dt": 2e-5, "rtol": 1e-3}
    out = tmp_path / "PLAN.toml"
    out.write_text(toml_dumps(data, "# plan"))
    assert cli.main(["check", str(out), "-q"]) == 0


@pytest.mark.slow
def test_plan_searches_adaptive_coarse_candidates(tmp_path):
    """``plan`` goes through tune: a [tune] table with an adaptive scheme and a ladder gives
    adaptive candidates measured in PLAN.json's tune record (slow: a real plan)."""
    source = tmp_path / "rod.toml"
    source.write_text(CONFIG.replace('schemes = ["euler"]',
                                     'schemes = ["euler", "ros2"]\ncoarse_rtols = [1e-3]'))
    out = tmp_path / "PLAN.toml"
    assert cli.main(["plan", str(source), "--cores", "2", "--target", "1e-5", "--out", str(out),
                     "--budget", "30"]) == 0
    plan = json.loads(out.with_suffix(".json").read_text())
    rows = [c for c in plan["tune"]["candidates"] if c["rtol"] == 1e-3]
    assert rows and all(c["scheme"] == "ros2" for c in rows)
    assert any(c["adaptive_steps"] for c in rows)
    assert cli.main(["check", str(out), "-q"]) == 0
