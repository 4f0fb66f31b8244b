"""``benchmarks/w_defect.py``: per step of an adaptive Rosenbrock run, its estimate against the
true local error of both its solutions (docs/stiff.md, "Why the exact Jacobian below rtol
1e-2")."""

from __future__ import annotations

import numpy as np
import pytest
from bench_modules import benchmark_module

from parastokes import integrate, models
from parastokes.integrate.controller import error_norm


@pytest.fixture(scope="module")
def wd():
    with benchmark_module("w_defect") as module:
        yield module


def test_the_steps_cover_the_run_and_their_true_errors_are_against_rk4(wd):
    """On a rod of 21 points: the accepted steps are contiguous from 0 to T, the run's end state
    is the last step's, and a step's true error is the controller's norm of its solution
    against RK4 from the same start (recomputed here for the first step, from the initial
    state)."""
    rod = models.rod_swimmer(n_points=21, length=4.0)
    t1, rtol = 2e-4, 1e-4
    run = wd.local_errors(rod, "ros34pw2", rtol, t1, 1e-6, first_step=1e-7)
    steps = np.array(run["steps"])
    assert steps[0, 0] == 0.0 and steps[:, 0] + steps[:, 1] == pytest.approx(
        np.append(steps[1:, 0], t1), rel=1e-12)
    assert run["accepted"] == len(steps) and np.all(steps[:, 2] <= 1.0)
    h = steps[0, 1]
    assert h == 1e-7  # the first step tried, accepted: a fresh stepper takes the same one
    x0 = rod.initial_state()
    stepper = wd.stepper_for(rod, integrate.SCHEMES["ros34pw2"])
    x_new, _ = stepper.step_with_estimate(0.0, x0, h)
    ref = integrate.run(rod, x0, 0.0, h, "rk4", h / int(np.ceil(h / 1e-6))).state
    assert steps[0, 3] == pytest.approx(error_norm(x0, x_new, ref, rtol, rtol / 10), rel=1e-12)


def test_a_tolerance_outside_0_1_is_refused(wd, capsys):
    with pytest.raises(SystemExit) as exit_:
        wd.main(["--rtol", "2"])
    assert exit_.value.code == 2
    assert "--rtol: must lie in (0, 1), got 2.0" in capsys.readouterr().err
