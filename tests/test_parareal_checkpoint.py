"""Checkpoint/resume gives bit-identical results; the wall-time limit stops cleanly."""

import numpy as np
import pytest
from odes import Logistic, Recording, Stepper

from parastokes import parareal

PROBLEM = Logistic(3.0)
X0 = np.array([0.05, 0.3])
ARGS = dict(x0=X0, t0=0.0, t1=2.0, n_slices=8, tol=0.0)


def _solvers():
    return Stepper(PROBLEM, 1e-2, order=4), Stepper(PROBLEM, 0.25, order=1)


def _assert_same_run(resumed, full):
    np.testing.assert_array_equal(resumed.states, full.states)
    assert resumed.increments == full.increments
    assert resumed.errors == full.errors
    assert resumed.iterations == full.iterations


def test_resume_after_max_iterations_is_bit_identical(tmp_path):
    fine, coarse = _solvers()
    reference = parareal.serial_solution(fine, X0, 0.0, 2.0, 8)
    full = parareal.run(fine, coarse, max_iterations=5, reference=reference, **ARGS)
    path = tmp_path / "run.npz"
    first = parareal.run(
        fine, coarse, max_iterations=2, reference=reference, checkpoint=path, **ARGS
    )
    assert first.iterations == 2 and first.stop_reason == "max_iterations"
    assert path.exists() and not list(tmp_path.glob("*.tmp"))
    counted_fine, counted_coarse = Recording(fine), Recording(coarse)
    resumed = parareal.run(
        counted_fine, counted_coarse, max_iterations=5, reference=reference, checkpoint=path, **ARGS
    )
    _assert_same_run(resumed, full)
    # it continued from iteration 3: no initial sweep, no repeated parallel sweeps
    assert len(counted_fine.calls) == sum(8 - k + 1 for k in (3, 4, 5))
    assert len(counted_coarse.calls) == sum(8 - k for k in (3, 4, 5))
    assert len(resumed.timings.serial_sweeps) == 6  # the history was kept
    assert resumed.timings.total >= first.timings.total


def test_wall_time_limit_stops_after_the_iteration_and_resumes(tmp_path):
    fine, coarse = _solvers()
    full = parareal.run(fine, coarse, max_iterations=4, **ARGS)
    path = tmp_path / "run.npz"
    results = []
    while not results or results[-1].stop_reason == "wall_time":
        results.append(
            parareal.run(
                fine, coarse, max_iterations=4, checkpoint=path, wall_time_limit=1e-9, **ARGS
            )
        )
    assert [r.iterations for r in results] == [1, 2, 3, 4]  # one iteration per call
    assert [r.stop_reason for r in results] == ["wall_time"] * 3 + ["max_iterations"]
    _assert_same_run(results[-1], full)


def test_finished_checkpoint_returns_without_work(tmp_path):
    fine, coarse = _solvers()
    path = tmp_path / "run.npz"
    done = parareal.run(fine, coarse, max_iterations=3, checkpoint=path, **ARGS)
    counted = Recording(fine)
    again = parareal.run(counted, coarse, max_iterations=3, checkpoint=path, **ARGS)
    assert counted.calls == []
    _assert_same_run(again, done)


def test_checkpoint_of_another_problem_is_refused(tmp_path):
    fine, coarse = _solvers()
    path = tmp_path / "run.npz"
    parareal.run(fine, coarse, max_iterations=1, checkpoint=path, **ARGS)
    with pytest.raises(ValueError, match="another problem"):
        parareal.run(fine, coarse, max_iterations=2, checkpoint=path, **{**ARGS, "t1": 3.0})
