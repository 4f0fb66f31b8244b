"""``plan``'s coarse solver (parastokes.planning.coarse): the implicit ladder searched first,
the pilot's size, α measured on the full problem, the ranking and what the rows rest on."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest
from test_plan import CONFIG

from parastokes import cli, config, integrate, models, tuning
from parastokes.core.contracts import rounds
from parastokes.planning import coarse, routes
from parastokes.planning.baseline import Run
from parastokes.planning.command import pilot_points, rests_on
from parastokes.tuning import Settings, Space
from parastokes.tuning.search import Candidate, rank
from parastokes.tuning.space import TuningError, parse_space

SIGMA = 0.2  # the 21-node, 4 μm rod's spacing (tests/test_tune.py)


# ---- the ladder, and its place in tune's order ---------------------------------------------
def test_the_ladder_is_the_plain_scheme_at_each_fraction_of_the_safe_step():
    ladder = coarse.leading("ros34pw2")
    assert [s.step_fraction for s in ladder] == list(coarse.IMPLICIT_FRACTIONS)
    assert all(s.plain and s.scheme == "ros34pw2" and s.dt is None for s in ladder)
    # the frontier's winners lie on it: 0.18 (the rod of 601 points) and 0.3 (Table 5)
    assert min(coarse.IMPLICIT_FRACTIONS) <= 0.18 and 0.3 in coarse.IMPLICIT_FRACTIONS


def test_rank_puts_given_then_leading_then_the_rest():
    plain = Settings("euler")
    assert rank(Candidate(plain, given=True)) == 0
    assert rank(Candidate(plain, leading=True)) == 1
    assert rank(Candidate(plain, given=True, leading=True)) == 0
    assert rank(Candidate(plain)) == 2


def test_leading_is_not_a_tune_option_and_its_schemes_are_checked():
    with pytest.raises(TuningError, match="unknown option 'leading'"):
        parse_space({"leading": ["ros34pw2"]})
    with pytest.raises(TuningError, match="unknown scheme 'nope'"):
        Space(leading=(Settings("nope"),)).check({}, lambda factor: True)


class Order(tuning.Progress):
    """The labels of the candidates in the order the search finished them."""

    def __init__(self) -> None:
        self.labels: list[str] = []

    def advance(self, label: str) -> None:
        self.labels.append(label)


def test_tune_finishes_the_leading_candidates_before_any_other():
    """With Euler (and its Lagrange candidates, ranked higher by the explicit model) in the
    space, the ladder of plain ROS2 is measured first: one step already in the space (1.0,
    moved forward, not repeated) and one not in it (0.3)."""
    fine = integrate.Propagator(models.rod_swimmer(n_points=21, length=4.0,
                                                   epsilon=5.0 * SIGMA), "rk2", 1e-6)
    ladder = (Settings("ros2", step_fraction=1.0), Settings("ros2", step_fraction=0.3))
    space = Space(schemes=("euler", "ros2"), parameters=("epsilon",), reach=(1,), nodes=(2,),
                  richardson=(0,), step_fractions=(1.0,), leading=ladder)
    order = Order()
    res = tuning.tune(fine, t0=0.0, t1=2e-3, n_slices=8, cores=8, target=1e-6, space=space,
                      pilot_slices=2, budget=300.0, progress=order)
    rows = [c for c in res.candidates if c.leading]
    assert sorted(c.settings.step_fraction for c in rows) == [0.3, 1.0]
    labels = [c.settings.label() for c in res.candidates]
    assert len(labels) == len(set(labels))  # nothing repeated
    assert set(order.labels[:2]) == {"ros2, plain", "ros2, 0.3·τ_safe"}
    assert len(order.labels) > 2  # the others came after them
    report = {row["label"]: row for row in res.report["candidates"]}
    assert report["ros2, 0.3·τ_safe"]["leading"] and not report["euler, plain"]["leading"]
    # measured, not pruned, though the explicit model ranks them below Euler's
    assert all(c.status in ("accepted", "rejected") for c in rows)


# ---- the pilot's size ----------------------------------------------------------------------
def test_full_pilot_when_f_over_its_window_is_at_most_a_hundredth_of_the_budget():
    # F over T 40 s, 40 slices, a pilot of 3: 3 s = a hundredth of 300 s
    assert coarse.full_pilot(40.0, 40, 3, 300.0)
    assert not coarse.full_pilot(40.01, 40, 3, 300.0)
    assert coarse.full_pilot(40.0, 40, 2, 200.0)
    assert not coarse.full_pilot(40.0, 40, 3, 299.9)


def _rod(n_points: int, pilot: int | None = None):
    text = CONFIG.replace("n_points = 21", f"n_points = {n_points}")
    if pilot is not None:
        text += f"pilot_points = {pilot}\n"
    return config.loads(text, "rod.toml")[0]


def test_pilot_points_are_the_runs_where_f_over_the_window_fits():
    fine = Run("rk2", 1e-6, None, "F", "reference", 1e-9, 40.0, 40.0)
    full, why = pilot_points(_rod(121), fine, 40, 300.0)
    assert full == 121 and "the full problem" in why and "3 s" in why
    short, why = pilot_points(_rod(121), fine, 40, 299.0)
    assert short == 61 and "a rod of 61 nodes" in why and "3 s" in why
    # no budget: tune's default, 15 % of F (6 s): a window of 3 s is too dear
    assert pilot_points(_rod(121), fine, 40, None)[0] == 61
    assert pilot_points(_rod(121, pilot=31), fine, 40, 300.0) == (
        31, "the configuration's [tune] pilot_points")
    assert pilot_points(_rod(41), fine, 40, 1.0)[0] is None  # not longer than a pilot


# ---- α on the full problem -----------------------------------------------------------------
class Clock:
    """A CPU clock advanced by fake propagators: ``rate`` seconds per step of ``step``."""

    def __init__(self) -> None:
        self.now = 0.0
        self.calls: list[float] = []

    def __call__(self) -> float:
        return self.now

    def propagator(self, rate: float, step: float):
        def run(t0: float, t1: float, x: np.ndarray) -> np.ndarray:
            self.calls.append(t1 - t0)
            self.now += rate * round((t1 - t0) / step)
            return x

        return run


def test_cpu_per_time_doubles_the_span_until_it_takes_enough():
    clock = Clock()
    rate, span = coarse.cpu_per_time(clock.propagator(0.004, 1e-3), np.zeros(3), 0.0, 1e-3,
                                     1.0, clock)
    assert rate == pytest.approx(4.0)  # 0.004 s per step of 1e-3
    # 20 steps untimed first, then 20, 40 steps (0.08, 0.16 s), then 80 (0.32 s >= 0.2)
    assert clock.calls == pytest.approx([0.02, 0.02, 0.04, 0.08]) and span == pytest.approx(0.08)
    clock = Clock()
    _, span = coarse.cpu_per_time(clock.propagator(1e-6, 1e-3), np.zeros(3), 0.0, 1e-3, 0.05,
                                  clock)
    assert span == 0.05 and clock.calls[-1] == 0.05  # never beyond a slice


def test_cpu_per_time_over_a_whole_slice_times_it_at_once():
    clock = Clock()
    rate, span = coarse.cpu_per_time(clock.propagator(1e-6, 1e-3), np.zeros(3), 0.0, 1e-3,
                                     0.5, clock, whole=True)
    assert clock.calls == pytest.approx([0.02, 0.5]) and span == 0.5
    assert rate == pytest.approx(1e-3)


def test_full_alpha_is_the_ratio_of_the_rates_in_waves_of_auxiliary_solvers(monkeypatch):
    """G of N_G = 3 auxiliary solvers (all in one call, 3x a plain step each) on 2 cores: two
    waves of one solver's share, over F's rate: the direct computation."""
    clock = Clock()
    settings = Settings("euler", lagrange=(("epsilon", (1.1, 1.2, 1.3)),), dt=1e-3)
    monkeypatch.setattr(Settings, "build", lambda self, system: clock.propagator(0.03, 1e-3))
    fine_run = clock.propagator(1e-3, 1e-5)

    class Fine:
        dt = 1e-5

        def __call__(self, t0, t1, x):
            return fine_run(t0, t1, x)

    alpha, measured = coarse.full_alpha(settings, None, Fine(), np.zeros(3), 0.0, 0.1, 2, clock)
    g_rate, f_rate = 0.03 / 1e-3, 1e-3 / 1e-5  # CPU seconds per unit time: 30 and 100
    assert measured["coarse_cpu_per_time"] == pytest.approx(g_rate)
    assert measured["fine_cpu_per_time"] == pytest.approx(f_rate)
    assert alpha == pytest.approx(rounds(3, 2) * (g_rate / 3) / f_rate)  # 0.2
    assert alpha == pytest.approx(0.2)


def test_full_alpha_of_f_against_itself_is_about_one():
    """On the 21-node rod, G = F's own scheme and step: the two rates are the same run's."""
    system = models.rod_swimmer(n_points=21, length=4.0, epsilon=5.0 * SIGMA)
    fine = integrate.Propagator(system, "euler", 1e-6)
    alpha, measured = coarse.full_alpha(Settings("euler", dt=1e-6), system, fine,
                                        system.initial_state(), 0.0, 0.05, 2)
    assert 0.6 < alpha < 1.6
    assert measured["coarse_span"] > 0 and measured["fine_span"] > 0


# ---- the ranking, and what a row rests on --------------------------------------------------
def _accepted(label_alpha_k):
    out = []
    for fraction, alpha, k in label_alpha_k:
        cand = Candidate(Settings("ros34pw2", step_fraction=fraction, dt=1e-4 * fraction),
                         status="accepted")
        cand.gamma_ratio, cand.iterations, cand.pilot_errors = alpha, k, [1e-6, 1e-8]
        out.append(cand)
    return out


def test_ranking_follows_the_full_problems_alpha_not_the_pilots():
    """On the pilot 1.0 looks cheapest (α 0.06 against 0.3); on the full problem 0.3 is
    (0.04 at K = 1 against 0.05 at K = 3): the routes take the full problem's."""
    cands = _accepted([(1.0, 0.06, 3), (0.3, 0.3, 1)])
    full = {1.0: 0.05, 0.3: 0.04}

    def wall(alpha, k):
        return routes.parareal_wall(1.0, alpha, k, 40, "pipelined")

    rows = coarse.ranked(cands, lambda c: (full[c.settings.step_fraction], "full", None), wall)
    assert [r.settings.step_fraction for r in rows] == [0.3, 1.0]
    assert rows[0].alpha == 0.04 and rows[0].iterations == 1
    pilot = coarse.ranked(cands, lambda c: (c.gamma_ratio, "pilot", None), wall)
    assert [r.settings.step_fraction for r in pilot] == [1.0, 0.3]
    row = rows[0].as_dict()
    assert (row["alpha"], row["pilot_alpha"], row["alpha_source"]) == (0.04, 0.3, "full")


def test_the_first_row_is_measured_again_until_it_holds_its_place():
    """A's α over a whole slice is worse than B's: B is measured too and stays first; a row
    that blows up over the slice goes last; each row at most once."""
    def wall(alpha, k):
        return routes.parareal_wall(1.0, alpha, k, 40, "pipelined")

    def rows():
        cands = _accepted([(1.0, 0.5, 1), (0.6, 0.5, 1), (0.3, 0.5, 1)])
        first = {1.0: 0.01, 0.6: 0.02, 0.3: 0.04}
        return coarse.ranked(cands, lambda c: (first[c.settings.step_fraction], "few", None),
                             wall)

    again = {1.0: (0.03, "whole", None), 0.6: (0.025, "whole", None),
             0.3: (0.001, "whole", None)}
    seen = []

    def measure(row):
        seen.append(row.settings.step_fraction)
        return again[row.settings.step_fraction]

    out = coarse.confirmed(rows(), measure, wall)
    assert seen == [1.0, 0.6] and [r.settings.step_fraction for r in out] == [0.6, 1.0, 0.3]
    assert (out[0].alpha, out[0].alpha_source) == (0.025, "whole")
    assert out[2].alpha == 0.04  # (never measured again: it never came first)
    again[1.0] = (None, "blew up", None)
    seen.clear()
    out = coarse.confirmed(rows(), measure, wall)
    assert seen == [1.0, 0.6] and [r.settings.step_fraction for r in out] == [0.6, 0.3, 1.0]
    assert out[-1].alpha is None and out[-1].alpha_source == "blew up"
    assert coarse.confirmed([], measure, wall) == []
    seen.clear()  # every row blew up over a few steps: none is run again
    dead = coarse.ranked(_accepted([(1.0, 0.5, 1)]), lambda c: (None, "blew up", None), wall)
    assert coarse.confirmed(dead, measure, wall)[0].alpha is None and seen == []


def test_a_parareal_row_says_what_its_alpha_and_k_rest_on():
    cand = _accepted([(0.3, 0.3, 1)])[0]
    row = coarse.Coarse(cand, 0.04, "measured on the full problem (601 points: ...)", 1)
    pilot = SimpleNamespace(system=SimpleNamespace(positions=lambda x: x.reshape(-1, 3)),
                            x0=np.zeros(61 * 3), n_slices=3)
    text = rests_on(row, pilot, Run("rk2", 1e-6, None, "F", "reference", 1e-9, 10.0, 10.0))
    assert text.startswith("α measured on the full problem (601 points")
    assert "K from tune's pilot η^k = 1e-06, 1e-08 (61 points, 3 slices)" in text
    assert "G = ros34pw2, 0.3·τ_safe at 3e-05 s" in text


def test_a_shortened_pilot_gives_alpha_measured_on_the_full_problem(tmp_path, capsys):
    """End to end on the 21-node rod with a pilot of 11 nodes: every accepted coarse solver's
    α is measured again on the 21 nodes, and the Parareal rows say so."""
    source = tmp_path / "rod.toml"
    source.write_text(CONFIG + "pilot_points = 11\n")
    out = tmp_path / "PLAN.toml"
    assert cli.main(["plan", str(source), "--cores", "2", "--target", "1e-6", "--out",
                     str(out), "--budget", "6"]) == 0
    assert "tune's pilot: the configuration's [tune] pilot_points" in capsys.readouterr().out
    plan = json.loads(out.with_suffix(".json").read_text())
    ranked = plan["coarse"]["ranked"]
    assert plan["coarse"]["pilot_points"] == 11 and ranked
    # the pilot's steps of 11 nodes do not all hold on 21: those that blow up go last
    usable = [row["alpha"] is not None for row in ranked]
    assert usable == sorted(usable, reverse=True) and usable[0]
    for row in ranked:
        if row["alpha"] is None:
            assert row["alpha_source"].startswith("blew up on the full problem over a ")
            continue
        assert row["alpha_source"].startswith("measured on the full problem (21 points")
        assert row["full_problem"]["coarse_span"] > 0
    first = ranked[0]  # its G run over a whole slice of the full problem
    assert "(a whole slice)" in first["alpha_source"]
    assert first["full_problem"]["coarse_span"] == pytest.approx(0.001)
    parareal = next(r for r in plan["routes"] if r["route"] == "parareal (pipelined)")
    assert parareal["settings"]["alpha"] == ranked[0]["alpha"]
    assert "(11 points, " in parareal["rests_on"]
