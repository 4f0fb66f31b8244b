"""gamma_F and gamma_G per slice (parareal.measure_slice_costs, coarse_step_time) on inputs whose
costs are known by hand: the clock counts rate evaluations (or is advanced by fake solvers), so
every "time" is an exact count."""

from __future__ import annotations

import numpy as np
import pytest
from odes import ToySystem

from parastokes import integrate, parareal


@pytest.mark.parametrize(
    ("workers", "expected"),
    [(None, 3.5), (3, 3.5), (5, 3.5), (2, 4.5), (1, 6.5)],
)
def test_coarse_step_time_all_at_once_batched_or_serial(workers, expected):
    # N_G <= W: max(1, 3, 2) + 0.5; W = 2: batches [1, 3] and [2] -> 4 + 0.5; W = 1: 6 + 0.5
    assert parareal.coarse_step_time([1.0, 3.0, 2.0], 0.5, workers) == expected
    assert parareal.coarse_step_time(np.array([1.0, 3.0, 2.0]), 0.5, workers) == expected


def test_coarse_step_time_rejects_bad_input():
    with pytest.raises(ValueError, match="at least one"):
        parareal.coarse_step_time(np.array([]), 0.0, 4)
    with pytest.raises(ValueError, match="workers must be >= 1"):
        parareal.coarse_step_time([1.0], 0.0, 0)


class Counting(ToySystem):
    """ToySystem whose rate evaluations are counted: the measuring clock."""

    evaluations = 0

    def rates(self, t, state):
        Counting.evaluations += 1
        return super().rates(t, state)

    def with_params(self, **theta):
        return Counting(self.n_points, **{**self.params, **theta})

    def coarsened(self, factor):
        transfer = super().coarsened(factor)[1]
        return Counting(transfer.n_coarse, **self.params), transfer


def clock() -> float:
    return float(Counting.evaluations)


@pytest.mark.parametrize("grid", [None, 2])
def test_extrapolated_solver_costs_are_its_step_counts(grid):
    system = Counting(n_points=5, decay=1.0, a=0.3)
    fine = integrate.Propagator(system, "rk2", 1e-3)  # 1000 steps of 2 evaluations per slice
    # N_G = 4: two Lagrange nodes x Richardson q = 0, 1 with steps 0.01, 0.005 (100, 200 steps)
    coarse = parareal.extrapolated(
        system, "euler", 0.01, lagrange={"a": [0.1, 0.2]}, richardson={"m": 1, "r": 0.5}, grid=grid
    )
    costs = parareal.measure_slice_costs(
        fine, coarse, 0.0, 1.0, system.initial_state(),
        repeats=2, fine_steps=10, coarse_steps=5, clock=clock,
    )
    assert costs.fine == [2000.0, 2000.0]
    assert costs.auxiliary == [[100.0, 200.0, 100.0, 200.0]] * 2
    assert costs.auxiliary_steps == [(5, 100), (10, 200), (5, 100), (10, 200)]
    assert costs.fine_steps == (10, 1000)
    assert costs.overhead == [0.0, 0.0]  # splitting, summing, projecting: no rate evaluation
    assert costs.linearity == [1.0, 1.0]
    assert costs.n_auxiliary == 4
    assert costs.task_ratio() == pytest.approx(200 / 2000)
    assert costs.gamma_ratio(2) == pytest.approx(300 / 2000)  # batches [100, 200], [100, 200]
    assert costs.gamma_ratio(1) == pytest.approx(600 / 2000)
    record = costs.as_dict()
    assert record["gamma_F_s"] == 2000.0 and record["gamma_ratio"] == pytest.approx(0.1)


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


class FakeSolver:
    """A fixed-step solver whose call costs ``per_call + per_step * steps`` on ``clock``."""

    def __init__(self, clock: Clock, dt: float, per_step: float, per_call: float) -> None:
        self.clock, self.dt, self.per_step, self.per_call = clock, dt, per_step, per_call

    def n_steps(self, t_start: float, t_end: float) -> int:
        return max(1, round((t_end - t_start) / self.dt))

    def __call__(self, t_start, t_end, x):
        self.clock.now += self.per_call + self.per_step * self.n_steps(t_start, t_end)
        return x


def test_per_call_cost_shows_in_the_linearity_check():
    clock = Clock()
    fine = FakeSolver(clock, 0.01, 1.0, 4.0)  # 100 steps per slice; t(n) = n + 4
    coarse = FakeSolver(clock, 0.1, 1.0, 0.0)  # a plain solver: 10 steps per slice
    costs = parareal.measure_slice_costs(
        fine, coarse, 0.0, 1.0, np.zeros(3), repeats=1, fine_steps=10, coarse_steps=5, clock=clock
    )
    # t(10) = 14, t(20) = 24: (14 + 24) / 30 steps x 100 steps; linearity 24 / (2 x 14)
    assert costs.fine == [pytest.approx(38 / 30 * 100)]
    assert costs.linearity == [pytest.approx(24 / 28)]
    assert costs.auxiliary == [[10.0]] and costs.auxiliary_steps == [(5, 10)]
    assert costs.overhead == [0.0]


def test_measure_slice_costs_rejects_no_repeats():
    clock = Clock()
    solver = FakeSolver(clock, 0.1, 1.0, 0.0)
    with pytest.raises(ValueError, match="repeats must be >= 1"):
        parareal.measure_slice_costs(solver, solver, 0.0, 1.0, np.zeros(1), repeats=0)


def test_a_richardson_ratio_near_one_is_timed_with_the_slices_coefficients():
    """With r = 0.995 the step counts of the 50-step probe span coincide (50 and 50) where the
    slice's differ (1000 and 1005); the probe combines with the slice's coefficients
    (regression: it raised the Richardson rule's ValueError on the short span)."""
    system = ToySystem(n_points=2, decay=1.0)
    coarse = parareal.extrapolated(system, "euler", 1e-3, richardson={"m": 1, "r": 0.995})
    fine = integrate.Propagator(system, "rk2", 1e-4)
    costs = parareal.measure_slice_costs(fine, coarse, 0.0, 1.0, system.initial_state(),
                                         repeats=1)
    assert costs.auxiliary_steps == [(50, 1000), (50, 1005)]
    assert len(costs.auxiliary[0]) == 2 and min(costs.auxiliary[0]) > 0


def test_an_empty_interval_is_the_projected_state_as_for_a_plain_propagator():
    # regression: the extrapolated solver divided by its zero step count
    system = ToySystem(n_points=2, decay=1.0)
    coarse = parareal.extrapolated(system, "euler", 0.1, lagrange={"a": [0.9, 1.1]},
                                   richardson={"m": 1, "r": 0.5})
    x = system.initial_state()
    plain = integrate.Propagator(system, "euler", 0.1)(0.5, 0.5, x)
    np.testing.assert_array_equal(coarse(0.5, 0.5, x), plain)
    assert coarse.split(0.5, 0.5, x) is None
