"""``parastokes tune`` / ``parastokes.tuning.tune`` (docs/tuning.md) on small rods (21 nodes, σ_f =
0.2).

What is asserted: bad input stops before the search with a message naming the problem; a
candidate whose every member is stable but whose combination amplifies perturbations is rejected
by the combined-slice-map check (and really blows up); the derived step margin solves its
defining equation; budget and Ctrl-C keep what was measured; TUNED.toml is accepted by ``check``
and a real run of it reaches η* within the predicted N_it + 1 iterations.
"""

from __future__ import annotations

import json
import math
import signal
import time
import tomllib
from pathlib import Path

import numpy as np
import pytest

from parastokes import cli, integrate, models, parareal, tuning
from parastokes.tuning import Settings, Space, TuningError, slice_map, stability
from parastokes.tuning import search as search_module
from parastokes.tuning.report import _helps, toml_dumps
from parastokes.tuning.search import Candidate
from parastokes.tuning.space import REACH, reach_table

SIGMA = 0.2  # grid spacing of the 21-node, 4 μm rod (the paper's σ_f)

#: The narrowest space: only the plain baseline is measured.
PLAIN = Space(schemes=("euler",), parameters=(), richardson=(0,), step_fractions=(1.0,))


def small_rod(epsilon_sigma: float = 5.0):
    return models.rod_swimmer(n_points=21, length=4.0, epsilon=epsilon_sigma * SIGMA)


class Spy(tuning.Progress):
    """Records whether the search started; optionally interrupts after some candidates."""

    def __init__(self, interrupt_after: int | None = None) -> None:
        self.started = False
        self.done = 0
        self.interrupt_after = interrupt_after

    def start(self, total: int) -> None:
        self.started = True

    def advance(self, label: str) -> None:
        self.done += 1
        if self.interrupt_after is not None and self.done >= self.interrupt_after:
            raise KeyboardInterrupt


# ---- bad input -----------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"cores": 0}, "cores must be an integer >= 1"),
        ({"target": 0.0}, "target"),
        ({"target": 2.0}, "target"),
        ({"budget": 1e-4}, "too small to test even one candidate"),
        ({"fine_dt": 4e-5}, "fine solver itself is unstable"),
        ({"target": 1e-16}, "below the fine solver's own time-discretization error"),
        ({"space": Space(parameters=("shear",))}, "cannot extrapolate in 'shear'"),
        ({"space": Space(grid_factors=(7,))}, "grid factor 7 does not fit"),
        ({"space": Space(grid_factors=(0,))}, "grid factors must be integers >= 1"),
        ({"space": Space(schemes=(), nodes=())}, "nothing to choose from in schemes, nodes"),
        ({"space": Space(parameters=("epsilon", "epsilon"))}, "name one twice"),
        ({"space": Space(extra=(Settings("euler", grid=7, dt=1e-5, name="paper"),))},
         "compared solver paper: euler, grid 7"),
        ({"budget": "5"}, "budget must be a positive number"),
        ({"pilot_slices": 2.5}, "pilot_slices must lie"),
        ({"n_slices": 1, "cores": 1}, "Parareal needs two slices"),
    ],
)
def test_bad_input_stops_before_the_search(changes, message):
    rod = small_rod()
    fine = integrate.Propagator(rod, "rk2", changes.pop("fine_dt", 1e-6))
    spy = Spy()
    kwargs = {"t0": 0.0, "t1": 8e-4, "n_slices": 4, "cores": 4, "target": 1e-6, "space": PLAIN}
    kwargs.update(changes)
    with pytest.raises(TuningError, match=message):
        tuning.tune(fine, progress=spy, **kwargs)
    assert not spy.started


def test_the_parareal_facade_hands_out_nothing_from_above():
    # the tuner builds on Parareal, so it lives above it: parastokes.tuning.tune, not parareal.tune
    assert not hasattr(parareal, "tune")
    assert parareal.hodmd.__module__ == "parastokes.parareal.dmd"


# ---- stability of the combined slice map ---------------------------------------------------
def table5_g1(theta0: dict) -> Settings:
    """Table 5 G¹ (36 auxiliary solvers, τ_c = 70 τ_f) for ε⁰ = 7σ_f."""
    return Settings(
        "euler",
        (
            ("epsilon", tuple(SIGMA * e for e in (7.2, 7.25, 7.3, 7.35))),
            ("bending", tuple(theta0["bending"] * a for a in (0.7, 0.75, 0.8))),
            ("viscosity", tuple(theta0["viscosity"] * m for m in (1.3, 1.45, 1.6))),
        ),
        dt=70e-6,
        name="Table 5 G1",
    )


def test_combination_of_stable_members_is_rejected_when_it_amplifies():
    """Short slices (14 coarse steps): every member damps, the Lagrange combination (Σ|w| ~ 1e4)
    amplifies (docs/validation.md, section 3). The tuner must reject it on the combined map's
    spectral radius, before its pilot run; a real initial sweep confirms that it blows up. Over
    longer slices the same solver is stable: ρ(DG) ≈ 1 although its norm ‖DG‖ (a one-slice
    transient) is above the allowed growth, so the verdict rests on ρ, not on the norm."""
    rod = small_rod(7.0)
    fine = integrate.Propagator(rod, "rk2", 1e-6)
    settings = table5_g1(rod.params)
    space = Space(schemes=("euler",), parameters=(), richardson=(0,), step_fractions=(1.0,),
                  extra=(settings,))
    res = tuning.tune(fine, t0=0.0, t1=4e-3, n_slices=4, cores=40, target=1e-6, space=space)
    (cand,) = [c for c in res.candidates if c.settings.name == "Table 5 G1"]
    assert cand.status == "rejected"
    assert "combined slice map unstable: ρ(DG)" in cand.reason
    assert cand.pilot_errors == []  # rejected before the pilot
    assert cand.spectral_radius > cand.allowed_radius
    coarse = settings.build(rod)
    x0 = rod.initial_state()
    # the whole Jacobian: the estimate is its spectral radius (5.894 by eigenvalues)
    rho, _ = slice_map.dense(slice_map.Probe(lambda x: coarse(0.0, 1e-3, x), rod.positions, x0))
    assert cand.spectral_radius == pytest.approx(rho, rel=3e-2)
    members = [stability.spectral_radius(p, rod, x0, 0.0, 1e-3)
               for row in coarse.auxiliary for p in row]
    assert all(m.converged for m in members)
    assert max(m.rho for m in members) < cand.allowed_radius  # each member alone passes
    # over the paper's slice length the same check accepts the same solver, whose norm the
    # allowed growth would reject
    longer = stability.spectral_radius(coarse, rod, x0, 0.0, 4e-3)
    assert longer.converged and longer.rho < cand.allowed_radius
    _, norm = slice_map.dense(slice_map.Probe(lambda x: coarse(0.0, 4e-3, x), rod.positions, x0))
    assert norm > 3 * cand.allowed_radius  # 15.2 against 3.2
    # checked against a real run: the initial coarse sweep over the short slices blows up
    with pytest.raises(integrate.BlowUpError):
        for n in range(4):
            x0 = coarse(n * 1e-3, (n + 1) * 1e-3, x0)


def test_step_margin_solves_its_equation():
    for steps, weights, target in [(113, 49.0, 1e-8), (60, 3249.0, 1e-6), (1400, 1e5, 1e-8)]:
        delta = stability.step_margin(steps, weights, target)
        assert weights * (1 - 2 * delta) ** steps == pytest.approx(target / 10, rel=1e-9)
    # short slices and large weights need larger margins (docs/validation.md: 5-10 %)
    assert stability.step_margin(60, 3249.0, 1e-8) > stability.step_margin(1400, 3249.0, 1e-8)
    assert 0.05 < stability.step_margin(113, 49.0, 1e-8) < 0.15
    assert stability.step_margin(2000, 49.0, 1e-8) < 0.01


def test_safe_step_divides_the_slice_below_the_margin():
    step, delta = stability.safe_step(1.3e-5, 2e-3, 49.0, 1e-8)
    n = round(2e-3 / step)
    assert n * step == pytest.approx(2e-3)
    assert step <= 1.3e-5 * (1 - delta) * (1 + 1e-12)
    assert delta == pytest.approx(stability.step_margin(n, 49.0, 1e-8))


# ---- budget and Ctrl-C ---------------------------------------------------------------------
SMALL = Space(schemes=("euler",), parameters=("epsilon",), reach=(1,), nodes=(2, 3),
              richardson=(0,), step_fractions=(1.0,))


def test_budget_stops_the_search_and_keeps_the_baseline():
    fine = integrate.Propagator(small_rod(), "rk2", 1e-6)
    t = [0.0]

    def clock() -> float:  # every reading is an hour later
        t[0] += 3600.0
        return t[0]

    res = tuning.tune(fine, t0=0.0, t1=8e-3, n_slices=4, cores=4, target=1e-6, space=SMALL,
                      budget=10.0, clock=clock)
    assert res.report["search"]["stopped"] == "budget"
    assert res.baseline.status == "accepted" and res.chosen is res.baseline
    assert {c.status for c in res.candidates[1:]} <= {"not reached", "pruned"}


def test_a_candidates_step_search_is_charged_to_it(monkeypatch):
    """The bisection for a candidate's step limit (10-15 one-slice solves for a new corner) is
    part of its cost, as the baseline's is: the budget's estimates of a screen rest on it."""
    from parastokes.tuning.search import _Search

    ticks, step = [0.0], _Search.step

    def charged(self, cand):
        found = step(self, cand)
        ticks[0] += 5.0
        return found

    monkeypatch.setattr(_Search, "step", charged)
    fine = integrate.Propagator(small_rod(), "rk2", 1e-6)
    res = tuning.tune(fine, t0=0.0, t1=8e-3, n_slices=4, cores=4, target=1e-6, space=SMALL,
                      budget=1e6, clock=lambda: ticks[0])
    stepped = [c for c in res.candidates if c.step_limit is not None]
    assert len(stepped) > 1 and all(c.seconds >= 5.0 for c in stepped)


@pytest.mark.parametrize(("signum", "stopped"), [(signal.SIGTERM, "terminated"),
                                                 (signal.SIGHUP, "hung up")])
def test_a_signal_during_the_search_is_named(signum, stopped):
    class Signalled(Spy):
        def advance(self, label: str) -> None:
            raise cli.Terminated(signum)

    fine = integrate.Propagator(small_rod(), "rk2", 1e-6)
    res = tuning.tune(fine, t0=0.0, t1=8e-3, n_slices=4, cores=4, target=1e-6, space=SMALL,
                      budget=1e6, progress=Signalled())
    assert res.report["search"]["stopped"] == stopped
    assert res.baseline.pilot_errors  # what was measured is kept


def test_interrupt_keeps_what_was_measured():
    fine = integrate.Propagator(small_rod(), "rk2", 1e-6)
    res = tuning.tune(fine, t0=0.0, t1=8e-3, n_slices=4, cores=4, target=1e-6, space=SMALL,
                      budget=1e6, progress=Spy(interrupt_after=1))
    search = res.report["search"]
    assert search["stopped"] == "interrupted" and search["evaluated"] == 1
    assert res.baseline.pilot_errors and res.chosen is not None
    assert any(c.status == "not reached" for c in res.candidates)


# ---- the command, end to end ---------------------------------------------------------------
CONFIG = """
title = "small rod for tune"
[model]
kind = "rod"
n_points = 21
length = 4.0
epsilon = 5.0
[time]
t1 = 0.008
[fine]
dt = 1e-6
[coarse]
dt_ratio = 10
[parareal]
n_slices = 2
[execution]
executor = "serial"
[run]
mode = "both"
[tune]
schemes = ["euler"]
parameters = ["epsilon"]
reach = [1]
nodes = [2, 3]
step_fractions = [1.0]
"""


@pytest.mark.parametrize(
    ("flags", "message"),
    [
        (["--cores", "1"], "--cores must be at least 2"),
        (["--cores", "4", "--pilot-points", "1"], "--pilot-points must be at least 3"),
        (["--cores", "4", "--pilot-points", "0"], "--pilot-points must be at least 3"),
        (["--cores", "4", "--pilot-slices", "0"], "--pilot-slices must be at least 2"),
    ],
)
def test_tune_command_refuses_bad_flags_before_any_work(tmp_path, capsys, flags, message):
    # regression: --pilot-points 1 failed with a ZeroDivisionError; 0 fell back to the default
    source = tmp_path / "rod.toml"
    source.write_text(CONFIG)
    out = tmp_path / "TUNED.toml"
    code = cli.main(["tune", str(source), *flags, "--target", "1e-6", "--out", str(out), "-q"])
    assert code == cli.ExitCode.CONFIG
    assert message in capsys.readouterr().err
    assert not list(tmp_path.glob("TUNED*"))


def test_tune_command_writes_a_config_that_runs_to_the_target(tmp_path):
    target = 1e-8
    source = tmp_path / "rod.toml"
    source.write_text(CONFIG)
    out = tmp_path / "TUNED.toml"
    assert cli.main(["tune", str(source), "--cores", "4", "--target", f"{target:g}", "--out",
                     str(out), "-q", "--richardson", "0", "1"]) == 0
    report = json.loads(out.with_suffix(".json").read_text())
    for key in ("chosen", "baseline"):
        assert set(report[key]["predicted"]) >= {"speedup", "iterations", "gamma_ratio"}
    assert report["candidates"] and {"seconds", "fraction"} <= set(report["cost"])
    assert out.with_suffix(".png").stat().st_size > 0
    for cand in report["candidates"]:
        assert cand["status"] in ("accepted", "rejected", "pruned", "not reached")
        assert cand["status"] == "accepted" or cand["reason"]
    chosen = report["chosen"]
    if chosen == report["baseline"]:
        # the plain solver won (the choice rests on measured costs): it has no combination to
        # check on ρ(DG) (docs/tuning.md, step 7), only its step below the limit by its margin
        stab = chosen["stability"]
        assert stab["stable"] is None and stab["spectral_radius"] is None
        assert stab["step_margin"] >= stab["required_step_margin"] - 1e-12 > 0
    else:
        assert chosen["stability"]["stable"] and chosen["stability"]["margin"] > 0
    # the chosen solver is the accepted one with the highest predicted speedup
    accepted = [c for c in [report["baseline"], *report["candidates"]] if c["status"] == "accepted"]
    assert chosen["predicted"]["speedup"] == max(c["predicted"]["speedup"] for c in accepted)
    assert chosen["status"] == "accepted" and chosen["predicted"]["iterations"] >= 1
    tuned = tomllib.loads(out.read_text())
    assert tuned["parareal"]["n_slices"] == 4
    assert tuned["parareal"]["max_iterations"] == chosen["predicted"]["iterations"]
    assert tuned["fine"] == {"scheme": "rk2", "dt": 1e-6} and tuned["time"]["t1"] == 0.008
    assert cli.main(["check", str(out), "-q"]) == 0
    # a real run of the tuned configuration reaches η* within the predicted N_it + 1
    n_it = chosen["predicted"]["iterations"]
    run_dir = tmp_path / "run"
    assert cli.main(["run", str(out), "--out", str(run_dir), "-q",
                     "--set", f"parareal.max_iterations={n_it + 1}",
                     "--set", "output.trajectory=false", "--set", "output.figures=false"]) == 0
    errors = json.loads((run_dir / "summary.json").read_text())["errors"]
    assert min(errors[: n_it + 1]) <= target


def test_toml_writer_round_trips():
    data = {"title": 'a "b"', "model": {"kind": "rod", "n": 3, "x": 1e-6, "flag": True,
                                        "shear": [0.6, 0.6]},
            "coarse": {"lagrange": {"epsilon": {"nodes": [1.04, 1.05], "unit": "absolute"}}}}
    assert tomllib.loads(toml_dumps(data, "header\nline")) == data
    with pytest.raises(ValueError):
        toml_dumps({"a": {"b": math.inf}})


def test_settings_weights_and_corner():
    theta0 = {"epsilon": 1.0, "bending": 1.0, "viscosity": 1e-6}
    s = Settings("euler", (("epsilon", (1.04, 1.05)), ("bending", (0.8, 0.9))), m=1, r=0.5)
    w = np.abs(parareal.lagrange_weights([1.0, 1.0], [[1.04, 1.05], [0.8, 0.9]])).sum()
    v = np.abs(parareal.richardson_weights(1, 0.5, 1)).sum()
    assert s.weight_sum(theta0) == pytest.approx(w * v)
    assert s.corner() == {"epsilon": 1.04, "bending": 0.9}
    assert s.n_auxiliary == 8


def test_richardson_settings_without_r_are_refused_when_made():
    # regression: m >= 1 without r failed with a TypeError on None inside the weights and label
    with pytest.raises(ValueError, match="r is required when m >= 1"):
        Settings("euler", m=1)


def test_a_plain_choice_is_not_called_extrapolation():
    # regression: with the baseline rejected, a plain chosen solver was reported as "helps"
    baseline = Candidate(Settings("euler"), status="rejected", reason="unstable")
    chosen = Candidate(Settings("rk2", step_fraction=0.6), status="accepted", speedup=3.0)
    verdict = _helps(chosen, baseline)
    assert verdict["helps"] is False and "not extrapolated" in verdict["note"]
    lagrange = Settings("euler", (("epsilon", (1.0, 1.1)),))
    assert _helps(Candidate(lagrange, status="accepted", speedup=3.0), baseline)["helps"] is True


def test_speedup_curve_needs_a_measured_candidate():
    # regression: a candidate without a measured γ_G/γ_F failed with a TypeError on None
    from types import SimpleNamespace

    from parastokes.tuning.search import Candidate, TuneResult

    cand = Candidate(Settings("euler", dt=0.1), pilot_errors=[1e-3, 1e-5])
    result = TuneResult(None, None, None, cand, [], {}, SimpleNamespace(n_slices=3))
    with pytest.raises(ValueError, match="no measured"):
        result.speedup_curve(cand, np.array([1e-4]), 30)
    cand.gamma_ratio = 0.01
    assert result.speedup_curve(cand, np.array([1e-4]), 30)[0] > 1


# ---- predictions and configurations --------------------------------------------------------
def test_predicted_iterations_scale_with_slices_and_contract_geometrically():
    from parastokes.tuning import cost

    # pilot η^1, η^2 at T_3; the run has 30 slices: 1e-5, 1e-7, then x 1e-2 per iteration
    assert cost.predicted_errors([1e-6, 1e-8], 3, 30, 4) == pytest.approx(
        [1e-5, 1e-7, 1e-9, 1e-11])
    assert cost.predicted_iterations([1e-6, 1e-8], 3, 30, 1e-8) == 3
    assert cost.predicted_iterations([1e-6, 1e-8], 3, 30, 1e-4) == 1
    assert cost.predicted_iterations([1e-6, 2e-6], 3, 30, 1e-8) is None  # no contraction
    assert cost.predicted_iterations([1e-6, 1e-8], 3, 3, 1e-10) is None  # needs N_c iterations


def _full_scale_checks():
    """(solver, window, pilot contraction, predicted N_it, the run's N_it or None) for every
    vesicle solver of docs/figures/tuning/pilot_check with a full-scale reproduction record."""
    root = Path(__file__).resolve().parents[1] / "docs"
    for path in sorted((root / "figures" / "tuning" / "pilot_check").glob("pilot_check_*.json")):
        for row in json.loads(path.read_text()):
            record = root / "reproduction" / f"{row['solver']}.json"
            if not record.exists():
                continue
            errors = json.loads(record.read_text())["errors"]
            for window in ("P2", "P3"):
                m = row[window]
                for target in (1e-6, 1e-8):
                    real = next((k for k, e in enumerate(errors, 1) if e <= target), None)
                    yield (row["solver"], window, m["contraction"],
                           m["iterations"][f"{target:g}"], real, len(errors))


def test_caution_marks_every_pilot_that_underestimated_a_full_run():
    """Against the full-scale records: wherever N_it lies within the pilot's measured iterations
    the run reached η* within N_it + 1 and the report is silent; wherever a run needed more,
    the report cautions."""
    from parastokes.tuning import cost

    checks = list(_full_scale_checks())
    assert len(checks) >= 20  # six records or more, two windows, two targets
    missed = 0
    for solver, window, rho, predicted, real, done in checks:
        measured = int(window[1:]) - 1  # K = P - 1
        too_few = predicted is not None and (real or done + 1) > predicted + 1
        missed += too_few
        if too_few:
            assert cost.caution(predicted, measured, rho), (solver, window)
        if predicted is not None and predicted <= measured:
            assert not too_few, (solver, window)
            assert cost.caution(predicted, measured, rho) is None
    assert missed >= 2  # Table 8 G¹ and G²


def test_gamma_ratio_counts_waves_of_the_slowest_auxiliary_solver():
    from parastokes.tuning import cost

    s = Settings("euler", (("epsilon", (1.04, 1.05, 1.06, 1.07)),), m=1, r=0.5, dt=2e-5)
    # steps per slice 1e-3: 50 (τ) and 100 (τ/2): the slowest holds 100/150 of a row's work
    one_wave = cost.gamma_ratio(s, 1e-3, coarse_seconds=1.2, gamma_f=10.0, cores=8)
    assert one_wave == pytest.approx(1.2 * 100 / (4 * 150) / 10.0)
    assert cost.gamma_ratio(s, 1e-3, 1.2, 10.0, cores=3) == pytest.approx(3 * one_wave)


def test_settings_from_config_is_the_configured_coarse_solver():
    from parastokes import config
    from parastokes.tuning.space import settings_from_config

    cfg, resolved = config.load("experiments/quick/table4_g3.toml")
    setup = config.build(cfg, resolved)
    built = settings_from_config(cfg, resolved).build(setup.system)
    assert built.thetas == setup.coarse.thetas
    assert [p.dt for p in built.auxiliary[0]] == [p.dt for p in setup.coarse.auxiliary[0]]
    np.testing.assert_array_equal(built.lagrange_weights, setup.coarse.lagrange_weights)


def test_coarse_grid_candidates_are_measured_on_the_coarse_rod():
    fine = integrate.Propagator(small_rod(), "rk2", 1e-6)
    space = Space(schemes=("euler",), parameters=(), richardson=(0,), grid_factors=(2,),
                  step_fractions=(1.0,))
    res = tuning.tune(fine, t0=0.0, t1=8e-3, n_slices=4, cores=4, target=1e-4, space=space,
                      budget=1e6)
    (cand,) = [c for c in res.candidates if c.settings.grid == 2]
    assert cand.status == "accepted", cand.reason
    assert cand.pilot_errors and cand.spectral_radius <= cand.allowed_radius
    # 11 nodes instead of 21: the coarse rod's step limit and cost are its own
    assert cand.step_limit != res.baseline.step_limit
    assert isinstance(cand.settings.build(small_rod()), parareal.OnCoarseGrid)
    assert cand.settings.coarse_table()["grid_factor"] == 2


# ---- screening, pruning, cost fraction -----------------------------------------------------
PRUNING = Space(schemes=("euler",), parameters=("epsilon",), reach=(1, 2), nodes=(2, 3),
                richardson=(0, 1), step_fractions=(1.0, 0.6))


PRUNING_RUN = {"t0": 0.0, "t1": 8e-3, "n_slices": 4, "cores": 4, "target": 1e-6,
               "space": PRUNING, "budget": 1e6}


@pytest.fixture(scope="module")
def exhaustive():
    """Every candidate of PRUNING measured."""
    fine = integrate.Propagator(small_rod(), "rk2", 1e-6)
    return tuning.tune(fine, exhaustive=True, **PRUNING_RUN)


def test_pruning_never_discards_what_the_exhaustive_search_would_choose(exhaustive):
    """Every candidate measured (exhaustive) vs the best-first search with pruning by the
    optimistic bound: the pruned search chooses as well (within the noise of measured CPU times),
    and no candidate it pruned does better in the exhaustive search."""
    fine = integrate.Propagator(small_rod(), "rk2", 1e-6)
    full = exhaustive
    pruned = tuning.tune(fine, **PRUNING_RUN)
    assert all(c.status in ("accepted", "rejected") for c in full.candidates)
    assert any(c.status == "pruned" for c in pruned.candidates)  # the pruning did something
    assert pruned.chosen is not None and full.chosen is not None
    assert pruned.chosen.speedup >= 0.9 * full.chosen.speedup
    by_settings = {c.settings: c for c in full.candidates}
    for cand in pruned.candidates:
        if cand.status == "pruned":
            other = by_settings[cand.settings]
            assert other.speedup is None or other.speedup <= 1.1 * pruned.chosen.speedup


def test_screen_ranks_candidates_like_the_pilot(exhaustive):
    """The one-call screen (slice-2 defect, η^k scaled from the baseline by (d/d_b)^(k+1), before
    any correction from measured candidates) against the pilot's measured η¹ of the same
    candidates: it ranks them alike (it only orders the search)."""
    from scipy.stats import spearmanr

    res = exhaustive
    pairs = [(c.screen["model_eta"][0], c.pilot_errors[0]) for c in res.candidates
             if c.screen and c.pilot_errors and c is not res.baseline]
    assert len(pairs) >= 10
    screened, measured = np.array(pairs).T
    assert spearmanr(screened, measured).statistic > 0.8


def test_default_budget_is_fifteen_percent_and_frugal(monkeypatch):
    """A problem that is not small gets 15 % of its serial fine solve; below 20 fine slices the
    search is frugal (two-slice pilot, contraction η¹/η⁰) and the report gives the fraction."""
    from parastokes.tuning import search

    monkeypatch.setattr(search, "SMALL_PROBLEM", 0.0)
    fine = integrate.Propagator(small_rod(), "rk2", 1e-6)
    res = tuning.tune(fine, t0=0.0, t1=8e-3, n_slices=4, cores=4, target=1e-6, space=SMALL)
    cost = res.report["cost"]
    assert cost["budget"] == pytest.approx(0.15 * cost["serial_fine_estimate"])
    assert cost["fraction"] == pytest.approx(cost["cpu_seconds"] / cost["serial_fine_estimate"])
    assert res.report["pilot"]["slices"] == 2
    assert any("frugal" in note for note in res.report["search"]["notes"])
    base = res.baseline
    assert len(base.pilot_errors) == 1 and 0 < base.contraction < 1  # η¹/η⁰
    # 15 % of 4 slices cannot hold the reference: the search stops after the baseline
    assert res.report["search"]["stopped"] == "budget"


def test_a_given_budget_is_respected():
    fine = integrate.Propagator(small_rod(), "rk2", 1e-6)
    budget = 4.0  # CPU seconds on this clock: the reference, the baseline and a few candidates
    res = tuning.tune(fine, t0=0.0, t1=8e-3, n_slices=4, cores=4, target=1e-6, space=PRUNING,
                      budget=budget, clock=time.process_time)
    largest = max(c.seconds for c in res.candidates)
    assert res.report["cost"]["cpu_seconds"] <= budget + largest


def test_the_budget_keeps_a_measurement_for_the_best_screened_candidate(monkeypatch):
    """With a clock that charges 1 per screen and 3 per measurement and room for 12, the search
    does not spend everything on screens (their optimistic bounds stay above every screened
    estimate): it measures the best screened candidate while a measurement still fits."""
    from parastokes.tuning import search as search_module
    from parastokes.tuning.search import _Search

    ticks = [0.0]
    screen, measure = _Search.screen, _Search.measure

    def charged(stage, cost):
        def run(self, cand):
            stage(self, cand)
            ticks[0] += cost
        return run

    monkeypatch.setattr(_Search, "screen", charged(screen, 1.0))
    monkeypatch.setattr(_Search, "measure", charged(measure, 3.0))
    # the search's estimates start from the time of a fine step; fixed here (an unloaded
    # machine's 1e-5 s for this rod), since the real one depends on the load and the path with it
    monkeypatch.setattr(search_module, "_seconds_per_step", lambda *args: 1e-5)
    fine = integrate.Propagator(small_rod(), "rk2", 1e-6)
    res = tuning.tune(fine, t0=0.0, t1=8e-3, n_slices=4, cores=4, target=1e-6,
                      space=Space(schemes=("euler",), step_fractions=(1.0,)), budget=15.0,
                      clock=lambda: ticks[0])
    assert res.report["search"]["stopped"] == "budget"
    measured = [c for c in res.candidates[1:] if c.pilot_errors]
    assert measured, "the budget went to screens only"
    # before its first measurement the search knows a measurement's cost only from the model (one
    # candidate's fine solves, 0.1 here), which this clock charges 3: the budget is exceeded by at
    # most that one stage (docs/tuning.md, "Bad input, budget and Ctrl-C")
    assert ticks[0] <= 15.0 + 3.0


def test_default_space_holds_the_structure_of_table5_g3():
    """(ε, a) with Richardson and five ε nodes (Table 5 G³) is in the default space."""
    rod = small_rod(7.0)
    space = Space()
    assert ("epsilon", "bending") in space.subsets(rod.params)
    found = [s for s in space.candidates(rod.params)
             if [n for n, _ in s.lagrange] == ["epsilon", "bending"] and s.m == 1
             and len(s.lagrange[0][1]) == 5]
    assert found


def _relative_nodes(system) -> list[dict]:
    theta0 = system.params
    space = Space(schemes=("euler",), richardson=(0,), step_fractions=(1.0,))
    return [{n: [round(v / theta0[n], 9) for v in values] for n, values in s.lagrange}
            for s in space.candidates(theta0, reach_table(system))]


def test_vesicle_space_holds_the_papers_vesicle_nodes():
    """The vesicle's own reach table puts the nodes of Tables 7-8 into the default space, which
    the rods' table (2-8 % in ε) cannot reach."""
    vesicle = models.vesicle(subdivisions=1)
    found = _relative_nodes(vesicle)
    assert {"epsilon": [1.2, 1.3, 1.4, 1.5], "stiffness": [0.8, 0.85, 0.9]} in found  # T8 G³
    assert {"epsilon": [1.35, 1.525, 1.7, 1.875]} in found                         # T7 G² (ε)
    assert {"epsilon": [1.6, 1.9, 2.2, 2.5], "stiffness": [0.6, 0.7, 0.8],
            "viscosity": [2.0, 2.5, 3.0]} in found                                # T7 G¹
    rods = Space(schemes=("euler",), richardson=(0,), step_fractions=(1.0,))
    assert max(max(v / vesicle.params[n] for v in values) for s in rods.candidates(vesicle.params)
               for n, values in s.lagrange if n == "epsilon") < 1.2


def test_rods_keep_the_default_reach():
    rod = small_rod(5.0)
    assert reach_table(rod) == REACH
    assert {"epsilon": [1.04, 1.05, 1.06, 1.07]} in _relative_nodes(rod)  # Table 4 G¹'s ε


@pytest.mark.parametrize("entry", [((0.1, 0.2), 0.5), ((0.1, 0.2, 1.5), 0.5),
                                   ((0.1, 0.2, 0.3), 0.0), "wide"])
def test_a_bad_reach_table_stops_before_the_search(entry):
    import dataclasses

    base = models.vesicle(subdivisions=1)

    @dataclasses.dataclass(frozen=True)
    class Odd(type(base)):
        tuning_reach = {"stiffness": entry}  # noqa: RUF012

    odd = Odd(**{f.name: getattr(base, f.name) for f in dataclasses.fields(base)})
    fine = integrate.Propagator(odd, "rk2", 1e-3)
    with pytest.raises(TuningError, match=r"Odd\.tuning_reach\['stiffness'\]"):
        tuning.tune(fine, t0=0.0, t1=1.0, n_slices=4, cores=4, target=1e-6)


def test_step_limit_is_relative_to_the_bodys_own_change():
    """A vesicle of twice the viscosity changes its area by more than the monitor's limit over a
    slice at the fine step (physics, not instability): the absolute test rejects even τ_f, the
    tuner's relative test finds a limit above the plain one (the limit grows with μ); on a
    vesicle at θ⁰ and on a rod, whose monitors barely move at τ_f, both tests agree."""
    vesicle = models.vesicle(subdivisions=2, epsilon_factor=0.5, stiffness=0.05)
    x0 = vesicle.initial_state()
    viscous = vesicle.with_params(viscosity=2 * vesicle.params["viscosity"])
    with pytest.raises(ValueError, match="dt_lo"):
        integrate.largest_stable_step(viscous, "euler", 2.5, 2e-3, 0.5, x0=x0, rtol=0.01)
    plain = stability.step_limit(vesicle, "euler", x0, 0.0, 2.5, 2e-3, 0.5)
    assert stability.step_limit(viscous, "euler", x0, 0.0, 2.5, 2e-3, 0.5) > 1.3 * plain
    absolute = integrate.largest_stable_step(vesicle, "euler", 2.5, 2e-3, 0.5, x0=x0, rtol=0.01)
    assert plain == pytest.approx(absolute, rel=0.02)
    rod = small_rod()
    args = ("euler", 2e-3, 1e-6, 2e-4)
    assert stability.step_limit(rod, args[0], rod.initial_state(), 0.0, *args[1:]) == (
        pytest.approx(integrate.largest_stable_step(rod, args[0], *args[1:], rtol=0.01), rel=0.02))


def test_screen_is_corrected_by_a_measured_candidate_of_the_same_structure():
    from types import SimpleNamespace

    from parastokes.tuning.search import Candidate, _Search

    search = _Search.__new__(_Search)  # only what rescreen reads
    search.pilot = SimpleNamespace(n_slices=3)
    search.n_slices, search.target, search.base_rho = 30, 1e-8, None
    measured = Settings("euler", (("epsilon", (1.04, 1.05)),), reach=1)
    search.calibrations = [(measured, [100.0, 1000.0])]

    def screened(settings: Settings) -> Candidate:
        cand = Candidate(settings)
        cand.screen = {"model_eta": [1e-10, 1e-12], "gamma_ratio": 0.01}
        search.rescreen(cand)
        return cand

    same = screened(Settings("euler", (("epsilon", (1.04, 1.05, 1.06)),), reach=1))
    assert same.screen["eta"] == pytest.approx([1e-8, 1e-9])
    assert same.screen["iterations"] == 2  # x 30/3 slices: 1e-7, then 1e-8 <= η*
    other_reach = screened(Settings("euler", (("epsilon", (1.02, 1.025)),), reach=0))
    assert other_reach.screen["eta"] == [1e-10, 1e-12]
    assert other_reach.screen["calibrated_by"] == "baseline"
    assert other_reach.screen["iterations"] == 1


def test_implicit_schemes_are_searched_beyond_the_explicit_step_limit():
    """An L-stable candidate (docs/stiff.md) gets a step limit up to half a slice, far above
    forward Euler's on the same rod, and is judged by the same measures (ρ(DG), the pilot's η^k,
    γ_G/γ_F) as every candidate; the report says why it wins or loses."""
    fine = integrate.Propagator(small_rod(), "rk2", 1e-6)
    space = Space(schemes=("euler", "ros2"), parameters=(), richardson=(0,),
                  step_fractions=(1.0,))
    res = tuning.tune(fine, t0=0.0, t1=2e-3, n_slices=8, cores=8, target=1e-6, space=space,
                      pilot_slices=2, budget=300.0)
    rows = {row["scheme"]: row for row in res.report["candidates"]}
    explicit, implicit = rows["euler"]["stability"], rows["ros2"]["stability"]
    assert implicit["step_limit"] >= 5 * explicit["step_limit"]
    assert rows["ros2"]["status"] in {"accepted", "not reached", "unstable"}
    assert rows["ros2"]["predicted"]["gamma_ratio"] > 0 or rows["ros2"]["reason"]


def test_the_baseline_schemes_are_euler_first_then_the_spaces_fixed_step_ones():
    assert search_module.baseline_schemes(("rk2", "euler", "ros2")) == ["euler", "rk2", "ros2"]
    assert search_module.baseline_schemes(("ros2", "rk2")) == ["ros2", "rk2"]
    assert search_module.baseline_schemes(("rk23",)) == ["euler"]  # adaptive only: Euler


#: F = RK4 above forward Euler's limit on the 21-node rod (tune's Euler limit there 1.71e-5 s):
#: no explicit coarse solver is stable at τ_f, as for the best-serial configs of docs/planning.md.
RK4_ABOVE_EULER = 1.8e-5


def test_a_baseline_unstable_at_the_fine_step_passes_to_the_next_scheme():
    fine = integrate.Propagator(small_rod(), "rk4", RK4_ABOVE_EULER)
    space = Space(schemes=("euler", "ros2"), parameters=(), richardson=(0,),
                  step_fractions=(1.0,))
    res = tuning.tune(fine, t0=0.0, t1=2e-3, n_slices=8, cores=8, target=1e-3, space=space,
                      pilot_slices=2, budget=300.0)
    assert ("the plain euler coarse solver is unstable even at τ_f: the baseline is the next "
            "fixed-step scheme") in res.report["search"]["notes"]
    rows = {row["scheme"]: row for row in res.report["candidates"]}
    assert rows["ros2"]["status"] == "accepted" and rows["euler"]["status"] == "rejected"
    # an explicit candidate's model step is Euler's limit (none here), not the implicit base's
    assert rows["euler"]["estimated_speedup"] == -math.inf
    assert res.chosen is not None and res.chosen.settings.scheme == "ros2"


def test_no_stable_baseline_names_every_scheme_tried_and_the_implicit_ones():
    fine = integrate.Propagator(small_rod(), "rk4", RK4_ABOVE_EULER)
    with pytest.raises(TuningError, match=r"the plain coarse solvers of euler, rk2 are unstable "
                       r"even at τ_f; add an implicit scheme to the schemes \(one of .*ros34pw2"):
        tuning.tune(fine, t0=0.0, t1=2e-3, n_slices=8, cores=8, target=1e-3,
                    space=Space(schemes=("euler", "rk2"), parameters=(), richardson=(0,)),
                    pilot_slices=2, budget=300.0)


def test_an_implicit_schemes_limit_search_starts_at_a_few_hundred_steps_per_slice(monkeypatch):
    """The lower bracket of the step-limit bisection: span / IMPLICIT_LO_STEPS for an implicit
    scheme (τ_f where that run fails, or where τ_f is larger), τ_f for an explicit one."""
    from types import SimpleNamespace

    tried = []

    def step_limit(system, scheme, x0, t0, span, lo, hi, stop=None):
        tried.append((scheme, lo, hi))
        if fail and lo > 1e-6:
            raise ValueError("not stable")
        return hi

    monkeypatch.setattr(stability, "step_limit", step_limit)
    pilot = SimpleNamespace(slice_length=0.04, fine=SimpleNamespace(dt=1e-6), t0=0.0, x0=None)
    fake = SimpleNamespace(pilot=pilot, limits={}, charge=None,
                           _grid_system=lambda grid: (None, None))
    fail = False
    assert search_module._Search.limit(fake, Settings("ros34pw2")) == 0.02
    assert tried == [("ros34pw2", 0.04 / search_module.IMPLICIT_LO_STEPS, 0.02)]
    tried.clear()
    search_module._Search.limit(fake, Settings("euler"))
    assert tried == [("euler", 1e-6, 0.04 / search_module.MIN_STEPS)]
    tried.clear()
    fail, fake.limits = True, {}
    assert search_module._Search.limit(fake, Settings("ros2")) == 0.02  # retried at τ_f
    assert [lo for _, lo, _ in tried] == [1e-4, 1e-6]
    tried.clear()
    pilot.fine.dt, fake.limits = 2e-4, {}  # τ_f above span / 400: τ_f alone
    search_module._Search.limit(fake, Settings("ros2"))
    assert [lo for _, lo, _ in tried] == [2e-4]
