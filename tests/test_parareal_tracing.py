"""The engine's contract for tracing coarse solvers (contracts.TracingCoarse; HODMD-Parareal):
both schedules give the same iterates bit for bit, on every executor; a run stopped after an
iteration or in the middle of one resumes bit-identically (traces in the checkpoint and the solve
memo); and the correction is the family's, not eq. 11's."""

from __future__ import annotations

import numpy as np
import pytest
from odes import FailsOnSlice, LinearODE, Stepper

from parastokes import parallel, parareal
from parastokes.coarse.hodmd.solver import HodmdCoarse
from parastokes.core.contracts import TracingCoarse
from parastokes.parareal import algorithm

# three damped oscillators coupled weakly: dx/dt = A x, 6 unknowns
_RNG = np.random.default_rng(3)
_BLOCKS = [np.array([[-0.2, w], [-w, -0.2]]) for w in (2.0, 3.0, 5.0)]
MATRIX = np.zeros((6, 6))
for _i, _b in enumerate(_BLOCKS):
    MATRIX[2 * _i:2 * _i + 2, 2 * _i:2 * _i + 2] = _b
MATRIX += 0.05 * _RNG.normal(size=(6, 6))
PROBLEM = LinearODE(MATRIX)
X0 = np.array([1.0, 0.0, 0.5, 0.5, 0.0, 1.0])
T0, T1, N_SLICES, ITERATIONS = 0.0, 4.0, 8, 4
FINE = Stepper(PROBLEM, 1e-3, order=4)
REFERENCE = parareal.serial_solution(FINE, X0, T0, T1, N_SLICES)


class Identity:
    """A system whose project is the identity (all HodmdCoarse uses of its system)."""

    def project(self, x: np.ndarray) -> np.ndarray:
        return x


def coarse(**kw) -> HodmdCoarse:
    """G1: Euler 0.01, G2: Euler 0.05 on 10 snapshot intervals of 0.05; windows 0.5, 0.6, 1."""
    args = dict(system=Identity(), g1=Stepper(PROBLEM, 0.01, order=1),
                g2=Stepper(PROBLEM, 0.05, order=1), snapshots=10, windows=(5, 6, 10), d=2)
    return HodmdCoarse(**(args | kw))


def run(schedule="standard", executor=None, checkpoint=None, fine=FINE, iterations=ITERATIONS,
        **kw):
    return parareal.run(FINE if fine is None else fine, coarse(), X0, T0, T1, N_SLICES, tol=0.0,
                        max_iterations=iterations, reference=REFERENCE, schedule=schedule,
                        executor=executor, checkpoint=checkpoint, **kw)


CLEAN = run()


def same(result) -> None:
    np.testing.assert_array_equal(result.states, CLEAN.states)
    assert result.increments == CLEAN.increments and result.errors == CLEAN.errors
    assert result.iterations == CLEAN.iterations


@pytest.fixture(scope="module")
def processes():
    with parallel.make_executor("processes", 2) as executor:
        yield executor


def test_the_hodmd_solver_is_a_tracing_coarse_solver_and_converges():
    assert isinstance(coarse(), TracingCoarse)
    errors = np.asarray(CLEAN.errors)
    assert np.all(np.diff(errors) < 0) and errors[-1] < 1e-3 * errors[0]  # 4 orders in 4 steps


def test_the_correction_is_the_authors_not_eq_11():
    """X_n^k = F + [G2(new)_S − G2(old)_S] + H[D(new) − D(old)](T_n): recomputed by hand from the
    family's traces, it equals the iterate; eq. 11 with the end states differs."""
    g = coarse()
    times = CLEAN.times
    first = parareal.run(FINE, g, X0, T0, T1, N_SLICES, tol=0.0, max_iterations=1)
    # X^0 by hand: the initial sweep of end states
    x0 = [X0]
    for n in range(1, N_SLICES + 1):
        x0.append(g(times[n - 1], times[n], x0[-1]))
    n = 3  # slice 3 in iteration 1: X_3^1 from X_2^1 (new) and X_2^0 (old)
    fine = FINE(times[n - 1], times[n], x0[n - 1])
    new = g.trace(times[n - 1], times[n], first.states[n - 1], 1)
    old = g.trace(times[n - 1], times[n], x0[n - 1], 0)
    by_hand = fine + (new[0] - old[0]) + g.extrapolate(new[1:] - old[1:], 5)
    np.testing.assert_array_equal(first.states[n], by_hand)
    eq11 = fine + g.end_state(0, 0, new) - g.end_state(0, 0, old)
    assert np.abs(eq11 - by_hand).max() > 1e-12


@pytest.mark.parametrize("schedule", ["standard", "pipelined"])
def test_both_schedules_and_executors_give_the_same_iterates(schedule, processes):
    same(run(schedule))
    same(run(schedule, executor=processes))


@pytest.mark.parametrize("schedule", ["standard", "pipelined"])
def test_a_run_resumes_from_its_checkpoint_bit_identically(schedule, tmp_path):
    path = tmp_path / "run.npz"
    first = run(schedule, checkpoint=path, iterations=2)
    assert first.iterations == 2 and path.exists()
    same(run(schedule, checkpoint=path))


@pytest.mark.parametrize("schedule", ["standard", "pipelined"])
def test_a_run_interrupted_in_an_iteration_resumes_bit_identically(schedule, tmp_path):
    """Ctrl-C in the 3rd fine solve of slice 3 (iteration 3): the checkpoint holds iteration 2
    (with its traces), the memo the solves of iteration 3; the rerun ends where CLEAN does."""
    markers = tmp_path / "markers"
    markers.mkdir()
    faulty = FailsOnSlice(FINE, CLEAN.times[2], 3, markers, mode="interrupt")
    path = tmp_path / "run.npz"
    with pytest.raises(KeyboardInterrupt):
        run(schedule, checkpoint=path, fine=faulty)
    same(run(schedule, checkpoint=path, fine=faulty))


def test_a_plain_coarse_solver_keeps_eq_11():
    plain = Stepper(PROBLEM, 0.05, order=1)
    assert not algorithm.is_tracing(plain)
    assert algorithm.step_of(plain, 3) is plain and algorithm.correction_of(plain, 0, 1, 2) is None


def test_windows_too_short_for_d_are_refused():
    with pytest.raises(ValueError, match="at least d \\+ 1 = 6 snapshots"):
        coarse(d=5, windows=(4,))


@pytest.mark.parametrize("grid", [None, 2])
def test_an_extrapolated_solvers_snapshots_are_the_solver_over_each_span(grid):
    """trajectory() runs the auxiliary solvers on through the snapshots and combines them at each:
    snapshot j equals the extrapolated G over [t0, t0 + j h] (the same steps), on its grid too."""
    from odes import ToySystem

    from parastokes.coarse.hodmd.solver import trajectory

    system = ToySystem(n_points=5, decay=0.7, a=0.3, b=0.2, c=0.1)
    g = parareal.extrapolated(system, "euler", 0.01, lagrange={"a": [0.4, 0.5, 0.6]},
                              richardson={"m": 1, "r": 0.5}, grid=grid)
    x = system.initial_state()
    snaps = trajectory(g, 0.0, 0.1, 4, x)
    np.testing.assert_array_equal(snaps[0], x if grid is None else g(0.0, 0.0, x))
    for j in (1, 4):
        np.testing.assert_allclose(snaps[j], g(0.0, 0.1 * j, x), rtol=1e-13, atol=1e-13)


GLOBAL = dict(initial=(0.5, 10, 4))  # G1 over 4 of the 8 slices, 10 snapshots each, d0 = 4


def run_global(schedule="standard", executor=None, checkpoint=None, iterations=ITERATIONS):
    return parareal.run(FINE, coarse(**GLOBAL), X0, T0, T1, N_SLICES, tol=0.0,
                        max_iterations=iterations, reference=REFERENCE, schedule=schedule,
                        executor=executor, checkpoint=checkpoint)


def test_the_global_initial_guess_is_the_authors():
    """X^0: G1's chain over the first half of the slices, then G2's chain plus the HODMD
    extrapolation of G1 − G2 (recomputed by hand); every schedule and executor agrees."""
    from parastokes.coarse.hodmd.solver import trajectory

    g = coarse(**GLOBAL)
    times = parareal.time_points(T0, T1, N_SLICES)
    guess = g.initial_guess(times, X0)
    g1 = trajectory(g.g1, T0, 0.05, 40, X0)
    g2 = trajectory(g.g2, T0, 0.05, 80, X0)
    np.testing.assert_array_equal(guess[4], g1[40])
    extra = g.extrapolate(np.array(g1) - np.array(g2[:41]), 40, 4, at=70)
    np.testing.assert_array_equal(guess[7], g2[70] + extra)
    # its extrapolation is worth something: closer to the fine solution than G2's chain
    assert np.abs(guess[8] - REFERENCE[8]).max() < np.abs(g2[80] - REFERENCE[8]).max()
    result = run_global(iterations=1)
    np.testing.assert_array_equal(result.states[:2], np.array([X0, FINE(T0, 0.5, X0)]))


def test_the_global_initial_guess_in_both_schedules_on_every_executor_and_resumed(processes,
                                                                                  tmp_path):
    clean = run_global()
    assert np.all(np.diff(clean.errors) < 0)
    for schedule, executor in (("pipelined", None), ("pipelined", processes)):
        other = run_global(schedule, executor)
        np.testing.assert_array_equal(other.states, clean.states)
        assert other.errors == clean.errors
    for schedule in ("standard", "pipelined"):
        path = tmp_path / f"{schedule}.npz"
        run_global(schedule, checkpoint=path, iterations=1)
        resumed = run_global(schedule, checkpoint=path)
        np.testing.assert_array_equal(resumed.states, clean.states)
