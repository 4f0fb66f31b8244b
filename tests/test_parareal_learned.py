"""The learned (secant) Parareal correction (parastokes/parareal/learned.py): the secant map
reproduces a linear map on its span, the correction reduces to eq. 11 on converged inputs, on a
linear ODE Parareal then converges in fewer iterations than with eq. 11, both schedules give the
same iterates bit for bit, a resumed run the uninterrupted one's, and bad settings are refused."""

from __future__ import annotations

import threading
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from configs import small_rod
from odes import LinearODE, Logistic, Recording, Stepper, oscillator
from test_coarse_hodmd import body_config

from parastokes import cli, parareal
from parastokes.parareal import checkpoint as ckpt
from parastokes.parareal.algorithm import correct
from parastokes.parareal.learned import SecantHistory, secant_step

T0, T1 = 0.0, 2.0


class Pool(ThreadPoolExecutor):
    """A thread pool that says how many tasks run at once."""

    def __init__(self, workers: int) -> None:
        super().__init__(workers)
        self.workers = workers


def _rotation() -> LinearODE:
    """A damped rotation in 3 dimensions (linear: F - G is linear)."""
    return LinearODE([[-0.1, 2.0, 0.0], [-2.0, -0.1, 0.5], [0.0, -0.5, -0.3]])


def test_the_secant_map_interpolates_its_data_and_is_zero_off_its_span():
    rng = np.random.default_rng(3)
    jacobian = rng.standard_normal((6, 6))
    dx = rng.standard_normal((6, 3))
    dd = jacobian @ dx
    for i in range(3):  # the model reproduces its training data
        np.testing.assert_allclose(secant_step(dx, dd, dx[:, i]), dd[:, i], rtol=0, atol=1e-12)
    inside = dx @ np.array([0.5, -2.0, 1.5])
    np.testing.assert_allclose(secant_step(dx, dd, inside), jacobian @ inside, atol=1e-12)
    basis, _ = np.linalg.qr(dx, mode="complete")
    outside = basis[:, 3:] @ np.array([1.0, -1.0, 2.0])  # orthogonal to every column
    np.testing.assert_allclose(secant_step(dx, dd, outside), 0.0, atol=1e-12)
    # a step with parts in and off the span: J of its projection (the minimum-norm map)
    np.testing.assert_allclose(secant_step(dx, dd, inside + outside), jacobian @ inside,
                               atol=1e-12)
    assert not np.any(secant_step(np.zeros((6, 0)), np.zeros((6, 0)), inside))


def _feed(history: SecantHistory, n: int, inputs: list, function) -> None:
    """Slice n's corrections of iterations 1..len(inputs) - 1 with D = ``function``."""
    for k in range(1, len(inputs)):
        history.correction(n, k, inputs[k], inputs[k - 1], function(inputs[k - 1]),
                           np.zeros(3))


def test_the_correction_is_exact_for_an_affine_difference_once_the_steps_span_the_state():
    rng = np.random.default_rng(5)
    jacobian, offset = rng.standard_normal((3, 3)), rng.standard_normal(3)

    def difference(x):
        return jacobian @ x + offset

    inputs = [rng.standard_normal(3) for _ in range(5)]
    history = SecantHistory()
    _feed(history, 2, inputs[:4], difference)  # iterations 1..3: steps 1, 2 known at k = 3
    new = rng.standard_normal(3)
    term = history.correction(2, 4, new, inputs[3], difference(inputs[3]), np.zeros(3))
    # 3 steps (iterations 1..3) span R^3: J = D' exactly
    np.testing.assert_allclose(term, jacobian @ (new - inputs[3]), atol=1e-10)


def test_the_correction_is_eq_11_bit_for_bit_on_a_converged_input():
    rng = np.random.default_rng(7)
    history = SecantHistory()
    inputs = [rng.standard_normal(3) for _ in range(3)]
    _feed(history, 4, inputs, np.sin)
    fine, coarse, previous = (rng.standard_normal(3) for _ in range(3))
    same = inputs[-1].copy()
    learned = correct(fine, coarse, previous, None, (4, 3, 1.0), None,
                      (history, same, inputs[-1]))
    assert np.array_equal(learned, correct(fine, coarse, previous, None))
    assert history.has(4, 2) and not history.has(4, 3) and history.has(9, -1)


def test_a_correction_before_the_previous_iterations_is_refused():
    history = SecantHistory()
    with pytest.raises(RuntimeError, match="slice 2 in iteration 3 before that of iteration 2"):
        history.correction(2, 3, np.ones(2), np.zeros(2), np.ones(2), np.zeros(2))


def test_the_history_round_trips_through_arrays_exactly():
    rng = np.random.default_rng(11)
    history = SecantHistory()
    for n in (2, 3):
        _feed(history, n, [rng.standard_normal(3) for _ in range(4)], np.cos)
    again = SecantHistory.from_arrays(history.to_arrays())
    new, old = rng.standard_normal(3), rng.standard_normal(3)
    for n in (2, 3):
        args = (n, 4, new, old, np.ones(3), np.zeros(3))
        assert np.array_equal(history.correction(*args), again.correction(*args))
    assert SecantHistory().to_arrays() == {}


def _errors(correction: str, problem, n_slices: int, iterations: int, schedule="standard",
            executor=None):
    fine, coarse = Stepper(problem, 0.02, order=4), Stepper(problem, 0.05, order=1)
    x0 = np.array([1.0, 0.0, 0.5][: problem.matrix.shape[0]]) if isinstance(
        problem, LinearODE) else np.array([0.1, 0.4])
    reference = parareal.serial_solution(fine, x0, T0, T1, n_slices)
    return parareal.run(fine, coarse, x0, T0, T1, n_slices, tol=0.0,
                        max_iterations=iterations, reference=reference, schedule=schedule,
                        executor=executor, correction=correction), reference


def test_on_a_linear_ode_the_secant_correction_converges_in_fewer_iterations():
    # F - G is linear: in iteration 4 each slice's 3 steps span R^3 and J = F' - G' exactly,
    # so X^4 is F's serial solution to round-off (eta = 6e-16); eq. 11 still errs by 1.1e-6 and
    # 2.0e-8 after 5 (measured: eta^k = 2.1e-2, 3.8e-5, 1.3e-7, 6e-16 against 2.1e-2, 1.2e-3,
    # 4.4e-5, 1.1e-6, 2.0e-8)
    learned, reference = _errors("secant", _rotation(), 10, 5)
    classical, _ = _errors("classical", _rotation(), 10, 5)

    def first_below(errors, target=1e-12):
        return next((k for k, e in enumerate(errors, 1) if e < target), None)

    assert first_below(learned.errors) == 4 and first_below(classical.errors) is None
    assert learned.errors[2] < 1e-6 < classical.errors[3]
    assert learned.errors[:1] == classical.errors[:1]  # iteration 1 has no steps yet: eq. 11
    # the first k slices are exact after k iterations (Parareal's exactness kept)
    for k in (1, 2, 3):
        run, _ = _errors("secant", _rotation(), 10, k)
        np.testing.assert_array_equal(run.states[: k + 1], reference[: k + 1])


@pytest.mark.parametrize("problem", [_rotation(), Logistic(3.0), oscillator(2.0)],
                         ids=["rotation", "logistic", "oscillator"])
def test_both_schedules_give_the_same_iterates_bit_for_bit(problem):
    standard, _ = _errors("secant", problem, 8, 5)
    pipelined, _ = _errors("secant", problem, 8, 5, "pipelined", Pool(3))
    np.testing.assert_array_equal(pipelined.states, standard.states)
    assert pipelined.errors == standard.errors and pipelined.increments == standard.increments
    classical, _ = _errors("classical", problem, 8, 5)
    assert classical.errors[1:] != standard.errors[1:]  # (the secant term changed something)


class SlowFirstSolve:
    """F, whose first solve of slice ``n`` (iteration 1) takes ``seconds`` longer: the pipelined
    schedule then has X_n^2's inputs before X_n^1's."""

    def __init__(self, fine, times, n: int, seconds: float) -> None:
        self.fine, self.start, self.seconds = fine, times[n - 1], seconds
        self.slept = threading.Lock()

    def __call__(self, t_start: float, t_end: float, x: np.ndarray) -> np.ndarray:
        if t_start == self.start and self.slept.acquire(blocking=False):
            time.sleep(self.seconds)
        return self.fine(t_start, t_end, x)


def test_the_pipelined_schedule_forms_a_slice_s_iterates_in_order():
    problem, x0 = Logistic(3.0), np.array([0.1, 0.4])
    fine, coarse = Stepper(problem, 1e-2, order=4), Stepper(problem, 0.1, order=1)
    times = parareal.time_points(T0, T1, 6)
    args = dict(tol=0.0, max_iterations=4, correction="secant")
    standard = parareal.run(fine, coarse, x0, T0, T1, 6, **args)
    slow = SlowFirstSolve(fine, times, 4, 0.5)
    pipelined = parareal.run(slow, coarse, x0, T0, T1, 6, executor=Pool(6),
                             schedule="pipelined", **args)
    assert slow.slept.locked()  # (the slow solve ran)
    np.testing.assert_array_equal(pipelined.states, standard.states)


@pytest.mark.parametrize("schedule", ["standard", "pipelined"])
def test_a_resumed_run_gives_the_uninterrupted_iterates(schedule, tmp_path):
    problem, x0 = Logistic(3.0), np.array([0.1, 0.4])
    fine, coarse = Stepper(problem, 1e-2, order=4), Stepper(problem, 0.1, order=1)
    args = dict(tol=0.0, schedule=schedule, executor=Pool(2), correction="secant")
    whole = parareal.run(fine, coarse, x0, T0, T1, 8, max_iterations=5, **args)
    path = tmp_path / "checkpoint.npz"
    parareal.run(fine, coarse, x0, T0, T1, 8, max_iterations=3, checkpoint=path, **args)
    assert "secant_inputs" in ckpt.load(path, ckpt.fingerprint(
        x0, T0, T1, 8, None) | {"correction": "secant"}).extra
    resumed = parareal.run(fine, coarse, x0, T0, T1, 8, max_iterations=5, checkpoint=path,
                           **args)
    np.testing.assert_array_equal(resumed.states, whole.states)
    assert resumed.increments == whole.increments
    # a checkpoint of the other correction is refused, naming it
    with pytest.raises(ckpt.CheckpointMismatch, match="correction"):
        parareal.run(fine, coarse, x0, T0, T1, 8, max_iterations=6, checkpoint=path,
                     **(args | {"correction": "classical"}))


class Tracing:
    """A coarse solver with the tracing members (its correction is its own, not eq. 11's)."""

    def __init__(self, coarse) -> None:
        self.coarse = coarse

    def __call__(self, t_start: float, t_end: float, x: np.ndarray) -> np.ndarray:
        return self.coarse(t_start, t_end, x)

    def trace(self, t_start: float, t_end: float, x: np.ndarray, k: int) -> np.ndarray:
        return self.coarse(t_start, t_end, x)

    def end_state(self, t_start: float, t_end: float, trace: np.ndarray) -> np.ndarray:
        return trace

    def correction(self, t_start, t_end, new, old, k) -> np.ndarray:
        return new - old


def test_bad_corrections_are_refused_before_any_solve():
    problem = Logistic(3.0)
    fine = Recording(Stepper(problem, 1e-2, order=4))
    with pytest.raises(ValueError, match="correction must be one of"):
        parareal.run(fine, fine, np.array([0.1]), T0, T1, 4, tol=0.0, correction="newton")
    with pytest.raises(ValueError, match="'secant' needs a coarse solver whose correction is"):
        parareal.run(fine, Tracing(fine), np.array([0.1]), T0, T1, 4, tol=0.0,
                     correction="secant")
    assert not fine.calls
    run = parareal.run(fine, Tracing(fine), np.array([0.1]), T0, T1, 4, tol=0.0,
                       max_iterations=1)  # (the tracing solver itself runs, with eq. 11's rule)
    assert run.iterations == 1


@pytest.mark.parametrize("text, override, words", [
    (small_rod(rest='[execution]\nexecutor = "serial"\n'), 'parareal.correction="newton"',
     "'classical' or 'secant'"),
    (body_config("rod"), 'parareal.correction="secant"', "the hodmd coarse solver replaces"),
], ids=["unknown", "hodmd"])
def test_check_refuses_a_bad_correction_in_one_line(text, override, words, tmp_path, capsys):
    path = tmp_path / "rod.toml"
    path.write_text(text)
    assert cli.main(["check", str(path), "--set", override]) == 2
    lines = [line for line in capsys.readouterr().err.strip().splitlines()
             if not line.startswith("note: running the parastokes of")]
    assert len(lines) == 2 and lines[1].strip().startswith("parareal.correction: ")
    assert words in lines[1]
    assert cli.main(["check", str(path)]) == 0  # (the same problem with eq. 11 is valid)


def test_a_run_from_a_config_uses_the_correction(tmp_path):
    import json

    text = small_rod(parareal="max_iterations = 3\ntol = 0.0",
                     rest='[execution]\nexecutor = "serial"\n[output]\nfigures = false\n'
                     ).replace("t1 = 0.002", "t1 = 0.0004")
    path = tmp_path / "rod.toml"
    path.write_text(text)
    errors = {}
    for correction in ("classical", "secant"):
        out = tmp_path / correction
        assert cli.main(["run", str(path), "--out", str(out), "-q", "--set",
                         f'parareal.correction="{correction}"']) == 0
        errors[correction] = json.loads((out / "summary.json").read_text())["errors"]
    # iteration 1 has no steps to learn from (eq. 11 both); from iteration 2 the secant's
    assert errors["secant"][0] == errors["classical"][0]
    assert errors["secant"][1:] != errors["classical"][1:]


def test_the_benchmark_s_gaussian_process_interpolates_and_reverts_to_its_zero_mean():
    from benchmarks.learned import LENGTHSCALES, gp_fit, gp_mean

    rng = np.random.default_rng(13)
    inputs = rng.standard_normal((12, 4))
    outputs = np.column_stack([np.sin(inputs @ [1.0, 0.5, -0.3, 0.2]), inputs[:, 0] ** 2])
    d2 = ((inputs[:, None, :] - inputs[None, :, :]) ** 2).sum(-1)
    scale, weights = gp_fit(d2, outputs)
    for x, y in zip(inputs, outputs, strict=True):  # (nugget 1e-10: interpolation)
        np.testing.assert_allclose(gp_mean(scale, weights, inputs, x), y, atol=1e-5)
    assert np.allclose(gp_mean(scale, weights, inputs, np.full(4, 1e3)), 0.0)
    # the lengthscale is the grid's likeliest (the profiled log marginal likelihood, eq. of
    # GParareal's fit with the signal variance at its optimum)

    def likelihood(length):
        kernel = np.exp(-d2 / (2 * length**2)) + 1e-10 * np.eye(12)
        fit = np.sum(outputs * np.linalg.solve(kernel, outputs)) / outputs.size
        return (-0.5 * outputs.size * np.log(fit)
                - 0.5 * outputs.shape[1] * np.linalg.slogdet(kernel)[1])

    grid = LENGTHSCALES * np.sqrt(np.median(d2[d2 > 0]))
    assert scale == grid[int(np.argmax([likelihood(length) for length in grid]))]


def test_the_benchmark_s_solve_cache_is_keyed_by_the_input_s_bytes():
    from benchmarks.learned import _key

    x = np.linspace(0.0, 1.0, 6)
    assert _key("fine", 0.0, 0.025, x) == _key("fine", 0.0, 0.025, x.copy())
    nudged = x.copy()
    nudged[3] = np.nextafter(nudged[3], 2.0)  # one ulp
    assert _key("fine", 0.0, 0.025, nudged) != _key("fine", 0.0, 0.025, x)
    assert _key("coarse", 0.0, 0.025, x) != _key("fine", 0.0, 0.025, x)
    assert _key("fine", 0.025, 0.05, x) != _key("fine", 0.0, 0.025, x)
