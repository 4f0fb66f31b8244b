"""The numbers of docs/validation.md section 1 (Figs. 3 and 5 on the shortened rod), recomputed at
the documented size (``validation.rod_extrapolation.FULL``: M = 61, T = 1e-2, N_c = 5) and compared
with ``docs/numbers.toml`` (``[rod_fig3]``, ``[rod_fig5]``).

The default run recomputes the rows the page's statements rest on: Fig. 3's plain solver and
epsilon^1 = 5.1, 5.6 sigma_f (tau_max by bisection, tau_c and the edge by the script's own search,
eta^1 at both; tau_c grows x1.43), Fig. 5's N_eps = 1 and 4 (Richardson lowers eta^1 37-fold) and
G_{eps^0, tau_c}; every Lagrange weight sum. The slow test reruns the whole script and compares
every registered number.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from documented import check, values

from validation import rod_extrapolation as script

SETUP = script.FULL
FIG3_ROWS = (0, 1, 4)  # the plain G_{eps^0}, eps^1 = 5.1 and 5.6 sigma_f
FIG5_ROWS = (0, 3)  # N_eps = 1, 4


@pytest.fixture(scope="module")
def reference():
    return script.reference_solution(SETUP)


def _fig3_row(index: int, reference) -> dict:
    rod = SETUP.rod()
    if index == 0:
        return script._steps_and_errors(
            SETUP, lambda tau: script._euler(rod, tau),
            script._largest_stable_step(SETUP, rod.epsilon), reference,
        )
    nodes = script.epsilon_nodes(SETUP, SETUP.fig3_epsilon1[index - 1], SETUP.fig3_n_nodes)
    row = script._steps_and_errors(
        SETUP, lambda tau: script._euler(rod, tau, lagrange={"epsilon": nodes}),
        script._largest_stable_step(SETUP, nodes[0]), reference,
    )
    row["plain_within_limit"] = script.within_limit(
        SETUP, script._euler(rod, row["tau_c_over_tau_f"] * SETUP.tau_f)
    )
    return row


def test_fig3_weight_sums():
    rod = SETUP.rod()
    sums = [1.0] + [
        float(np.abs(script.parareal.lagrange_weights(
            rod.epsilon, script.epsilon_nodes(SETUP, e, SETUP.fig3_n_nodes))).sum())
        for e in SETUP.fig3_epsilon1
    ]
    check("rod_fig3", "sum_abs_weights", sums)


def test_fig3_steps_and_first_iterates(reference):
    rows = {i: _fig3_row(i, reference) for i in FIG3_ROWS}
    for i, row in rows.items():
        check("rod_fig3", "tau_max", row["tau_max_over_tau_f"], i)
        check("rod_fig3", "tau_c", row["tau_c_over_tau_f"], i)
        check("rod_fig3", "eta1", row["eta1"], i)
        check("rod_fig3", "edge_tau_c", row["edge"]["tau_c_over_tau_f"], i)
        check("rod_fig3", "edge_eta1", row["edge"]["eta1"], i)
        if i:
            check("rod_fig3", "plain_within_limit", row["plain_within_limit"], i)
    check("rod_fig3", "tau_c_growth", rows[4]["tau_c_over_tau_f"] / rows[1]["tau_c_over_tau_f"])
    monitor = max(SETUP.rod().monitor(x) for x in reference)
    check("rod_fig3", "reference_monitor_percent", 100 * monitor)


def test_fig5_first_iterates(reference):
    rod = SETUP.rod()
    tau_c, r = SETUP.fig5_tau_ratio * SETUP.tau_f, SETUP.richardson_r
    plain = script.first_iteration(SETUP, script._euler(rod, tau_c), reference)
    check("rod_fig5", "plain_eta1", plain["eta1"])
    for i in FIG5_ROWS:
        lagrange = {"epsilon": script.epsilon_nodes(SETUP, SETUP.fig5_epsilon1, i + 1)}
        g3 = script._euler(rod, tau_c, lagrange=lagrange)
        g4 = script._euler(rod, tau_c / r, lagrange=lagrange, richardson={"m": 1, "r": r})
        eta3 = script.first_iteration(SETUP, g3, reference)["eta1"]
        eta4 = script.first_iteration(SETUP, g4, reference)["eta1"]
        check("rod_fig5", "g3_eta1", eta3, i)
        check("rod_fig5", "g4_eta1", eta4, i)
        check("rod_fig5", "g3_over_g4", eta3 / eta4, i)
        steps, weights = g4.plan(0.0, SETUP.slice_length)
        check("rod_fig5", "richardson_steps", list(steps / SETUP.tau_f))
        check("rod_fig5", "richardson_weights", list(weights))


def test_step_limit_over_a_shorter_span():
    """The limit shrinks with the span: 12.9 tau_f over [0, 1e-3] against 12.2 over [0, 1e-2]."""
    short = dataclasses.replace(SETUP, t_end=1e-3)
    limit = script._largest_stable_step(short, short.rod().epsilon) / SETUP.tau_f
    check("rod_step_limits", "tau_max_span_1e3", limit)


@pytest.mark.slow
def test_step_limits_of_the_paper_rod():
    """M = 301 (L = 60) has the same limits as M = 61: the rod length does not set them."""
    paper = dataclasses.replace(SETUP, n_points=301, length=60.0)
    limits = [script._largest_stable_step(paper, f * paper.sigma_f) / SETUP.tau_f for f in (5, 5.6)]
    check("rod_step_limits", "tau_max_m301", limits)


@pytest.mark.slow
def test_every_section_1_number():
    """The whole script (about 4 min on two shared cores), every registered number."""
    numbers = script.documented_numbers(script.run_all(SETUP, log=lambda _line: None))
    for group, computed in numbers.items():
        assert set(computed) == set(values(group))
        for name, value in computed.items():
            check(group, name, value)
