"""An adaptive coarse solver's step counts (``Timings.coarse_steps``) are the same under both
schedules (standard == pipelined on the serial and process executors:
tests/test_adaptive_everywhere.py), and on resume: the counts of a step replayed from the memo of a
stopped session are the ones kept with it (not recomputed), those of completed sweeps come from
the checkpoint (docs/parareal.md, "Adaptive coarse steps")."""

from __future__ import annotations

import numpy as np
import pytest
from odes import Logistic, Stepper

from parastokes import integrate, models, parallel, parareal
from parastokes.parareal import checkpoint as ckpt
from parastokes.parareal.algorithm import add_steps
from parastokes.parareal.solve_memo import SolveMemo, memo_directory

N_SLICES, T1, ITERATIONS = 3, 3e-4, 2
ROD = models.rod_swimmer(n_points=21)
FINE = integrate.Propagator(ROD, "rk2", 1e-6)
LAGRANGE = {"epsilon": [1.03, 1.06]}


def _coarse():
    return parareal.extrapolated(ROD, "ros2", 2e-5, lagrange=LAGRANGE, rtol=1e-4,
                                 allow_oversubscribe=True)


def _solve(executor=None, schedule="standard", coarse=None, checkpoint=None):
    return parareal.run(FINE, coarse or _coarse(), ROD.initial_state(), t0=0.0, t1=T1,
                        n_slices=N_SLICES, tol=0.0, max_iterations=ITERATIONS, executor=executor,
                        allow_oversubscribe=True, schedule=schedule, checkpoint=checkpoint)


@pytest.fixture(scope="module")
def standard():
    with parallel.make_executor("serial") as executor:
        return _solve(executor)


def test_add_steps_sums_key_by_key_and_skips_uncounted_steps():
    a = {"accepted": 5, "rejected": 1, "switches": 0}
    b = {"accepted": 3, "rejected": 2, "switches": 4}
    assert add_steps(None, None) is None
    assert add_steps(None, a) == a and add_steps(None, a) is not a  # a copy, not the step's
    assert add_steps(a, None) == a
    assert add_steps(a, b) == {"accepted": 8, "rejected": 3, "switches": 4}


class _FailsOnce:
    """The coarse solver, failing on its ``fail_at``-th call (a stopped session), counting its
    calls and handing its step counts on (it has no ``with_executor``: run as it is)."""

    def __init__(self, inner, fail_at: int | None) -> None:
        self.inner, self.fail_at, self.calls = inner, fail_at, 0

    def __call__(self, t_start, t_end, x):
        self.calls += 1
        if self.calls == self.fail_at:
            raise RuntimeError("injected fault")
        return self.inner(t_start, t_end, x)

    def take_step_counts(self):
        return self.inner.take_step_counts()


def test_a_resumed_run_reports_the_kept_steps_counts_without_recomputing_them(standard,
                                                                              tmp_path):
    path = tmp_path / "run.npz"
    with pytest.raises(parallel.TaskError, match="coarse solve of slice 3 in iteration 0"):
        _solve(coarse=_FailsOnce(_coarse(), 3), checkpoint=path)
    resumed_coarse = _FailsOnce(_coarse(), None)
    resumed = _solve(coarse=resumed_coarse, checkpoint=path)
    # slices 1, 2 of the initial sweep came from the memo: 1 + 2 + 1 calls instead of 3 + 2 + 1
    assert resumed_coarse.calls == 1 + (N_SLICES - 1) + (N_SLICES - 2)
    assert resumed.timings.coarse_steps == standard.timings.coarse_steps


def test_completed_sweeps_counts_come_from_the_checkpoint(standard, tmp_path):
    path = tmp_path / "run.npz"
    with parallel.make_executor("serial") as executor:
        parareal.run(FINE, _coarse(), ROD.initial_state(), t0=0.0, t1=T1, n_slices=N_SLICES,
                     tol=0.0, max_iterations=1, executor=executor, allow_oversubscribe=True,
                     checkpoint=path)
    key = ckpt.fingerprint(ROD.initial_state(), 0.0, T1, N_SLICES, None)
    saved = ckpt.load(path, key)
    assert saved.timings.coarse_steps == standard.timings.coarse_steps[:2]
    planted = {"accepted": 10**6, "rejected": 7, "switches": 0}
    saved.timings.coarse_steps[0] = planted  # read back as it is, not recomputed
    ckpt.save(path, saved, key)
    for schedule in ("standard", "pipelined"):
        resumed = _solve(schedule=schedule, checkpoint=parareal.Checkpoint(path, resume=True))
        assert resumed.timings.coarse_steps == [planted, *standard.timings.coarse_steps[1:]]
        ckpt.save(path, saved, key)


@pytest.mark.parametrize("schedule", ["standard", "pipelined"])
def test_a_kept_coarse_step_brings_its_counts_from_the_memo(schedule, tmp_path):
    """A planted kept step with counts: the sweep's counts are exactly those kept (the coarse
    solver itself, fixed steps, counts none), so they are read, not recomputed."""
    x0, t1, n = np.array([0.1, 0.3]), 1.2, 4
    fine, coarse = Stepper(Logistic(3.0), 1e-3, order=4), Stepper(Logistic(3.0), 0.05, order=1)
    times = parareal.time_points(0.0, t1, n)
    path = tmp_path / "run.npz"
    memo = SolveMemo(memo_directory(path), ckpt.fingerprint(x0, 0.0, t1, n, None))
    kept = {"accepted": 11, "rejected": 2, "switches": 1}
    memo.put("coarse", 1, 0, times[0], times[1], x0, coarse(times[0], times[1], x0), 0.5, kept)
    res = parareal.run(fine, coarse, x0, 0.0, t1, n, tol=0.0, max_iterations=1,
                       checkpoint=path, schedule=schedule)
    assert res.timings.coarse_steps == [kept]  # sweep 0: the kept step's; sweep 1: none
