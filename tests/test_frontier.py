"""The arithmetic of benchmarks/frontier.py: the iteration count K that reaches a target, the
speedups at P = 40 (closed formulas), against F and against the fastest serial run, and the
frontier's pick per family. Pure functions: no physics is run."""

from __future__ import annotations

import numpy as np
import pytest
from bench_modules import ROOT, benchmark_module


@pytest.fixture(scope="module")
def frontier():
    with benchmark_module("frontier") as module:
        yield module


def test_iterations_to_reach_counts_f_own_error_and_equality(frontier):
    errors = [8.0, 2.0, 0.25, 2.0**-10]            # (binary fractions: the sums are exact)
    assert frontier.iterations_to_reach(errors, 1.0) == 3
    assert frontier.iterations_to_reach(errors, 1.0, own_error=0.75) == 3   # 0.25 + 0.75 = 1
    assert frontier.iterations_to_reach(errors, 1.0, own_error=0.875) == 4
    assert frontier.iterations_to_reach(errors, 2.0**-11) is None
    assert frontier.iterations_to_reach(None, 1.0) is None


def test_predicted_speedups_closed_formulas(frontier):
    s = frontier.predicted_speedups(0.1, 2, cores=40)
    assert s["standard"] == pytest.approx(1 / (3 * 0.1 + 2 / 40))           # 2.857
    assert s["pipelined"] == pytest.approx(1 / ((1 + 2 / 40) * 0.1 + 2 / 40))  # 6.452
    # the event-based schedule is at least as fast as the closed pipeline, and not faster than
    # its critical path K gamma_F + (P - K) gamma_G
    assert s["pipelined"] <= s["pipelined_simulated"] <= 40 / (2 + 38 * 0.1) + 1e-12


def test_pipelined_with_many_auxiliary_solves_is_the_simulated_schedule(frontier):
    """36 auxiliary solves per coarse step compete with the fine solves for 40 cores: the
    closed formula (one coarse task) overstates the pipeline, so N_G > 1 takes the simulation."""
    s = frontier.predicted_speedups(0.105, 4, n_auxiliary=36)
    assert s["pipelined_formula"] == pytest.approx(1 / (1.1 * 0.105 + 0.1))   # 4.63
    assert s["pipelined"] == s["pipelined_simulated"] < 0.5 * s["pipelined_formula"]


def test_best_serial_is_the_cheapest_reaching_the_target(frontier):
    rows = [{"scheme": "euler", "error": 2e-4, "cpu_per_time": 1.0},
            {"scheme": "rk2", "error": 1e-7, "cpu_per_time": 2.0},
            {"scheme": "rk4", "error": 1e-9, "cpu_per_time": 2.6},
            {"scheme": "rk2", "error": None, "cpu_per_time": 0.1}]
    assert frontier.best_serial(rows, 1e-6)["scheme"] == "rk2"
    assert frontier.best_serial(rows, 1e-8)["scheme"] == "rk4"
    assert frontier.best_serial(rows, 1e-3)["scheme"] == "euler"
    assert frontier.best_serial(rows, 1e-12) is None


def test_assess_scales_speedups_by_the_serial_cost_ratio(frontier):
    entry = {"alpha": 0.05, "errors": [1e-4, 1e-7], "n_auxiliary": 1}
    v = frontier.assess(entry, 1e-6, 0.0, fine_cost=4.0, best_cost=1.0)
    assert v["K"] == 2
    assert v["vs_F"]["pipelined"] == pytest.approx(1 / ((1 + 2 / 40) * 0.05 + 2 / 40))
    assert v["vs_best"]["pipelined"] == pytest.approx(v["vs_F"]["pipelined"] / 4)
    assert v["vs_best"]["standard"] == pytest.approx(v["vs_F"]["standard"] / 4)
    assert frontier.assess(entry, 1e-8, 0.0, 4.0, 1.0) is None


def test_frontier_keeps_the_fastest_per_family(frontier):
    entries = {
        "a": {"family": "grid", "alpha": 0.02, "errors": [1e-7]},              # K = 1
        "b": {"family": "grid", "alpha": 0.001, "errors": [1e-4, 1e-7]},       # K = 2, cheaper
        "c": {"family": "implicit", "alpha": 0.5, "errors": [1e-3]},           # misses
        "d": {"family": "implicit", "alpha": 0.2, "errors": [1e-3]},           # misses, cheaper
        "e": {"family": "implicit", "blowup": "x"},
    }
    best = frontier.frontier(entries, 1e-6, 0.0, 1.0, 1.0)
    # pipelined: a 1/(1.025*0.02 + 0.025) = 21.9; b 1/(1.05*0.001 + 0.05) = 19.6
    assert best["grid"]["label"] == "a" and best["grid"]["K"] == 1
    assert best["implicit"]["label"] == "d" and best["implicit"]["K"] is None
    # the standard schedule ranks them the other way: a 1/(0.04 + 0.025) = 15.4, b 1/(0.003 +
    # 0.05) = 18.9
    standard = frontier.frontier(entries, 1e-6, 0.0, 1.0, 1.0, "standard")
    assert standard["grid"]["label"] == "b" and standard["grid"]["K"] == 2


def test_hopeless_extrapolates_the_last_contraction(frontier):
    # 1e-2 -> 1e-3: rate 0.1, 4 iterations left of 6 reach 1e-7 <= 1e-6
    assert not frontier.hopeless([1e-2, 1e-3], 1e-6, 6)
    # with 2 left: 1e-5 > 1e-6
    assert frontier.hopeless([1e-2, 1e-3], 1e-6, 4)
    # exactly on the target after the last one allowed: not hopeless
    assert not frontier.hopeless([1.0, 0.5], 0.125, 4)
    assert frontier.hopeless([1e-3, 2e-3], 1e-6, 40)       # stalled or growing
    assert not frontier.hopeless([1e-3], 1e-6, 2)          # one iteration says nothing


ROUND5 = sorted((ROOT / "experiments" / "round5").glob("*.toml"))
#: Cut a shipped configuration to seconds: the rod at a fifth (L = 12, M = 61: σ_f, ε and the
#: grid factors of 2 and 3 as the full rod's), the vesicle at 162 points, two short slices.
QUICK = {"rod": ["model.n_points=61", "model.length=12", "time.t1=0.0004"],
         "vesicle": ["model.subdivisions=2", "time.t1=0.2"]}


@pytest.mark.parametrize("path", ROUND5, ids=lambda p: p.stem)
def test_round5_configuration_checks_and_runs_quick(path):
    """Each shipped configuration validates as it is (40 slices, pipelined), and a quick cut of
    it runs Parareal to the end with finite states."""
    from parastokes import config, parareal

    cfg, resolved = config.load(path)
    assert cfg.parareal.n_slices == 40 and cfg.parareal.schedule == "pipelined"
    assert resolved.n_auxiliary <= cfg.execution.workers
    cut = QUICK[cfg.model.kind] + ["parareal.n_slices=2", "parareal.max_iterations=1",
                                   'execution.executor="serial"', "execution.workers=1"]
    cfg, resolved = config.load(path, cut)
    setup = config.build(cfg, resolved)
    x0 = setup.system.initial_state()
    result = parareal.run(setup.fine, setup.coarse, x0, 0.0, cfg.time.t1, 2, tol=0.0,
                          max_iterations=1)
    assert result.iterations == 1 and np.isfinite(result.states).all()


def test_the_profile_counts_a_call_inside_a_timed_one_as_the_outer_piece(frontier):
    """f_t's forward difference evaluates the rates: those count as f_t, not as stage rates;
    a call of its own counts as its piece."""
    timer = frontier._PieceTimer()
    rates = timer.wrap("stage rates", lambda: sum(range(20000)))
    time_derivative = timer.wrap("f_t", lambda: rates() - rates())
    time_derivative()
    rates()
    assert timer.calls == {**dict.fromkeys(frontier.PIECES, 0), "f_t": 1, "stage rates": 1}
    assert timer.seconds["f_t"] > 0.0 and timer.seconds["stage rates"] > 0.0


def test_interleaved_alphas_take_each_candidates_median_over_the_rounds(frontier, monkeypatch):
    """Round by round each candidate is measured once (F beside it); its alpha is the median of
    its own ratios, not of the others'."""
    from types import SimpleNamespace

    from parastokes import parareal

    label, candidate = next(iter(frontier.CANDIDATES["quick"].items()))
    monkeypatch.setitem(frontier.CANDIDATES, "quick", {label: candidate, "other": candidate})
    ratios = iter([0.5, 0.1, 0.3, 0.2, 0.9, 0.25])

    def measured(*args, **kw):
        ratio = next(ratios)
        return SimpleNamespace(task_ratio=lambda: ratio)

    monkeypatch.setattr(parareal, "measure_slice_costs", measured)
    monkeypatch.setattr(frontier, "build", lambda problem, coarse: SimpleNamespace(
        fine=None, coarse=None, system=SimpleNamespace(initial_state=lambda: None)))
    out = frontier.interleaved_alphas("quick", [label, "other"], rounds=3)
    assert out[label]["ratios"] == [0.5, 0.3, 0.9] and out[label]["median"] == 0.5
    assert out["other"]["ratios"] == [0.1, 0.2, 0.25] and out["other"]["median"] == 0.2


def test_alphas_are_stored_under_the_given_key_prefix(monkeypatch):
    with benchmark_module("frontier") as frontier:
        stored = []
        monkeypatch.setattr(frontier, "interleaved_alphas",
                            lambda name, labels, rounds: {label: {"median": 0.1}
                                                          for label in labels})
        monkeypatch.setattr(frontier, "_store", lambda *args: stored.append(args))
        frontier.main(["--alphas", "table5", "7", "ros34pw2 1.25e-3", "--alphas-key",
                       "third session, quiet, "])
        frontier.main(["--alphas", "table4", "3", "ros34pw2 6.25e-4"])
    assert stored == [("table5", "alphas", "third session, quiet, ros34pw2 1.25e-3",
                       {"median": 0.1}),
                      ("table4", "alphas", "ros34pw2 6.25e-4", {"median": 0.1})]


def test_a_double_lu_label_names_its_candidate_and_the_patch(frontier):
    base = "ros34pw2 1.25e-3"
    assert frontier.split_variant(base + frontier.DOUBLE_LU) == (base, np.float64)
    assert frontier.split_variant(base) == (base, None)
    from parastokes.stiff import solve

    saved = solve.BAND_PRECISION
    with frontier.band_precision(np.float64):
        assert solve.BAND_PRECISION is np.float64
    assert solve.BAND_PRECISION is saved
    with frontier.band_precision(None):
        assert solve.BAND_PRECISION is saved


def test_interleaved_alphas_measure_the_double_lu_variant_under_its_patch(frontier, monkeypatch):
    """The variant is built from its base candidate's [coarse] table and each of its slices is
    measured with the band LU in double; the plain candidate's with the default."""
    from types import SimpleNamespace

    from parastokes import parareal
    from parastokes.stiff import solve

    label = "ros34pw2 1.25e-3"
    built, seen = [], []

    def measured(fine, coarse, *args, **kw):
        seen.append((coarse, solve.BAND_PRECISION))
        return SimpleNamespace(task_ratio=lambda: 0.1)

    def build(problem, coarse):
        built.append(coarse)
        return SimpleNamespace(fine=None, coarse=len(built),
                               system=SimpleNamespace(initial_state=lambda: None))

    monkeypatch.setattr(parareal, "measure_slice_costs", measured)
    monkeypatch.setattr(frontier, "build", build)
    frontier.interleaved_alphas("table5", [label, label + frontier.DOUBLE_LU], rounds=2)
    coarse = frontier.CANDIDATES["table5"][label].coarse
    assert built == [coarse, coarse]
    default = solve.BAND_PRECISION
    assert default is not np.float64
    assert seen == [(1, default), (2, np.float64)] * 2


def test_interleaved_serial_ratios_are_medians_of_each_rounds_ratio_to_the_first(frontier,
                                                                                monkeypatch):
    from types import SimpleNamespace

    times = iter([9.0, 9.0,                  # (the warm-ups)
                  2.0, 1.0, 4.0, 1.0, 3.0, 2.4])   # rounds: (F, run) x 3
    monkeypatch.setattr(frontier, "_cpu", lambda function: (None, next(times)))
    monkeypatch.setattr(frontier, "build", lambda problem, coarse: SimpleNamespace(
        system=SimpleNamespace(initial_state=lambda: None)))
    out = frontier.interleaved_serial("table5", [("rk4", 5.45e-5, None),
                                                 ("ros34pw2-krylov", 5.45e-5, 1e-6)], rounds=3)
    assert out["rk4 5.45e-05"]["median_ratio"] == 1.0
    assert out["ros34pw2-krylov rtol 1e-06"]["cpu_per_slice"] == [1.0, 1.0, 2.4]
    assert out["ros34pw2-krylov rtol 1e-06"]["median_ratio"] == pytest.approx(0.5)  # 0.5 .25 .8
    assert len(out["rk4 5.45e-05"]["load_average"]) == 4


def test_serial_runs_are_read_as_steps_or_tolerances(frontier):
    assert frontier._runs(["rk2", "3.74e-5", "ros34pw2-krylov", "rtol=1e-5"]) == [
        ("rk2", 3.74e-5, None), ("ros34pw2-krylov", None, 1e-5)]
    with pytest.raises(SystemExit, match="SCHEME DT pairs"):
        frontier._runs(["rk2", "3.74e-5", "rk4"])
    assert frontier.problem_step("table5", None) == 5.45e-5
    assert frontier.problem_step("table5", 1e-3) == 1e-3


def test_full_serial_errors_are_against_the_reference_over_the_same_interval(frontier,
                                                                              monkeypatch,
                                                                              tmp_path):
    """The reference's own scheme and step read 0 (the same run); a coarser run does not, and
    a second call adds its rows to the file (the reference cached per interval)."""
    monkeypatch.setattr(frontier, "OUT", tmp_path)
    scheme, dt = frontier.PROBLEMS["quick"].reference
    data = frontier.full_serial("quick", [(scheme, dt, None)], t1=0.0005)
    rows = data["T = 0.0005"]["runs"]
    assert rows[f"{scheme} {dt:g}"]["error_positions"] == 0.0
    assert rows[f"{scheme} {dt:g}"]["error_state"] == 0.0
    assert (tmp_path / ".quick_reference_t0.0005.npy").exists()
    again = frontier.full_serial("quick", [("rk2", 1.16e-5, None)], t1=0.0005)
    rows = again["T = 0.0005"]["runs"]
    assert set(rows) == {f"{scheme} {dt:g}", "rk2 1.16e-05"}
    assert rows["rk2 1.16e-05"]["error_positions"] > 1e-12


def test_summary_takes_the_best_runs_cost_from_the_interleaved_ratio_where_measured(
        frontier, monkeypatch, tmp_path):
    """Table 5's fastest serial run is not F: its CPU over F's is the interleaved median of
    PROBLEM_serial_ratios.json (a record starting with F), else the ratio of the analogue's
    rows; the frontier's speedups against it scale by that ratio."""
    import json

    monkeypatch.setattr(frontier, "OUT", tmp_path)
    problem = frontier.PROBLEMS["table5"]
    (scheme, dt), (best_scheme, best_dt) = problem.fine, problem.best
    data = {"problem": {"title": problem.title, "target": 1e-6, "fine": [scheme, dt]},
            "serial": [{"scheme": scheme, "dt": dt, "error": 1e-9, "cpu_per_time": 4.0},
                       {"scheme": best_scheme, "dt": best_dt, "error": 9e-7,
                        "cpu_per_time": 2.0}],
            "candidates": {"g": {"family": "implicit", "alpha": 0.1, "errors": [5e-7]}}}
    s = frontier.summary(data)
    assert s["cost_ratio"] == 0.5 and s["best"]["dt"] == best_dt      # the rows: 2 / 4
    f_key, b_key = f"{scheme} {dt:g}", f"{best_scheme} {best_dt:g}"
    (tmp_path / "table5_serial_ratios.json").write_text(json.dumps({   # (ratios to the first)
        "F first": {f_key: {"median_ratio": 1.0}, b_key: {"median_ratio": 0.75}},
        "other first": {b_key: {"median_ratio": 1.0}, f_key: {"median_ratio": 1.25}}}))
    s = frontier.summary(data)
    assert s["cost_ratio"] == 0.75
    verdict = s["frontier"]["implicit"]["assessment"]
    assert verdict["vs_best"]["pipelined"] == pytest.approx(0.75 * verdict["vs_F"]["pipelined"])


def test_a_serial_run_is_fixed_or_adaptive_with_atol_a_tenth_of_rtol(frontier, monkeypatch):
    from parastokes import integrate

    calls = []
    monkeypatch.setattr(integrate, "propagate", lambda *args, **kw: calls.append((args, kw)))
    frontier.serial_run("system", "x0", 0.5, "rk2", 1e-3, None)
    frontier.serial_run("system", "x0", 0.5, "ros34pw2-krylov", 1e-3, 2.5)
    assert calls == [(("system", "x0", 0.0, 0.5, "rk2", 1e-3), {"rtol": None, "atol": None}),
                     (("system", "x0", 0.0, 0.5, "ros34pw2-krylov", 1e-3),
                      {"rtol": 2.5, "atol": 0.25})]


def test_a_checkpointed_run_goes_on_from_its_last_checkpoint(frontier):
    done = {"0.01": {"last_step": 5e-4, "cpu": 9.0}, "0.02": {"last_step": 6e-4, "cpu": 12.0},
            "yardsticks": []}
    assert frontier.next_checkpoint(done, [0.01, 0.02, 0.05]) == (0.02, 6e-4, 12.0)
    assert frontier.next_checkpoint(done, [0.01, 0.02]) is None
    t, step, cpu = frontier.next_checkpoint({}, [0.01, 0.02])
    assert (t, cpu) == (0.0, 0.0) and np.isnan(step)


def test_cost_over_fine_is_cpu_per_unit_time_over_the_yardsticks(frontier):
    # 340 s over T = 1 against F's 3.8 s over 1e-3 (3800 s over T = 1)
    assert frontier.cost_over_fine(340.0, 1.0, 3.8, 1e-3) == pytest.approx(340 / 3800)
    assert frontier.cost_over_fine(3.0, 0.5, 1.5, 0.25) == pytest.approx(1.0)


def _fake_run(calls):
    from types import SimpleNamespace

    def run(system, x, t0, t1, scheme, h, rtol=None, atol=None):
        calls.append((t0, t1, h, rtol, atol))
        return SimpleNamespace(state=x + (t1 - t0), dt=(t1 - t0) / 2, n_steps=1, n_rejected=0)
    return run


@pytest.mark.parametrize("rtol", [None, 1e-5])
def test_checkpointed_runs_carry_the_state_and_the_last_step_across_a_resume(
        frontier, monkeypatch, tmp_path, rtol):
    """Adaptive segments start from the step the one before tried (here half the segment),
    fixed ones from dt; a second call goes on from the last checkpoint's state and CPU."""
    from types import SimpleNamespace

    from parastokes import integrate

    monkeypatch.setattr(frontier, "OUT", tmp_path)
    monkeypatch.setattr(frontier, "build", lambda problem, coarse: SimpleNamespace(
        system=SimpleNamespace(initial_state=lambda: np.zeros(3))))
    calls, sticks = [], []
    monkeypatch.setattr(integrate, "run", _fake_run(calls))
    monkeypatch.setattr(integrate, "propagate", lambda *a, **kw: sticks.append(a[3]))
    done = frontier.checkpointed_serial("quick", "ros34pw2-krylov", 0.01, rtol, [0.125, 0.375])
    atol = None if rtol is None else rtol / 10
    assert calls == [(0.0, 0.125, 0.01, rtol, atol),            # (binary fractions: exact)
                     (0.125, 0.375, 0.01 if rtol is None else 0.0625, rtol, atol)]
    assert done["0.375"]["cpu"] >= done["0.125"]["cpu"] >= 0.0
    calls.clear()
    again = frontier.checkpointed_serial("quick", "ros34pw2-krylov", 0.01, rtol,
                                         [0.125, 0.375, 0.625])
    assert calls == [(0.375, 0.625, 0.01 if rtol is None else 0.125, rtol, atol)]
    key = frontier.run_key("ros34pw2-krylov", 0.01, rtol).replace(" ", "_")
    assert np.load(tmp_path / f".quick_state_{key}_t0.625.npy") == pytest.approx([0.625] * 3)
    assert again["0.625"]["cpu"] >= again["0.375"]["cpu"] == done["0.375"]["cpu"]
    assert sticks == [frontier.YARDSTICK] * 2 and len(again["yardsticks"]) == 2
    assert frontier.checkpointed_serial("quick", "ros34pw2-krylov", 0.01, rtol, [0.125]) == again


def test_checkpoint_errors_compare_states_at_the_same_time(frontier, monkeypatch, tmp_path):
    import json
    from types import SimpleNamespace

    monkeypatch.setattr(frontier, "OUT", tmp_path)
    monkeypatch.setattr(frontier, "build", lambda problem, coarse: SimpleNamespace(
        system=SimpleNamespace(positions=lambda s: s[:, :3])))
    ref = np.array([[1.0, 0.0, 0.0, 5.0], [0.0, 2.0, 0.0, 0.0]])
    run = ref + [[0.25, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
    np.save(tmp_path / ".quick_state_ref_t0.1.npy", ref)
    np.save(tmp_path / ".quick_state_a_t0.1.npy", run)
    np.save(tmp_path / ".quick_state_a_t0.2.npy", run)
    np.save(tmp_path / ".quick_reference_t0.1.npy", 2 * ref)
    (tmp_path / "quick_checkpoints.json").write_text(json.dumps({
        "ref": {"0.1": {"cpu": 1.0}},
        "a": {"0.1": {"cpu": 2.0}, "0.2": {"cpu": 3.0},
              "yardsticks": [{"cpu": 1.0}, {"cpu": 2.0}, {"cpu": 9.0}]}}))
    out = frontier.checkpoint_errors("quick", "ref")
    a = out["a"]["0.1"]
    assert a["error_positions"] == pytest.approx(0.25)            # point 0: 0.25 / 1
    assert a["error_state"] == pytest.approx(0.5)                 # point 1: 1 / 2
    # against twice ref: point 0 |(1.25, 0, 0) - (2, 0, 0)| / 2, point 1 |2 - 4| / 4
    assert a["error_positions_vs_fine_reference"] == pytest.approx(0.5)
    assert a["cost_over_fine"] == pytest.approx((2.0 / 0.1) / (2.0 / frontier.YARDSTICK))
    assert "error_positions" not in out["a"]["0.2"]               # no reference state at 0.2
    assert "error_positions" not in out["ref"]["0.1"]
    assert out["ref"]["0.1"]["cost_over_fine"] is None


def test_an_implicit_fine_configuration_is_adaptive_with_the_serial_runs_tolerances(frontier):
    """F = ros34pw2-krylov at rtol (atol rtol / 10) from F's fixed step, over P slices of L,
    and the configuration schema takes it as it is."""
    from parastokes import config

    problem = frontier.PROBLEMS["rod601_long"]
    coarse = frontier.CANDIDATES["rod601_long"]["ros34pw2 rtol 1e-3"].coarse
    data = frontier.implicit_fine_config(problem, coarse, 1e-5, 0.025, 4)
    assert data["fine"] == {"scheme": "ros34pw2-krylov", "dt": 7.58e-7, "rtol": 1e-5,
                            "atol": pytest.approx(1e-6)}
    assert data["time"]["t1"] == pytest.approx(0.1) and data["parareal"]["n_slices"] == 4
    cfg = config.parse(data, "test")
    assert cfg.fine.rtol == 1e-5 and cfg.coarse.rtol == 1e-3
