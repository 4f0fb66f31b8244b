"""A stopped run loses none of the solves of the iteration in progress (parareal.solve_memo).

Every fine solve and coarse step of the iteration in progress is kept as it completes; a resumed
run takes exactly those whose input is bit-identical, computes the rest, and reaches the iterates
of a run that was never stopped.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from odes import FailsOnSlice, Logistic, Recording, Sleeping, Stepper

from parastokes import parallel, parareal
from parastokes.output import rundir
from parastokes.parareal import checkpoint as ckpt
from parastokes.parareal.solve_memo import SolveMemo, memo_directory

T0, T1, N_SLICES, ITERATIONS = 0.0, 1.2, 6, 4
X0 = np.array([0.1, 0.3])
FINE = Stepper(Logistic(3.0), 1e-3, order=4)
COARSE = Stepper(Logistic(3.0), 0.05, order=1)
TIMES = parareal.time_points(T0, T1, N_SLICES)
REFERENCE = parareal.serial_solution(FINE, X0, T0, T1, N_SLICES)


def _run(fine=FINE, coarse=COARSE, executor=None, checkpoint=None, schedule="standard"):
    return parareal.run(
        fine, coarse, X0, T0, T1, N_SLICES, tol=0.0, max_iterations=ITERATIONS,
        executor=executor, reference=REFERENCE, checkpoint=checkpoint, schedule=schedule,
    )


CLEAN = _run()


def _same(res):
    np.testing.assert_array_equal(res.states, CLEAN.states)
    assert res.increments == CLEAN.increments and res.errors == CLEAN.errors
    assert res.iterations == ITERATIONS


# ---- the memo itself -------------------------------------------------------------------------
def test_a_kept_solve_is_returned_only_for_exactly_its_input(tmp_path):
    memo = SolveMemo(tmp_path / "m", {"problem": "a"})
    x = np.array([0.1, 0.3])
    value = np.array([1.0, 2.0])
    assert memo.get("fine", 3, 2, 0.4, 0.6, x) is None and memo.count() == 0
    memo.put("fine", 3, 2, 0.4, 0.6, x, value, 1.25)
    kept, seconds, steps = memo.get("fine", 3, 2, 0.4, 0.6, x)
    np.testing.assert_array_equal(kept, value)
    assert seconds == 1.25 and steps is None and memo.count() == 1
    one_ulp = x.copy()
    one_ulp[1] = np.nextafter(x[1], 1.0)
    assert memo.get("fine", 3, 2, 0.4, 0.6, one_ulp) is None  # another input state
    assert memo.get("fine", 3, 2, 0.4, 0.7, x) is None  # another interval
    assert memo.get("coarse", 3, 2, 0.4, 0.6, x) is None  # another kind (not stored)
    assert memo.get("fine", 3, 3, 0.4, 0.6, x) is None  # another iteration (not stored)
    assert SolveMemo(tmp_path / "m", {"problem": "b"}).get("fine", 3, 2, 0.4, 0.6, x) is None
    for k in (1, 3):
        memo.put("coarse", 5, k, 0.8, 1.0, x, value, 0.5)
    memo.forget(2)  # iterations 1 and 2 are in the checkpoint now
    assert memo.count() == 1 and memo.get("coarse", 5, 3, 0.8, 1.0, x) is not None
    memo.forget(3)
    assert memo.count() == 0 and not (tmp_path / "m").exists()
    memo.put("fine", 1, 1, 0.0, 0.2, x, value, 0.5)
    memo.clear()
    assert memo.count() == 0 and not (tmp_path / "m").exists()
    with pytest.raises(ValueError, match="kind"):
        memo.get("auxiliary", 1, 1, 0.0, 1.0, x)


def test_a_damaged_kept_solve_is_recomputed_not_used(tmp_path, caplog):
    memo = SolveMemo(tmp_path / "m", {"problem": "a"})
    x = np.zeros(2)
    memo.put("coarse", 1, 0, 0.0, 0.2, x, np.ones(2), 0.5)
    (path,) = (tmp_path / "m").glob("*.npz")
    path.write_bytes(b"PK\x03\x04 half a zip file")
    assert memo.get("coarse", 1, 0, 0.0, 0.2, x) is None
    assert "damaged" in caplog.text


def test_the_memo_lives_beside_its_checkpoint():
    assert memo_directory("out/checkpoint.npz").as_posix() == "out/checkpoint.solves"
    assert "checkpoint.solves" in rundir.STATE_FILES


# ---- a run stopped inside an iteration ----------------------------------------------------------
SLICE = 4  # the fault: slice 4's fine solve in iteration 2 (slices 2 and 3 completed before it)


def _failing(tmp_path, propagator, t_start, call):
    """``propagator`` failing on its ``call``-th solve of the slice that starts at ``t_start``."""
    markers = tmp_path / "markers"
    markers.mkdir()
    return FailsOnSlice(propagator, t_start, call, markers)


@pytest.mark.parametrize("kind", ["in-process", "processes"])
def test_a_run_stopped_in_the_parallel_sweep_repeats_none_of_its_solves(kind, tmp_path):
    faulty = _failing(tmp_path, FINE, TIMES[SLICE - 1], 2)
    path = tmp_path / "run.npz"
    executor = parallel.make_executor("processes", 2) if kind == "processes" else None
    try:
        with pytest.raises(parallel.TaskError) as info:
            _run(faulty, executor=executor, checkpoint=path)
    finally:
        if executor is not None:
            executor.shutdown()
    key = ckpt.fingerprint(X0, T0, T1, N_SLICES, REFERENCE)
    assert ckpt.load(path, key).iteration == 1
    memo = SolveMemo(memo_directory(path), key)
    kept = {n for n in range(2, N_SLICES + 1) if (memo.directory / f"fine-k2-n{n}.npz").exists()}
    assert {2, 3} <= kept and SLICE not in kept  # what completed before the fault, not the fault
    assert any("keeps" in note and "solves" in note for note in info.value.__notes__)

    fine, coarse = Recording(FINE), Recording(COARSE)
    resumed = _run(fine, coarse, checkpoint=path)
    _same(resumed)
    # iteration 2 solved only the slices that were not kept; iterations 3, 4 all theirs
    solved_in_2 = [t for t, _ in fine.calls[: N_SLICES - 1 - len(kept)]]
    assert sorted(solved_in_2) == [TIMES[n - 1] for n in range(2, N_SLICES + 1) if n not in kept]
    assert len(fine.calls) == (N_SLICES - 1 - len(kept)) + (N_SLICES - 2) + (N_SLICES - 3)
    assert len(coarse.calls) == sum(N_SLICES - k for k in (2, 3, 4))
    # the kept solves' wall times are in the history, one per slice of every sweep
    assert [len(f) for f in resumed.timings.fine] == [6, 5, 4, 3]
    assert all(s >= 0 for f in resumed.timings.fine for s in f)
    assert not memo.directory.exists()  # emptied once the iteration's checkpoint was written


def test_a_run_stopped_in_the_initial_sweep_keeps_its_coarse_steps(tmp_path):
    faulty = _failing(tmp_path, COARSE, TIMES[SLICE - 1], 1)
    path = tmp_path / "run.npz"
    with pytest.raises(parallel.TaskError, match="coarse solve of slice 4 in iteration 0") as info:
        _run(coarse=faulty, checkpoint=path)
    assert not path.exists()  # the initial sweep never completed
    assert any("keeps 3 solves" in note for note in info.value.__notes__)
    coarse = Recording(COARSE)
    resumed = _run(coarse=coarse, checkpoint=path)
    _same(resumed)
    assert [t for t, _ in coarse.calls[: N_SLICES - 3]] == list(TIMES[3:-1])  # slices 4..6
    assert len(coarse.calls) == (N_SLICES - 3) + sum(N_SLICES - k for k in range(1, 5))


def test_a_fresh_run_at_the_same_path_forgets_kept_solves(tmp_path):
    path = tmp_path / "run.npz"
    memo = SolveMemo(memo_directory(path), ckpt.fingerprint(X0, T0, T1, N_SLICES, REFERENCE))
    memo.put("coarse", 1, 0, TIMES[0], TIMES[1], X0, np.full(2, 7.0), 1.0)  # a wrong value
    fresh = parareal.run(
        FINE, COARSE, X0, T0, T1, N_SLICES, tol=0.0, max_iterations=ITERATIONS,
        reference=REFERENCE, checkpoint=parareal.Checkpoint(path, resume=False),
    )
    _same(fresh)


def test_a_resumed_run_uses_a_kept_solve_whose_input_matches(tmp_path):
    """The memo is really read: a planted value for the first coarse step changes the run."""
    path = tmp_path / "run.npz"
    memo = SolveMemo(memo_directory(path), ckpt.fingerprint(X0, T0, T1, N_SLICES, REFERENCE))
    planted = COARSE(TIMES[0], TIMES[1], X0) + 1e-3
    memo.put("coarse", 1, 0, TIMES[0], TIMES[1], X0, planted, 1.0)
    coarse = Recording(COARSE)
    res = parareal.run(
        FINE, coarse, X0, T0, T1, N_SLICES, tol=0.0, max_iterations=1,
        reference=REFERENCE, checkpoint=path,
    )
    assert coarse.calls[0][0] == TIMES[1]  # the first step came from the memo
    assert not np.array_equal(res.states, _run_one_iteration().states)


def _run_one_iteration():
    return parareal.run(
        FINE, COARSE, X0, T0, T1, N_SLICES, tol=0.0, max_iterations=1, reference=REFERENCE
    )


@pytest.mark.parametrize("resume_with", ["pipelined", "standard"])
def test_the_pipelined_schedule_keeps_its_solves_too(tmp_path, resume_with):
    """Its kept solves may reach past the checkpoint's iteration; either schedule resumes them."""
    faulty = _failing(tmp_path, FINE, TIMES[SLICE - 1], 2)
    path = tmp_path / "run.npz"
    with pytest.raises(parallel.TaskError, match=f"fine solve of slice {SLICE}"):
        _run(faulty, checkpoint=path, schedule="pipelined")
    key = ckpt.fingerprint(X0, T0, T1, N_SLICES, REFERENCE)
    saved = ckpt.load(path, key).iteration
    kept = [f.name for f in memo_directory(path).glob("fine-*.npz")]
    assert saved == 1 and kept  # iteration 1 closed; solves of iteration 2 (and later) kept
    assert all(int(name.split("-k")[1].split("-")[0]) > saved for name in kept)
    fine = Recording(FINE)
    resumed = _run(fine, checkpoint=path, schedule=resume_with)
    _same(resumed)
    todo = sum(N_SLICES - k + 1 for k in range(saved + 1, ITERATIONS + 1))
    assert len(fine.calls) == todo - len(kept)  # every kept fine solve was used
    assert not memo_directory(path).exists()  # all forgotten when the run returned
    assert [len(f) for f in resumed.timings.fine] == [6, 5, 4, 3]


def test_a_stop_on_the_tolerance_leaves_no_kept_solves(tmp_path):
    path = tmp_path / "run.npz"
    res = parareal.run(
        FINE, COARSE, X0, T0, T1, N_SLICES, tol=1e-3, checkpoint=path, schedule="pipelined"
    )
    assert res.stop_reason == "tolerance" and path.exists()
    assert not memo_directory(path).exists()


def test_a_run_stopped_in_a_correction_sweep_solves_no_fine_slice_again(tmp_path):
    # slice 5's coarse step: 1st call in the initial sweep, 2nd in iteration 1, 3rd in iteration 2
    faulty = _failing(tmp_path, COARSE, TIMES[4], 3)
    path = tmp_path / "run.npz"
    with pytest.raises(parallel.TaskError, match="coarse solve of slice 5 in iteration 2"):
        _run(coarse=faulty, checkpoint=path)
    fine, coarse = Recording(FINE), Recording(COARSE)
    resumed = _run(fine, coarse, checkpoint=path)
    _same(resumed)
    assert len(fine.calls) == (N_SLICES - 2) + (N_SLICES - 3)  # iteration 2's were all kept
    assert coarse.calls[0][0] == TIMES[4]  # iteration 2 went on from slice 5's coarse step
    assert len(coarse.calls) == 2 + (N_SLICES - 3) + (N_SLICES - 4)


def test_a_wall_time_stop_keeps_the_solves_of_later_iterations(tmp_path):
    """The batch loop `run(..., wall_time_limit=...)` resumed: the pipelined schedule's solves of
    the iteration after the stop are kept for the next call, which uses every one of them."""
    path = tmp_path / "run.npz"
    # slow coarse steps: iteration 1 closes after a chain of 5 of them, while the fine solves of
    # iteration 2 on the first slices (0.02 s each) have long completed
    coarse = Sleeping(COARSE, 0.05)
    with ThreadPoolExecutor(N_SLICES) as pool:
        pool.workers = N_SLICES  # type: ignore[attr-defined]
        first = parareal.run(
            Sleeping(FINE, 0.02), coarse, X0, T0, T1, N_SLICES, tol=0.0,
            max_iterations=ITERATIONS, reference=REFERENCE, executor=pool, checkpoint=path,
            schedule="pipelined", wall_time_limit=1e-9,
        )
    assert first.stop_reason == "wall_time" and first.iterations == 1
    kept = [f.name for f in memo_directory(path).glob("fine-*.npz")]
    assert kept and all(int(name.split("-k")[1].split("-")[0]) >= 2 for name in kept)
    fine = Recording(FINE)
    resumed = _run(fine, checkpoint=path, schedule="pipelined")
    _same(resumed)
    todo = sum(N_SLICES - k + 1 for k in range(2, ITERATIONS + 1))
    assert len(fine.calls) == todo - len(kept)  # every kept fine solve was used
    assert not memo_directory(path).exists()  # a finished run forgets them


def test_a_pipelined_resume_replays_hundreds_of_kept_coarse_steps(tmp_path):
    """Kept solves are applied from a queue, not by recursion: 399 kept steps of the initial
    sweep (more than Python's recursion limit allows as nested calls) resume bit for bit."""
    n_slices = 400

    def fine(t_start, t_end, x):
        return x * np.exp(-(t_end - t_start))

    def coarse(t_start, t_end, x):
        return x * (1.0 - (t_end - t_start))

    x0 = np.array([1.0])
    clean = parareal.run(fine, coarse, x0, 0.0, 1.0, n_slices, tol=0.0, max_iterations=1)
    times = parareal.time_points(0.0, 1.0, n_slices)
    path = tmp_path / "run.npz"
    faulty = _failing(tmp_path, coarse, times[-2], 1)  # the initial sweep's last step
    with pytest.raises(parallel.TaskError, match=f"slice {n_slices}"):
        parareal.run(
            fine, faulty, x0, 0.0, 1.0, n_slices, tol=0.0, max_iterations=1, checkpoint=path,
            schedule="pipelined",
        )
    assert len(list(memo_directory(path).glob("coarse-*.npz"))) == n_slices - 1
    counted = Recording(coarse)
    resumed = parareal.run(
        fine, counted, x0, 0.0, 1.0, n_slices, tol=0.0, max_iterations=1, checkpoint=path,
        schedule="pipelined",
    )
    np.testing.assert_array_equal(resumed.states, clean.states)
    assert resumed.increments == clean.increments
    # the step that had failed, then iteration 1's steps: none of the kept ones again
    iteration_1 = [(times[n - 1], times[n]) for n in range(2, n_slices + 1)]
    assert sorted(counted.calls) == sorted([(times[-2], times[-1]), *iteration_1])
