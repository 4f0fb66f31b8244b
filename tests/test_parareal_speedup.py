"""Cost accounting and the speedup model (eqs. 12-15)."""

import time

import numpy as np
import pytest
from odes import Stepper, oscillator

from parastokes import parareal
from parastokes.parareal.speedup import main
from parastokes.parareal.timings import queued_durations
from parastokes.run import speedup_table


@pytest.fixture(scope="module")
def result():
    problem = oscillator(2.0)
    fine, coarse = Stepper(problem, 2e-3, order=4), Stepper(problem, 0.1, order=1)
    return parareal.run(fine, coarse, np.array([1.0, 0.0]), 0.0, 2.0, 6, tol=0.0, max_iterations=3)


def test_every_call_and_sweep_is_timed(result):
    t = result.timings
    assert [len(c) for c in t.coarse] == [6, 5, 4, 3]
    assert [len(f) for f in t.fine] == [6, 5, 4]
    assert len(t.serial_sweeps) == 4 and len(t.parallel_sweeps) == 3
    assert all(x > 0 for x in np.concatenate(t.coarse + t.fine))
    for calls, sweep in zip(t.coarse, t.serial_sweeps, strict=True):
        assert sum(calls) <= sweep
    assert sum(t.serial_sweeps) + sum(t.parallel_sweeps) <= t.total


def test_theoretical_speedup_is_eq14_by_hand(result):
    t = result.timings
    gamma_g = np.mean([x for sweep in t.coarse for x in sweep][1:])  # the first: setup
    gamma_f = np.mean([x for sweep in t.fine for x in sweep])
    n_it, n_c = 3, 6
    by_hand = 1.0 / (0.5 * (n_it + 1) * (2 - n_it / n_c) * gamma_g / gamma_f + n_it / n_c)
    s = result.speedup()
    assert s["theoretical"] == pytest.approx(by_hand, rel=1e-12)
    assert s["bound"] == pytest.approx(2 / ((n_it + 1) * (2 - n_it / n_c)) * gamma_f / gamma_g)
    assert s["theoretical"] < s["bound"]
    assert s["measured"] == pytest.approx(n_c * gamma_f / t.total)
    assert s["serial_time_estimated"] is True
    # eq. 14 with the overhead of eq. 12 is the measured speedup
    with_overhead = 1.0 / (
        0.5 * (n_it + 1) * (2 - n_it / n_c) * gamma_g / gamma_f
        + n_it / n_c
        + s["overhead"] / (n_c * gamma_f)
    )
    assert s["measured"] == pytest.approx(with_overhead, rel=1e-9)
    assert result.speedup(serial_time=2.0)["measured"] == pytest.approx(2.0 / t.total)


class _SetUpOnce(Stepper):
    """A coarse solver whose first call builds something it keeps (as a rigid body's LU)."""

    setup = 0.3

    def __call__(self, t_start, t_end, x):
        if self.setup:
            time.sleep(self.setup)
            self.setup = 0.0
        return super().__call__(t_start, t_end, x)


def test_a_one_off_setup_of_g_is_reported_apart_not_in_gamma_g():
    problem = oscillator(2.0)
    fine, coarse = Stepper(problem, 2e-3, order=4), _SetUpOnce(problem, 0.1, order=1)
    result = parareal.run(fine, coarse, np.array([1.0, 0.0]), 0.0, 2.0, 6, tol=0.0,
                          max_iterations=2)
    calls = np.concatenate(result.timings.coarse)
    s = result.speedup()
    assert calls[0] > 0.3 > 100 * calls[1:].max()
    assert s["gamma_G"] == pytest.approx(calls[1:].mean())
    assert s["coarse_setup"] == pytest.approx(calls[0] - calls[1:].mean())
    # still in the measured total and in eq. 12's overhead
    assert s["overhead"] > 0.3
    summary = {"speedup": dict(s, n_slices=6), "iterations": 2, "workers": 1,
               "timings": {"total": result.timings.total}}
    assert "one-off setup of 0.3" in speedup_table(summary)
    summary["speedup"]["coarse_setup"] = 0.0
    assert "setup" not in speedup_table(summary)


def test_eq12_runtime_counts_coarse_calls():
    # sum_{k=0}^{N_it} (N_c - k) = 8 + 7 + 6 for N_it = 2, N_c = 8
    assert parareal.parareal_runtime(1.0, 0.0, 2, 8) == 21
    assert parareal.parareal_runtime(0.0, 5.0, 2, 8, overhead=1.5) == 11.5
    assert parareal.speedup(0.0, 1.0, 2, 8) == pytest.approx(4.0)  # N_c / N_it with free G
    with pytest.raises(ValueError):
        parareal.speedup(0.1, 1.0, 9, 8)


def test_predictor_table_and_cli(capsys):
    rows = parareal.predict(0.02, 3, [8, 64, 2])
    assert [r[0] for r in rows] == [8, 64, 2]
    for n_c, theory, bound in rows:
        n_it = min(3, n_c)
        assert theory == pytest.approx(parareal.speedup(0.02, 1.0, n_it, n_c))
        assert bound == pytest.approx(parareal.speedup_bound(0.02, n_it, n_c))
    assert rows[1][1] > rows[0][1]  # more cores, more speedup at a fixed iteration count
    main(["--ratio", "0.02", "--iterations", "3", "--cores", "8", "64"])
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 3 and out[2].split()[0] == "64"
    assert float(out[2].split()[2]) == pytest.approx(rows[1][1], abs=1e-3)


def test_queued_durations_reconstruct_fifo_schedule():
    # 2 workers, 4 tasks of 1 s each, all submitted at t = 0: completions at 1, 1, 2, 2
    assert queued_durations([0, 0, 0, 0], [1, 1, 2, 2], workers=2) == [1, 1, 1, 1]
    # without a worker count every task is taken to start when submitted
    assert queued_durations([0, 0, 0, 0], [1, 1, 2, 2], workers=None) == [1, 1, 2, 2]
    # a task submitted after a worker freed starts when submitted
    assert queued_durations([0, 0, 3], [1, 2, 4], workers=1) == [1, 1, 1]
