"""The cost model of the two schedules: closed formulas and the discrete-event simulation."""

import itertools

import numpy as np
import pytest

from parastokes import parareal
from parastokes.parareal.schedule_model import simulate


@pytest.mark.parametrize(
    ("n", "k", "alpha"), [(1, 1, 0.5), (4, 2, 0.1), (8, 3, 0.3), (40, 2, 0.025), (64, 4, 0.01)]
)
def test_standard_with_one_worker_per_slice_is_eq_12(n, k, alpha):
    # W = P, N_G = 1, no overhead: the simulated Algorithm 1 is eq. 12 exactly
    sim = simulate("standard", n, k, n, alpha)
    assert sim.wall == pytest.approx(parareal.parareal_runtime(alpha, 1.0, k, n), rel=1e-12)
    assert sim.speedup == pytest.approx(parareal.speedup(alpha, 1.0, k, n), rel=1e-12)


@pytest.mark.parametrize(("n", "k", "alpha"), [(4, 2, 0.1), (8, 3, 0.3), (40, 2, 0.025)])
def test_pipelined_without_waiting_is_the_critical_path(n, k, alpha):
    # unlimited workers: K gamma_F + (N - K) gamma_G, also with N_G auxiliary solves in parallel
    for n_aux in (1, 3):
        sim = simulate("pipelined", n, k, None, alpha, n_auxiliary=n_aux)
        assert sim.wall == pytest.approx(parareal.pipelined_runtime(alpha, 1.0, k, n), rel=1e-12)


@pytest.mark.parametrize(
    ("n", "k", "alpha"), list(itertools.product([8, 40], [1, 2, 4], [0.01, 0.3]))
)
def test_pipelined_on_p_workers_between_critical_path_and_closed_formula(n, k, alpha):
    sim = simulate("pipelined", n, k, n, alpha)
    critical = parareal.pipelined_runtime(alpha, 1.0, k, n)
    slice_owned = n * alpha + k * (1.0 + alpha)  # the wall time behind speedup_pipelined
    assert critical - 1e-12 <= sim.wall <= slice_owned + 1e-12
    assert sim.speedup >= parareal.speedup_pipelined(alpha, k, n) - 1e-12


@pytest.mark.parametrize(("k", "alpha"), [(1, 0.1), (2, 0.3), (4, 0.05)])
def test_closed_formulas_are_the_large_p_limit_of_the_simulation(k, alpha):
    # they differ from the simulated schedules by O(K / P)
    n = 400
    for schedule, formula in (
        ("standard", parareal.speedup_standard),
        ("pipelined", parareal.speedup_pipelined),
    ):
        sim = simulate(schedule, n, k, n, alpha)
        assert sim.speedup == pytest.approx(formula(alpha, k, n), rel=2.5 * k / n)


def test_closed_formulas_values():
    # anchors.md: P = 50, K = 3, alpha = 1/8: standard 1.79, pipelined 5.19
    assert parareal.speedup_standard(1 / 8, 3, 50) == pytest.approx(1.79, abs=0.005)
    assert parareal.speedup_pipelined(1 / 8, 3, 50) == pytest.approx(5.19, abs=0.005)


def test_hand_computed_two_slices():
    # N = 2, K = 1, alpha = 0.5.  One worker: G1 G2 | F1 | G2' | F2 in either order: 3.5.
    assert simulate("standard", 2, 1, 1, 0.5).wall == pytest.approx(3.5)
    assert simulate("pipelined", 2, 1, 1, 0.5).wall == pytest.approx(3.5)
    # Two workers. Standard: G1 G2 (0-1), F1 || F2 (1-2), G2' (2-2.5).
    assert simulate("standard", 2, 1, 2, 0.5).wall == pytest.approx(2.5)
    # Pipelined: G1 || F1 (0-0.5, 0-1), G2 (0.5-1), then G2' || F2 (1-1.5, 1-2): 2.0.
    sim = simulate("pipelined", 2, 1, 2, 0.5)
    assert sim.wall == pytest.approx(2.0)
    starts = {(kind, n, k): (start, end) for kind, n, k, start, end, _ in sim.tasks}
    assert starts == {
        ("coarse", 1, 0): (0.0, 0.5),
        ("fine", 1, 1): (0.0, 1.0),
        ("coarse", 2, 0): (0.5, 1.0),
        ("coarse", 2, 1): (1.0, 1.5),
        ("fine", 2, 1): (1.0, 2.0),
    }


def test_hand_computed_auxiliary_rounds_and_overhead():
    # N_G = 3 auxiliary solves of 0.25 on 2 workers: every coarse step takes 2 rounds (0.5).
    # Standard, N = 2, K = 1: coarse sweep 1.0, fine sweep 1.0, one coarse step 0.5.
    assert simulate("standard", 2, 1, 2, 0.25, n_auxiliary=3).wall == pytest.approx(2.5)
    # An overhead of 0.1 per task: 2 rounds of 0.35 per coarse step, 1.1 per fine wave.
    sim = simulate("standard", 2, 1, 2, 0.25, n_auxiliary=3, overhead=0.1)
    assert sim.wall == pytest.approx(3 * 0.7 + 1.1)
    assert sum(kind == "auxiliary" for kind, *_ in sim.tasks) == 3 * 3


def test_fewer_workers_than_slices_gives_waves():
    # standard, W = 2 < P = 4, K = 1, alpha -> 0: the fine sweep runs in 2 waves
    assert simulate("standard", 4, 1, 2, 0.0).wall == pytest.approx(2.0)
    # pipelined on one worker does all the work in sequence: 4 + 3 + 2 coarse, 4 + 3 fine steps
    sim = simulate("pipelined", 4, 2, 1, 0.1)
    assert sim.wall == pytest.approx(0.1 * (4 + 3 + 2) + (4 + 3))


def test_more_workers_than_slices_helps_only_the_auxiliary_solves():
    base = simulate("pipelined", 8, 2, 8, 0.05, n_auxiliary=8).wall
    wide = simulate("pipelined", 8, 2, 64, 0.05, n_auxiliary=8).wall
    assert wide < base
    assert wide == pytest.approx(parareal.pipelined_runtime(0.05, 1.0, 2, 8))


def test_pipelined_never_slower_than_standard():
    cases = itertools.product([4, 16], [1, 3], [1, 4, 16], [0.02, 0.3], [1, 4])
    for n, k, w, alpha, n_aux in cases:
        std = simulate("standard", n, k, w, alpha, n_auxiliary=n_aux).wall
        pipe = simulate("pipelined", n, k, w, alpha, n_auxiliary=n_aux).wall
        assert pipe <= std + 1e-12, (n, k, w, alpha, n_aux)


def test_predict_schedules_rows():
    rows = parareal.predict_schedules(0.025, 2, [40, 128], n_auxiliary=4)
    assert [r["cores"] for r in rows] == [40, 128]
    for row in rows:
        assert row["alpha"] == pytest.approx(0.025)
        assert row["pipelined"] > row["standard"]
        assert row["pipelined_formula"] > row["standard_formula"]
    assert parareal.predict_schedules(0.1, 3, [2], n_auxiliary=4)[0]["alpha"] == pytest.approx(0.2)


def test_bad_input():
    with pytest.raises(ValueError, match="schedule"):
        simulate("eager", 4, 1, 4, 0.1)
    with pytest.raises(ValueError, match="workers"):
        simulate("standard", 4, 1, 0, 0.1)
    with pytest.raises(ValueError, match="coarse_cost"):
        simulate("standard", 4, 1, 4, -0.1)
    with pytest.raises(ValueError, match="n_auxiliary"):
        simulate("standard", 4, 1, 4, 0.1, n_auxiliary=0)
    with pytest.raises(ValueError, match="core counts"):
        parareal.predict_schedules(0.1, 1, [0])
    with pytest.raises(ValueError, match="workers"):
        parareal.predict_schedules(0.1, 2, [4], workers=0)
    with pytest.raises(ValueError, match="workers"):
        simulate("standard", 4, 1, 2.5, 0.1)
    with pytest.raises(ValueError, match="coarse_cost"):
        simulate("standard", 4, 1, 4, "a")


def test_numpy_integers_are_counts():
    assert simulate("standard", np.int64(4), np.int64(2), np.int64(4), 0.1).wall == (
        simulate("standard", 4, 2, 4, 0.1).wall
    )


def test_the_handover_latency_is_the_median_wait_of_coarse_steps_for_their_inputs():
    """Hand-computed records ``[kind, n, k, start, end, worker]``: G(2, 0) waits 0.1 after G(1, 0);
    G(3, 1) waits 0.3 after the last of F(2, 1), G(2, 1), G(2, 0); G(3, 2) 0.2 after F(2, 2)
    (exact); G(2, 1) has no complete recorded input (slice 1 of iteration 1 is exact) and G(1, *)
    none at all: the median of (0.1, 0.3, 0.2) is 0.2. A split step counts from its first
    auxiliary solve's start and its last one's end."""
    tasks = [
        ["coarse", 1, 0, 0.0, 1.0, 0],
        ["auxiliary", 2, 0, 1.1, 1.5, 0],
        ["auxiliary", 2, 0, 1.2, 2.0, 1],
        ["fine", 2, 1, 0.5, 2.5, 1],
        ["coarse", 2, 1, 2.0, 2.6, 0],
        ["coarse", 3, 1, 2.9, 3.0, 0],
        ["fine", 2, 2, 3.0, 4.0, 1],
        ["coarse", 3, 2, 4.2, 4.5, 0],
    ]
    assert parareal.handover_latency(tasks) == pytest.approx(0.2)
    assert parareal.handover_latency([]) == 0.0
