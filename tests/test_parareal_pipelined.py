"""The pipelined schedule: Algorithm 1's iterates bit for bit, on every executor.

Toy ODEs (tests/odes.py), a small rod and a small vesicle; serial, threads, processes and MPI; a
plain and an extrapolated coarse solver; stopping, cancellation, failures and resume.
"""

from __future__ import annotations

import threading
import time
from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np
import pytest
from configs import small_rod
from mpi_scripts import parareal_rod
from mpi_scripts.launch import POOL, SCRIPTS, SKIP_REASON, mpiexec
from odes import (
    Exact,
    FailsOnSlice,
    FaultyToySystem,
    Logistic,
    Recording,
    Stepper,
    ToySystem,
    oscillator,
)

from parastokes import cli, config, integrate, models, parallel, parareal
from parastokes.output import trajectory as io
from parastokes.output.gantt import gantt
from parastokes.parareal import checkpoint as ckpt
from parastokes.parareal.timings import MANAGER

T0, T1 = 0.0, 2.0
PROBLEMS = {
    "logistic": (Logistic(3.0), np.array([0.1, 0.4])),
    "oscillator": (oscillator(2.0), np.array([1.0, 0.0])),
}


def _solvers(problem):
    return Stepper(problem, 1e-2, order=4), Stepper(problem, 0.1, order=1)


class Pool(ThreadPoolExecutor):
    """A thread pool that says how many tasks run at once."""

    def __init__(self, workers: int) -> None:
        super().__init__(workers)
        self.workers = workers


def _both(fine, coarse, x0, n, executor=None, **kw):
    """The same run by both schedules, and the final states of every iteration of each."""
    results, finals = [], []
    for schedule in ("standard", "pipelined"):
        seen = []
        res = parareal.run(
            fine,
            coarse,
            x0,
            T0,
            T1,
            n,
            executor=executor,
            schedule=schedule,
            on_iteration=lambda report, seen=seen: seen.append(report.final_state),
            **kw,
        )
        results.append(res)
        finals.append(seen)
    return results, finals


def _assert_same(standard, pipelined):
    np.testing.assert_array_equal(pipelined.states, standard.states)
    assert pipelined.increments == standard.increments
    assert pipelined.errors == standard.errors
    assert pipelined.iterations == standard.iterations
    assert pipelined.stop_reason == standard.stop_reason
    assert pipelined.timings.schedule == "pipelined" and standard.timings.schedule == "standard"


EXECUTORS = {
    "in-process": lambda: None,
    "serial": parallel.SerialExecutor,
    "threads, 2 workers": lambda: Pool(2),
    "threads, no workers attribute": lambda: ThreadPoolExecutor(3),
}


@pytest.mark.parametrize("executor", sorted(EXECUTORS))
@pytest.mark.parametrize("name", sorted(PROBLEMS))
def test_toy_odes_bit_identical_at_every_iteration(name, executor):
    problem, x0 = PROBLEMS[name]
    fine, coarse = _solvers(problem)
    pool = EXECUTORS[executor]()
    reference = parareal.serial_solution(fine, x0, T0, T1, 5)
    for k in range(1, 6):  # every iteration: the whole iterate X^k, not only its end
        (std, pipe), (f_std, f_pipe) = _both(
            fine, coarse, x0, 5, pool, tol=0.0, max_iterations=k, reference=reference
        )
        _assert_same(std, pipe)
        assert len(f_pipe) == k
        assert all(np.array_equal(a, b) for a, b in zip(f_std, f_pipe, strict=True))
    assert pipe.stop_reason == "all_slices"
    np.testing.assert_array_equal(pipe.states, reference)


@pytest.mark.parametrize("tol", [1e-2, 1e-4, 1e-7])
def test_same_stopping_iteration_on_the_tolerance(tol):
    problem, x0 = PROBLEMS["logistic"]
    fine, coarse = _solvers(problem)
    (std, pipe), _ = _both(fine, coarse, x0, 8, Pool(4), tol=tol, max_iterations=8)
    _assert_same(std, pipe)
    assert std.stop_reason == "tolerance" and 1 <= std.iterations < 8


def test_projection_is_applied_as_in_algorithm_1():
    problem, x0 = PROBLEMS["oscillator"]
    fine, coarse = _solvers(problem)
    unit = lambda x: x / np.linalg.norm(x)  # noqa: E731 (in-process executors only)
    (std, pipe), _ = _both(fine, coarse, x0, 6, Pool(3), tol=0.0, max_iterations=3, project=unit)
    _assert_same(std, pipe)


def test_work_only_on_inexact_slices_and_up_to_the_last_iteration():
    problem, x0 = PROBLEMS["oscillator"]
    fine, coarse = Recording(_solvers(problem)[0]), Recording(_solvers(problem)[1])
    n, k = 6, 3
    res = parareal.run(fine, coarse, x0, T0, T1, n, 0.0, k, schedule="pipelined")
    times = res.times
    expected_fine = [(times[i - 1], times[i]) for j in range(1, k + 1) for i in range(j, n + 1)]
    expected_coarse = [(times[i - 1], times[i]) for j in range(k + 1) for i in range(j + 1, n + 1)]
    assert sorted(fine.calls) == sorted(expected_fine)  # F_n^k for n >= k only, k <= K
    assert sorted(coarse.calls) == sorted(expected_coarse)  # G_n^k for n > k only
    assert [len(f) for f in res.timings.fine] == [n - j + 1 for j in range(1, k + 1)]
    assert [len(c) for c in res.timings.coarse] == [n - j for j in range(k + 1)]


def test_tasks_start_before_the_previous_sweep_ends():
    # the point of pipelining: fine solves of iteration 1 overlap the initial coarse sweep
    problem, x0 = PROBLEMS["logistic"]
    fine, coarse = _solvers(problem)
    res = parareal.run(fine, coarse, x0, T0, T1, 6, 0.0, 2, executor=Pool(4), schedule="pipelined")
    tasks = res.timings.tasks
    first_fine = min(t[3] for t in tasks if t[0] == "fine")
    last_initial_coarse = max(t[4] for t in tasks if t[0] == "coarse" and t[2] == 0)
    assert first_fine < last_initial_coarse
    assert {t[5] for t in tasks} <= set(range(4))  # never more than 4 tasks at once
    for task in tasks:
        assert 0.0 <= task[3] <= task[4] <= res.timings.total
    # at most 4 tasks overlap at any instant
    for _, _, _, start, _, _ in tasks:
        assert sum(t[3] <= start < t[4] for t in tasks) <= 4


class Slow:
    """A propagator that counts its calls when they start and sleeps first."""

    def __init__(self, propagator, seconds: float) -> None:
        self.propagator, self.seconds = propagator, seconds
        self.started = 0
        self.lock = threading.Lock()

    def __call__(self, t_start, t_end, x):
        with self.lock:
            self.started += 1
        time.sleep(self.seconds)
        return self.propagator(t_start, t_end, x)


def test_work_beyond_the_stopping_iteration_is_cancelled():
    problem, x0 = PROBLEMS["oscillator"]
    fine = Slow(Exact(problem), 0.02)
    n = 12
    with Pool(3) as pool:
        # an exact coarse solver: eta~^1 = 0 < tol stops the run after iteration 1
        res = parareal.run(
            fine, Exact(problem), x0, T0, T1, n, 1e-12, n, pool, schedule="pipelined"
        )
        started = fine.started
        time.sleep(0.2)
        assert fine.started == started  # nothing starts after the run returned
    assert res.iterations == 1 and res.stop_reason == "tolerance"
    assert started < n + (n - 1)  # not all of iteration 2 was started


@pytest.fixture(scope="module")
def processes():
    with parallel.make_executor("processes", 2) as executor:
        yield executor


# ---- extrapolated coarse solvers: every auxiliary solve is a task ------------------------------
def _toy_extrapolated(system, **kw):
    return parareal.extrapolated(
        system, "euler", 0.05, lagrange={"a": [0.4, 0.5, 0.6], "b": [1.1, 1.2]}, **kw
    )


@pytest.mark.parametrize("kind", ["in-process", "threads", "processes"])
def test_extrapolated_coarse_solver_bit_identical(kind, request):
    system = ToySystem(decay=0.5, a=0.2, b=1.0, c=0.1)
    x0 = system.initial_state()
    fine = integrate.Propagator(system, "rk4", 0.01)
    coarse = _toy_extrapolated(system)
    executor = {
        "in-process": lambda: None,
        "threads": lambda: Pool(4),
        "processes": lambda: request.getfixturevalue("processes"),
    }[kind]()
    (std, pipe), _ = _both(
        fine, coarse, x0, 5, executor, tol=0.0, max_iterations=3, allow_oversubscribe=True
    )
    _assert_same(std, pipe)
    auxiliary = [t for t in pipe.timings.tasks if t[0] == "auxiliary"]
    assert len(auxiliary) == coarse.n_auxiliary * (5 + 4 + 3 + 2)  # one task per auxiliary solve
    assert not any(t[0] == "coarse" for t in pipe.timings.tasks)


def test_extrapolated_on_a_coarse_grid_bit_identical():
    system = ToySystem(n_points=9, decay=0.5, a=0.2, b=1.0, c=0.1)
    fine = integrate.Propagator(system, "rk4", 0.01)
    coarse = _toy_extrapolated(system, grid=2)
    (std, pipe), _ = _both(
        fine,
        coarse,
        system.initial_state(),
        4,
        Pool(3),
        tol=0.0,
        max_iterations=2,
        allow_oversubscribe=True,
    )
    _assert_same(std, pipe)


def test_split_equals_call_bit_for_bit():
    system = ToySystem(decay=0.5, a=0.2, b=1.0, c=0.1)
    coarse = parareal.extrapolated(
        system, "euler", 0.05, lagrange={"a": [0.4, 0.5, 0.6]}, richardson={"m": 1, "r": 0.5}
    )
    x = system.initial_state()
    tasks, combine = coarse.split(0.0, 0.3, x)
    assert len(tasks) == coarse.n_auxiliary == 6
    assert tasks[0].label.startswith("auxiliary coarse solver 0 (a=0.4")
    values = [task.fn(*task.args) for task in tasks]
    np.testing.assert_array_equal(combine(values), coarse(0.0, 0.3, x))


# ---- a small rod and a small vesicle ---------------------------------------------------------
def test_rod_bit_identical_serial_and_processes(processes):
    serial = parareal_rod.solve(parallel.SerialExecutor())
    for executor in (parallel.SerialExecutor(), processes):
        states, increments = parareal_rod.solve(executor, schedule="pipelined")
        assert np.array_equal(states, serial[0])
        assert np.array_equal(increments, serial[1])


@pytest.mark.mpi
@pytest.mark.skipif(SKIP_REASON is not None, reason=str(SKIP_REASON))
def test_rod_bit_identical_on_mpi(tmp_path):
    run = mpiexec([*POOL, str(SCRIPTS / "parareal_pipelined.py"), str(tmp_path)], ranks=3)
    assert run.returncode == 0, run.stderr
    states, increments = parareal_rod.solve(parallel.SerialExecutor())
    assert np.array_equal(np.load(tmp_path / "states.npy"), states)
    assert np.array_equal(np.load(tmp_path / "increments.npy"), increments)


def test_vesicle_bit_identical(processes):
    ves = models.vesicle(subdivisions=1)
    eps = ves.params["epsilon"]
    fine = integrate.Propagator(ves, "rk2", 1e-3)
    coarse = parareal.extrapolated(
        ves, "euler", 5e-3, lagrange={"epsilon": [1.3 * eps, 1.45 * eps]}
    )
    x0 = ves.initial_state()
    kw = dict(tol=0.0, max_iterations=2, project=ves.project, positions=ves.positions)
    std = parareal.run(fine, coarse, x0, 0.0, 0.08, 4, **kw)
    for executor in (None, processes):
        pipe = parareal.run(
            fine, coarse, x0, 0.0, 0.08, 4, executor=executor, schedule="pipelined", **kw
        )
        _assert_same(std, pipe)


# ---- failures and resume ---------------------------------------------------------------------
N_SLICES, ITERATIONS = 6, 4
X0 = np.array([0.1, 0.3])
FINE = Stepper(Logistic(3.0), 1e-3, order=4)
COARSE = Stepper(Logistic(3.0), 0.05, order=1)
TIMES = parareal.time_points(T0, T1, N_SLICES)
CLEAN = parareal.run(FINE, COARSE, X0, T0, T1, N_SLICES, 0.0, ITERATIONS)


def _pipelined(fine, executor=None, checkpoint=None, iterations=ITERATIONS, **kw):
    """The logistic problem of CLEAN (tol 0), by the pipelined schedule unless ``schedule``."""
    kw = {"schedule": "pipelined", **kw}
    return parareal.run(
        fine, COARSE, X0, T0, T1, N_SLICES, 0.0, iterations, executor, checkpoint=checkpoint, **kw
    )


@pytest.mark.parametrize("kind", ["in-process", "threads", "processes"])
def test_failing_fine_solve_is_labelled_and_resumes(kind, tmp_path, request):
    executor = {
        "in-process": lambda: None,
        "threads": lambda: Pool(3),
        "processes": lambda: request.getfixturevalue("processes"),
    }[kind]()
    markers = tmp_path / "markers"
    markers.mkdir()
    # the 2nd solve of slice 3 to start: iteration 2, or 3 when F_3^3 started before F_3^2
    # (pipelining allows that: F_3^3 needs only X_2^2 = F_2^2, F_3^2 also the coarse step
    # G_2^1), or even 1 when two solves of slice 3 were in flight and the later one started first
    faulty = FailsOnSlice(FINE, TIMES[2], 2, markers)
    path = tmp_path / "run.npz"
    with pytest.raises(parallel.TaskError) as info:
        _pipelined(faulty, executor, path)
    err = info.value
    k = int(err.label.removeprefix("fine solve of slice 3 in iteration "))
    assert k in (1, 2, 3)
    assert str(err).startswith(f"{err.label} failed: RuntimeError: injected fault")
    assert isinstance(err.original, RuntimeError) and err.__cause__ is err.original
    assert any(f"holds iteration {k - 1}" in note for note in err.__notes__)
    key = ckpt.fingerprint(X0, T0, T1, N_SLICES, None)
    assert ckpt.load(path, key).iteration == k - 1  # the iterations before it were saved
    for schedule in ("pipelined", "standard"):  # resume by either schedule
        copy = tmp_path / f"{schedule}.npz"
        copy.write_bytes(path.read_bytes())
        res = _pipelined(FINE, executor, copy, schedule=schedule)
        np.testing.assert_array_equal(res.states, CLEAN.states)
        assert res.increments == CLEAN.increments


def test_dead_worker_is_named_and_the_run_resumes(tmp_path):
    markers = tmp_path / "markers"
    markers.mkdir()
    faulty = FailsOnSlice(FINE, TIMES[2], 2, markers, mode="exit")
    path = tmp_path / "run.npz"
    with parallel.make_executor("processes", 2) as executor:
        with pytest.raises(parallel.TaskError) as info:
            _pipelined(faulty, executor, path)
    err = info.value
    assert err.label in [f"fine solve of slice 3 in iteration {k}" for k in (1, 2, 3)]
    assert isinstance(err.original, parallel.WorkerDiedError) and err.original.exitcode == 3
    res = _pipelined(FINE, None, path)  # the broken pool is gone: resume in-process
    np.testing.assert_array_equal(res.states, CLEAN.states)
    assert res.increments == CLEAN.increments


def test_failing_auxiliary_solve_is_labelled():
    # (N_G = 3 auxiliary solves on 2 workers: no N_G <= N_c rule in the pipelined schedule)
    system = FaultyToySystem(fail_a=0.6, fail_after=0.8, decay=0.5, a=0.2, b=1.0)
    coarse = parareal.extrapolated(system, "euler", 0.05, lagrange={"a": [0.4, 0.5, 0.6]})
    fine = integrate.Propagator(ToySystem(decay=0.5, a=0.2, b=1.0), "rk4", 0.01)
    x0 = system.initial_state()
    with pytest.raises(parallel.TaskError) as info:
        parareal.run(fine, coarse, x0, 0.0, 2.0, 5, 0.0, 2, executor=Pool(2), schedule="pipelined")
    assert info.value.label.startswith(
        "auxiliary coarse solver 2 (a=0.6, step 0.05) in the coarse solve of slice 3 in iteration 0"
    )


class FailsAfterIterationOne:
    """The fine solver, failing on the slice that starts at ``t_start`` from any state but
    ``first`` (X_{n-1}^0): it fails in iterations >= 2 only, whatever the order of the calls."""

    def __init__(self, propagator, t_start: float, first: np.ndarray) -> None:
        self.propagator, self.t_start, self.first = propagator, t_start, first

    def __call__(self, t_start, t_end, x):
        if t_start == self.t_start and not np.array_equal(x, self.first):
            raise RuntimeError("injected fault in iteration >= 2")
        return self.propagator(t_start, t_end, x)


def test_failure_in_work_beyond_the_stopping_iteration_is_discarded():
    # F_5^k fails for k >= 2, but eta~^1 < tol stops the run at k = 1: Algorithm 1 never runs
    # those solves, and the pipelined schedule must not report their failure
    first = parareal.run(FINE, COARSE, X0, T0, T1, N_SLICES, 0.0, 1)
    tol = 2.0 * first.increments[0]
    initial = parareal.serial_solution(COARSE, X0, T0, T1, N_SLICES)  # X^0, eq. 9
    faulty = FailsAfterIterationOne(FINE, TIMES[4], initial[4])
    with pytest.raises(parallel.TaskError, match="slice 5 in iteration 2"):
        parareal.run(faulty, COARSE, X0, T0, T1, N_SLICES, 0.0, 3)  # (the fault is real)
    for executor in (None, Pool(3)):
        res = parareal.run(
            faulty, COARSE, X0, T0, T1, N_SLICES, tol, 3, executor, schedule="pipelined"
        )
        assert res.iterations == 1 and res.stop_reason == "tolerance"
        np.testing.assert_array_equal(res.states, first.states)


def test_interrupt_leaves_a_resumable_checkpoint(tmp_path):
    markers = tmp_path / "markers"
    markers.mkdir()
    faulty = FailsOnSlice(FINE, TIMES[2], 2, markers, mode="interrupt")
    path = tmp_path / "run.npz"
    with pytest.raises(KeyboardInterrupt):
        _pipelined(faulty, None, path)
    key = ckpt.fingerprint(X0, T0, T1, N_SLICES, None)
    assert ckpt.load(path, key).iteration >= 1
    res = _pipelined(FINE, None, path)
    np.testing.assert_array_equal(res.states, CLEAN.states)


def test_unknown_schedule_is_rejected_before_any_work():
    fine = Recording(FINE)
    with pytest.raises(ValueError, match="schedule must be one of"):
        parareal.run(fine, COARSE, X0, T0, T1, N_SLICES, 0.0, 2, schedule="eager")
    assert fine.calls == []


class InstantExecutor:
    """A minimal concurrent.futures-shaped executor without ``workers`` or ``shutdown``."""

    def submit(self, fn, *args):
        future = Future()
        future.set_result(fn(*args))
        return future


def test_any_executor_with_submit_works():
    res = _pipelined(FINE, InstantExecutor())
    np.testing.assert_array_equal(res.states, CLEAN.states)
    assert res.increments == CLEAN.increments


# ---- configuration, command line, Gantt chart --------------------------------------------------
TINY = small_rod(
    parareal="max_iterations = 2",
    rest='[execution]\nexecutor = "serial"\n[output]\nformats = ["png"]\ntrajectory = false\n',
)


@pytest.fixture(scope="module")
def tiny_runs(tmp_path_factory):
    """The same small rod configuration run by both schedules (``parareal.schedule``)."""
    root = tmp_path_factory.mktemp("schedules")
    path = root / "tiny.toml"
    path.write_text(TINY)
    outs = {}
    for schedule in ("standard", "pipelined"):
        out = root / schedule
        args = ["run", str(path), "--out", str(out), "-q", "--set"]
        assert cli.main([*args, f'parareal.schedule="{schedule}"']) == 0
        outs[schedule] = out
    return path, outs


def test_config_schedule_gives_the_same_run_and_a_gantt_chart(tiny_runs):
    _, outs = tiny_runs
    summaries = {s: io.read_summary(out / "summary.json") for s, out in outs.items()}
    std, pipe = summaries["standard"], summaries["pipelined"]
    assert pipe["config"]["parareal"]["schedule"] == "pipelined"
    assert pipe["timings"]["schedule"] == "pipelined" and std["timings"]["schedule"] == "standard"
    assert pipe["final_positions"] == std["final_positions"]
    assert pipe["errors"] == std["errors"] and pipe["increments"] == std["increments"]
    for schedule, summary in summaries.items():
        tasks = summary["timings"]["tasks"]
        kinds = {task[0] for task in tasks}
        assert kinds == ({"fine", "coarse"} if schedule == "standard" else {"fine", "auxiliary"})
        assert (outs[schedule] / "gantt.png").exists()  # drawn with the run's figures
    # the standard schedule's coarse steps run on the manager
    assert {t[5] for t in std["timings"]["tasks"] if t[0] == "coarse"} == {MANAGER}


def test_plot_draws_the_gantt_chart_of_a_run_directory(tiny_runs, tmp_path):
    _, outs = tiny_runs
    (outs["pipelined"] / "gantt.png").unlink()
    assert cli.main(["plot", str(outs["pipelined"]), "--formats", "png", "-q"]) == 0
    assert (outs["pipelined"] / "gantt.png").exists()
    # a simulated schedule draws the same way
    sim = parareal.simulate("pipelined", 6, 2, 3, 0.2, n_auxiliary=2)
    assert gantt(sim.tasks, tmp_path / "sim", ["png"]) == [tmp_path / "sim.png"]


def test_predict_shows_both_schedules(tiny_runs, capsys):
    path, _ = tiny_runs
    args = ["predict", str(path), "--cores", "4", "40", "--ratio", "0.05", "--iterations", "2"]
    assert cli.main(args) == 0
    lines = capsys.readouterr().out.splitlines()
    header = next(i for i, line in enumerate(lines) if "std sim" in line)  # after the baseline's
    assert "pipe sim" in lines[header]
    n_aux = 4  # (2 Lagrange nodes x Richardson m = 1)
    for line, cores in zip(lines[header + 1:header + 3], (4, 40), strict=True):
        row = line.split()
        (expected,) = parareal.predict_schedules(0.05, 2, [cores], n_aux)
        assert int(row[0]) == cores
        assert float(row[5]) == round(expected["standard_formula"], 3)
        assert float(row[6]) == round(expected["standard"], 3)
        assert float(row[7]) == round(expected["pipelined_formula"], 3)
        assert float(row[8]) == round(expected["pipelined"], 3)
    assert cli.main([*args, "--workers", "2"]) == 0
    assert "W = 2 workers" in capsys.readouterr().out


@pytest.mark.parametrize("bad", [["--cores", "0"], ["--cores", "4", "-2"], ["--workers", "0"]])
def test_predict_rejects_bad_core_counts(tiny_runs, capsys, bad):
    path, _ = tiny_runs
    args = ["predict", str(path), *bad]
    if bad[0] == "--workers":
        args += ["--cores", "4"]
    assert cli.main(args) == cli.ExitCode.CONFIG
    err = capsys.readouterr().err
    assert "must be at least 1" in err


def test_resume_after_max_iterations_and_wall_time_is_bit_identical(tmp_path):
    path = tmp_path / "run.npz"
    first = _pipelined(FINE, None, path, iterations=2)
    assert first.iterations == 2 and first.stop_reason == "max_iterations"
    # wall_time_limit: one iteration per call at least, then a clean stop
    res = _pipelined(FINE, None, path, wall_time_limit=1e-9)
    assert res.iterations == 3 and res.stop_reason == "wall_time"
    res = _pipelined(FINE, Pool(2), path)
    np.testing.assert_array_equal(res.states, CLEAN.states)
    assert res.increments == CLEAN.increments
    assert [len(f) for f in res.timings.fine] == [6, 5, 4, 3]
    kinds = {(t[0], t[2]) for t in res.timings.tasks}  # tasks of every session are kept
    assert {("coarse", 0), ("fine", 1), ("fine", 3), ("fine", 4)} <= kinds


def test_check_accepts_more_auxiliary_solves_than_workers_when_pipelined(tmp_path):
    path = tmp_path / "c.toml"
    path.write_text(small_rod(rest="[execution]\nworkers = 2\n"))  # N_G = 4 > 2 workers
    with pytest.raises(config.ConfigError, match="N_G = 4"):
        config.load(path)
    cfg, resolved = config.load(path, ['parareal.schedule="pipelined"'])
    assert cfg.parareal.schedule == "pipelined" and resolved.n_auxiliary == 4


def test_a_pipelined_runs_theoretical_speedup_is_its_schedules_model():
    """speedup(): eqs. 14-15 for Algorithm 1; for the pipelined schedule the simulation on N_c
    workers and its critical path, fed with the same measured gamma_G, gamma_F (and the same for
    every iteration in the runner's report)."""
    fine, coarse = _solvers(PROBLEMS["logistic"][0])
    (standard, pipelined), _ = _both(
        fine, coarse, PROBLEMS["logistic"][1], 8, Pool(8), tol=0.0, max_iterations=3
    )
    for res, schedule in ((standard, "standard"), (pipelined, "pipelined")):
        s = res.speedup()
        g, f, k, n = s["gamma_G"], s["gamma_F"], res.iterations, res.n_slices
        assert s["schedule"] == schedule
        if schedule == "standard":
            assert s["theoretical"] == parareal.speedup(g, f, k, n)
            assert s["bound"] == parareal.speedup_bound(g / f, k, n)
        else:
            assert s["theoretical"] == pytest.approx(
                n / parareal.simulate("pipelined", n, k, n, g / f).wall, rel=1e-12
            )
            assert s["bound"] == pytest.approx(n * f / (k * f + (n - k) * g), rel=1e-12)
            # the pipelined model beats Algorithm 1's at the same gammas, and stays below its
            # critical path
            assert parareal.speedup(g, f, k, n) < s["theoretical"] <= s["bound"] * (1 + 1e-12)
