"""Algorithm 1 on simple ODEs with known solutions."""

import itertools
import logging
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from odes import Exact, Logistic, Recording, RecordingExecutor, Stepper, decay, oscillator

from parastokes import parareal

T0, T1 = 0.0, 2.0


PROBLEMS = {
    "decay": (decay(1.5, dim=2), np.array([1.0, -2.0])),
    "oscillator": (oscillator(2.0), np.array([1.0, 0.0])),
    "logistic": (Logistic(3.0), np.array([0.1])),
}


def _solvers(problem):
    return Stepper(problem, 1e-2, order=4), Stepper(problem, 0.1, order=1)


@pytest.mark.parametrize("name", sorted(PROBLEMS))
def test_exactness_after_k_iterations(name):
    problem, x0 = PROBLEMS[name]
    fine, coarse = _solvers(problem)
    n = 6
    serial = parareal.serial_solution(fine, x0, T0, T1, n)
    # the fine solver itself is accurate: compare with the known solution
    np.testing.assert_allclose(serial[-1], problem.exact(T0, T1, x0), rtol=1e-8, atol=1e-10)
    for k in range(1, n + 1):
        res = parareal.run(fine, coarse, x0, T0, T1, n, tol=0.0, max_iterations=k)
        assert res.iterations == k
        np.testing.assert_array_equal(res.states[: k + 1], serial[: k + 1])
        if k < n:
            assert not np.array_equal(res.states, serial)
    assert res.stop_reason == "all_slices"
    assert res.converged
    np.testing.assert_array_equal(res.states, serial)


def test_stops_at_n_even_with_more_iterations_allowed():
    problem, x0 = PROBLEMS["oscillator"]
    fine, coarse = _solvers(problem)
    res = parareal.run(fine, coarse, x0, T0, T1, 4, tol=0.0, max_iterations=10)
    assert res.iterations == 4
    assert res.stop_reason == "all_slices"


def test_exact_coarse_converges_in_one_iteration():
    problem, x0 = PROBLEMS["oscillator"]
    res = parareal.run(Exact(problem), Exact(problem), x0, T0, T1, 8, tol=1e-12, max_iterations=8)
    assert res.iterations == 1
    assert res.stop_reason == "tolerance"
    assert res.increments == [0.0]


def test_increments_decrease_on_contracting_problem():
    problem, x0 = PROBLEMS["decay"]
    fine, coarse = _solvers(problem)
    reference = parareal.serial_solution(fine, x0, T0, T1, 10)
    res = parareal.run(
        fine, coarse, x0, T0, T1, 10, tol=1e-13, max_iterations=6, reference=reference
    )
    assert res.iterations >= 4
    assert np.all(np.diff(res.increments) < 0)
    assert np.all(np.diff(res.errors) < 0)
    assert res.errors[0] > 1e-6  # the coarse solver is genuinely inaccurate


def test_tolerance_stops_early_and_errors_match_definition():
    problem, x0 = PROBLEMS["logistic"]
    fine, coarse = _solvers(problem)
    reference = parareal.serial_solution(fine, x0, T0, T1, 8)
    res = parareal.run(fine, coarse, x0, T0, T1, 8, tol=1e-6, max_iterations=8, reference=reference)
    assert res.stop_reason == "tolerance"
    assert res.increments[-1] < 1e-6 <= res.increments[-2]
    assert res.iterations < 8
    eta = np.abs(res.states[-1] - reference[-1]) / np.abs(reference[-1])  # eq. 34, one point
    assert res.errors[-1] == pytest.approx(eta.max())


def test_positions_select_the_measured_points():
    problem, x0 = PROBLEMS["oscillator"]
    fine, coarse = _solvers(problem)
    before = parareal.run(fine, coarse, x0, T0, T1, 4, tol=0.0, max_iterations=1).states[-1]
    whole = parareal.run(fine, coarse, x0, T0, T1, 4, tol=0.0, max_iterations=2)
    first = parareal.run(
        fine, coarse, x0, T0, T1, 4, tol=0.0, max_iterations=2, positions=FirstComponent()
    )
    np.testing.assert_array_equal(whole.states, first.states)
    final = whole.states[-1]
    # eq. 34: ||x^k - x^{k-1}|| / ||x^k|| with the whole state as one point, or its first entry
    assert whole.increments[-1] == pytest.approx(
        np.linalg.norm(final - before) / np.linalg.norm(final)
    )
    assert first.increments[-1] == pytest.approx(abs(final[0] - before[0]) / abs(final[0]))
    assert first.increments[-1] != pytest.approx(whole.increments[-1])


class FirstComponent:
    def __call__(self, state):
        return state[:1]


def test_projection_applied_after_every_correction():
    problem, x0 = PROBLEMS["oscillator"]  # |x| = 1 is conserved: project onto the unit circle
    fine, coarse = _solvers(problem)
    project = UnitCircle()
    n, k = 6, 3
    res = parareal.run(fine, coarse, x0, T0, T1, n, tol=0.0, max_iterations=k, project=project)
    assert project.calls == sum(n - j for j in range(1, k + 1))  # n = j+1..N in iteration j
    plain = parareal.run(fine, coarse, x0, T0, T1, n, tol=0.0, max_iterations=k)
    np.testing.assert_array_equal(res.states[: k + 1], plain.states[: k + 1])  # F values untouched
    np.testing.assert_allclose(np.linalg.norm(res.states[k + 1 :], axis=1), 1.0, rtol=1e-14)
    assert np.abs(np.linalg.norm(plain.states[k + 1 :], axis=1) - 1.0).max() > 1e-6


class UnitCircle:
    def __init__(self):
        self.calls = 0

    def __call__(self, state):
        self.calls += 1
        return state / np.linalg.norm(state)


def test_executor_gives_identical_numbers_and_gets_fine_unwrapped():
    problem, x0 = PROBLEMS["logistic"]
    fine, coarse = _solvers(problem)
    serial = parareal.run(fine, coarse, x0, T0, T1, 6, tol=0.0, max_iterations=3)
    recorder = RecordingExecutor()
    with ThreadPoolExecutor(3) as pool:
        for executor in (recorder, pool):
            res = parareal.run(
                fine, coarse, x0, T0, T1, 6, tol=0.0, max_iterations=3, executor=executor
            )
            np.testing.assert_array_equal(res.states, serial.states)
            assert res.increments == serial.increments
            assert [len(f) for f in res.timings.fine] == [6, 5, 4]
    assert all(fn is fine for fn in recorder.submitted)  # submitted as is, never wrapped
    assert len(recorder.submitted) == 6 + 5 + 4


def test_parallel_sweep_only_on_slices_k_to_n_and_coarse_reused():
    problem, x0 = PROBLEMS["oscillator"]
    fine, coarse = Recording(_solvers(problem)[0]), Recording(_solvers(problem)[1])
    n, k = 5, 3
    res = parareal.run(fine, coarse, x0, T0, T1, n, tol=0.0, max_iterations=k)
    times = res.times
    expected_fine = [(times[i - 1], times[i]) for j in range(1, k + 1) for i in range(j, n + 1)]
    assert fine.calls == expected_fine
    expected_coarse = [(times[i - 1], times[i]) for j in range(k + 1) for i in range(j + 1, n + 1)]
    assert coarse.calls == expected_coarse  # one new G per corrected slice, old ones reused
    assert [len(c) for c in res.timings.coarse] == [n - j for j in range(k + 1)]


def test_one_log_line_per_iteration(caplog):
    problem, x0 = PROBLEMS["decay"]
    fine, coarse = _solvers(problem)
    reference = parareal.serial_solution(fine, x0, T0, T1, 4)
    with caplog.at_level(logging.INFO, logger="parastokes.parareal"):
        parareal.run(fine, coarse, x0, T0, T1, 4, tol=0.0, max_iterations=3, reference=reference)
    lines = [r.getMessage() for r in caplog.records if "k=" in r.getMessage()]
    assert len(lines) == 3
    assert lines[0].startswith("parareal k=1 eta~=")
    assert "eta=" in lines[0] and "n/a" not in lines[0] and "parallel sweep" in lines[0]


GOOD = dict(x0=np.array([1.0]), t0=0.0, t1=1.0, n_slices=4, tol=1e-8, max_iterations=3)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"n_slices": 0}, "n_slices"),
        ({"n_slices": 2.5}, "n_slices"),
        ({"tol": -1e-3}, "tol"),
        ({"tol": float("nan")}, "tol"),
        ({"max_iterations": 0}, "max_iterations"),
        ({"t1": 0.0}, "t0 < t1"),
        ({"t1": -1.0}, "t0 < t1"),
        ({"x0": np.array([1.0, np.nan])}, "x0"),
        ({"x0": np.array([np.inf])}, "x0"),
        ({"reference": np.zeros((3, 1))}, "reference"),
        ({"wall_time_limit": 0.0}, "wall_time_limit"),
    ],
)
def test_bad_parameters_raise_before_any_propagator_call(change, message):
    problem = decay()
    fine, coarse = Recording(Exact(problem)), Recording(Exact(problem))
    with pytest.raises(ValueError, match=message):
        parareal.run(fine, coarse, **{**GOOD, **change})
    assert fine.calls == [] and coarse.calls == []


def test_result_shape_and_time_points():
    problem, _ = PROBLEMS["decay"]
    x0 = np.ones((2, 3))
    fine, coarse = Exact(problem), Exact(problem)
    res = parareal.run(fine, coarse, x0, 1.0, 3.0, 5, tol=1e-10, max_iterations=2)
    assert res.states.shape == (6, 2, 3)
    assert res.times[0] == 1.0 and res.times[-1] == 3.0
    np.testing.assert_allclose(np.diff(res.times), 0.4)
    assert res.n_slices == 5


def test_on_iteration_reports_every_iteration_as_the_result_records_it():
    problem, x0 = PROBLEMS["oscillator"]
    fine, coarse = _solvers(problem)
    serial = parareal.serial_solution(fine, x0, T0, T1, 5)
    reports = []
    res = parareal.run(
        fine, coarse, x0, T0, T1, 5, tol=0.0, max_iterations=3, reference=serial,
        on_iteration=reports.append,
    )
    assert [r.iteration for r in reports] == [1, 2, 3]
    assert [r.increment for r in reports] == res.increments
    assert [r.error for r in reports] == res.errors
    np.testing.assert_array_equal(reports[-1].final_state, res.states[-1])
    assert all(a.elapsed <= b.elapsed for a, b in itertools.pairwise(reports))
