"""``parareal.run``'s grouped options (Stopping, Checkpoint, Reporting) against its flat keywords:
the same runs, conflicts refused naming both, checkpoint/resume through the group."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from odes import Logistic, Recording, Stepper

from parastokes import parareal
from parastokes.parareal import checkpoint as ckpt

PROBLEM = Logistic(3.0)
X0 = np.array([0.05, 0.3])
SPAN = dict(t0=0.0, t1=2.0, n_slices=8)


def _solvers():
    return Stepper(PROBLEM, 1e-2, order=4), Stepper(PROBLEM, 0.25, order=1)


def _same(a: parareal.PararealResult, b: parareal.PararealResult) -> None:
    np.testing.assert_array_equal(a.states, b.states)
    assert a.increments == b.increments
    assert a.errors == b.errors
    assert (a.iterations, a.stop_reason) == (b.iterations, b.stop_reason)


@pytest.mark.parametrize("schedule", parareal.SCHEDULES)
@pytest.mark.parametrize(
    ("flat", "stopping"),
    [
        ({"tol": 0.0, "max_iterations": 3}, parareal.Stopping(tol=0.0, max_iterations=3)),
        ({"tol": 1e-3, "max_iterations": 8}, parareal.Stopping(tol=1e-3, max_iterations=8)),
        ({"tol": 0.0}, parareal.Stopping(tol=0.0)),  # no limit: k = N, the serial solution
    ],
)
def test_flat_and_grouped_options_give_identical_runs(tmp_path, schedule, flat, stopping):
    fine, coarse = _solvers()
    reference = parareal.serial_solution(fine, X0, **SPAN)
    flat_reports, grouped_reports = [], []
    by_flat = parareal.run(
        fine, coarse, X0, **SPAN, **flat, reference=reference, schedule=schedule,
        checkpoint=tmp_path / "flat.npz", identity={"case": 1},
        on_iteration=flat_reports.append,
    )
    grouped = parareal.run(
        fine, coarse, X0, **SPAN, stopping=stopping, reference=reference, schedule=schedule,
        checkpoint=parareal.Checkpoint(tmp_path / "grouped.npz", identity={"case": 1}),
        reporting=parareal.Reporting(on_iteration=grouped_reports.append),
    )
    _same(grouped, by_flat)
    assert [r.increment for r in grouped_reports] == [r.increment for r in flat_reports]
    assert [r.iteration for r in grouped_reports] == list(range(1, grouped.iterations + 1))
    # both wrote the same checkpoint content under the same fingerprint
    key = ckpt.fingerprint(X0, 0.0, 2.0, 8, reference, {"case": 1})
    saved = ckpt.load(tmp_path / "grouped.npz", key)
    np.testing.assert_array_equal(saved.states, ckpt.load(tmp_path / "flat.npz", key).states)
    if "max_iterations" not in flat:
        assert grouped.stop_reason == "all_slices"
        np.testing.assert_array_equal(grouped.states, reference)


@pytest.mark.parametrize(
    ("flat", "group", "named"),
    [
        ({"tol": 1e-6}, {"stopping": parareal.Stopping(tol=1e-6)}, "tol="),
        ({"max_iterations": 2}, {"stopping": parareal.Stopping(tol=0.0)}, "max_iterations="),
        ({"wall_time_limit": 5.0}, {"stopping": parareal.Stopping(tol=0.0)}, "wall_time_limit="),
        ({"identity": {"a": 1}}, {"checkpoint": parareal.Checkpoint("c.npz")}, "identity="),
        ({"on_iteration": print}, {"reporting": parareal.Reporting()}, "on_iteration="),
    ],
)
def test_an_option_given_flat_and_grouped_is_refused_naming_both(flat, group, named):
    fine, coarse = Recording(_solvers()[0]), Recording(_solvers()[1])
    stopping = {} if "stopping" in group else {"tol": 0.0, "max_iterations": 1}
    options = {**stopping, **flat, **group}
    (group_name,) = group
    with pytest.raises(TypeError, match=named) as caught:
        parareal.run(fine, coarse, X0, **SPAN, **options)
    assert f"{group_name}=" in str(caught.value)
    assert fine.calls == [] and coarse.calls == []


def test_a_run_without_a_tolerance_is_refused_saying_how_to_give_one():
    fine, coarse = _solvers()
    with pytest.raises(TypeError, match=r"stopping=parareal\.Stopping"):
        parareal.run(fine, coarse, X0, **SPAN, max_iterations=2)


def test_a_group_of_the_wrong_type_is_refused():
    fine, coarse = _solvers()
    with pytest.raises(TypeError, match=r"parareal\.Stopping"):
        parareal.run(fine, coarse, X0, **SPAN, stopping={"tol": 0.0})
    with pytest.raises(TypeError, match=r"parareal\.Reporting"):
        parareal.run(fine, coarse, X0, **SPAN, tol=0.0, reporting=print)


@pytest.mark.parametrize(
    ("fields", "named"),
    [
        ({"tol": -1.0}, "tol"),
        ({"tol": float("inf")}, "tol"),
        ({"tol": 0.0, "max_iterations": 0}, "max_iterations"),
        ({"tol": 0.0, "max_iterations": True}, "max_iterations"),
        ({"tol": 0.0, "wall_time_limit": -1.0}, "wall_time_limit"),
        ({"tol": True}, "tol"),
        ({"tol": "1e-8"}, "tol"),
        ({"tol": 0.0, "wall_time_limit": "5"}, "wall_time_limit"),
    ],
)
def test_a_bad_stopping_value_is_refused_when_made(fields, named):
    with pytest.raises(ValueError, match=named):
        parareal.Stopping(**fields)


def test_numpy_numbers_are_valid_stopping_values():
    stopping = parareal.Stopping(
        tol=np.float64(1e-8), max_iterations=np.int64(3), wall_time_limit=np.float32(5.0)
    )
    assert stopping.max_iterations == 3


@pytest.mark.parametrize(
    ("identity", "named"),
    [([1], "mapping"), ({"n": np.int64(3)}, "JSON values"), ({"f": print}, "JSON values")],
)
def test_a_checkpoint_identity_that_cannot_be_stored_is_refused_when_made(identity, named):
    with pytest.raises(ValueError, match=named):
        parareal.Checkpoint("run.npz", identity=identity)


def test_the_span_must_be_two_real_numbers():
    fine, coarse = _solvers()
    with pytest.raises(ValueError, match="t0 < t1"):
        parareal.run(fine, coarse, X0, None, 1.0, 4, tol=0.0)  # type: ignore[arg-type]


def test_option_values_are_frozen():
    stopping = parareal.Stopping(tol=1e-8, max_iterations=4)
    with pytest.raises(dataclasses.FrozenInstanceError):
        stopping.tol = 0.0  # type: ignore[misc]
    assert dataclasses.replace(stopping, max_iterations=5).max_iterations == 5


@pytest.mark.parametrize("schedule", parareal.SCHEDULES)
def test_checkpoint_group_resumes_bit_for_bit_and_checks_identity(tmp_path, schedule):
    fine, coarse = _solvers()
    full = parareal.run(fine, coarse, X0, **SPAN, stopping=parareal.Stopping(tol=0.0,
                        max_iterations=5), schedule=schedule)
    saving = parareal.Checkpoint(tmp_path / "run.npz", identity={"model": "logistic"})
    first = parareal.run(fine, coarse, X0, **SPAN, schedule=schedule, checkpoint=saving,
                         stopping=parareal.Stopping(tol=0.0, max_iterations=2))
    assert first.iterations == 2
    counted = Recording(fine)
    resumed = parareal.run(counted, coarse, X0, **SPAN, schedule=schedule, checkpoint=saving,
                           stopping=parareal.Stopping(tol=0.0, max_iterations=5))
    _same(resumed, full)
    assert len(counted.calls) == sum(8 - k + 1 for k in (3, 4, 5))  # continued after k = 2
    other = dataclasses.replace(saving, identity={"model": "other"})
    with pytest.raises(ckpt.CheckpointMismatch, match="model"):
        parareal.run(fine, coarse, X0, **SPAN, checkpoint=other, tol=0.0, max_iterations=6)


def test_checkpoint_without_resume_starts_afresh_and_replaces_the_file(tmp_path):
    fine, coarse = _solvers()
    path = tmp_path / "run.npz"
    parareal.run(fine, coarse, X0, **SPAN, tol=0.0, max_iterations=2, checkpoint=path)
    counted = Recording(coarse)
    again = parareal.run(fine, counted, X0, **SPAN, tol=0.0, max_iterations=1,
                         checkpoint=parareal.Checkpoint(path, resume=False))
    assert again.iterations == 1
    assert len(counted.calls) == 8 + 7  # the initial sweep was computed again, then k = 1
    key = ckpt.fingerprint(X0, 0.0, 2.0, 8, None)
    assert ckpt.load(path, key).iteration == 1  # the file now holds this run


def test_the_wall_time_limit_in_the_group_stops_after_each_iteration(tmp_path):
    fine, coarse = _solvers()
    stopping = parareal.Stopping(tol=0.0, max_iterations=3, wall_time_limit=1e-9)
    saving = parareal.Checkpoint(tmp_path / "run.npz")
    reasons = [parareal.run(fine, coarse, X0, **SPAN, stopping=stopping, checkpoint=saving)
               .stop_reason for _ in range(3)]
    assert reasons == ["wall_time", "wall_time", "max_iterations"]
