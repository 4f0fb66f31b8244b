"""Adaptive schemes (rtol) and ``scheme = "auto"`` in Parareal's coarse solver, ``tune`` and
``plan`` (issue 49's "Done when"; issue 50: an adaptive coarse solver reports its step counts).

The counts of an adaptive coarse solver are checked against the same propagator run directly
(``integrate.run``) over each slice from the very states Parareal fed it, on the serial and the
process-pool executors, which must agree bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from test_plan import CONFIG as PLAN_ROD

from parastokes import integrate, models, parallel, parareal

N_SLICES = 3
T1 = 3e-4


def _rod():
    return models.rod_swimmer(n_points=21)


def _solve(executor, scheme: str, lagrange: dict | None = None, iterations: int = 2,
           schedule: str = "standard"):
    rod = _rod()
    fine = integrate.Propagator(rod, "rk2", 1e-6)
    coarse = parareal.extrapolated(rod, scheme, 2e-5, lagrange=lagrange, rtol=1e-4,
                                   allow_oversubscribe=True)
    result = parareal.run(fine, coarse, rod.initial_state(), t0=0.0, t1=T1, n_slices=N_SLICES,
                           tol=0.0, max_iterations=iterations, executor=executor,
                           allow_oversubscribe=True, schedule=schedule)
    return rod, result


@pytest.fixture(scope="module")
def pool():
    with parallel.make_executor("processes", 2) as executor:
        yield executor


@pytest.fixture(scope="module")
def ros2_serial():
    with parallel.make_executor("serial") as executor:
        return _solve(executor, "ros2", lagrange={"epsilon": [1.03, 1.06]})


def test_adaptive_coarse_counts_equal_direct_runs_over_each_slice(ros2_serial):
    rod, result = ros2_serial
    steps = result.timings.coarse_steps
    assert len(steps) == result.iterations + 1  # the initial sweep, then one per iteration
    # the initial sweep (eq. 9) runs G from X_{n-1}^0 on every slice; X^0 is its own output
    times = result.times
    x = rod.initial_state()
    accepted = rejected = 0
    g = parareal.extrapolated(rod, "ros2", 2e-5, lagrange={"epsilon": [1.03, 1.06]}, rtol=1e-4)
    for n in range(1, N_SLICES + 1):
        for p in (p for row in g.auxiliary for p in row):
            r = integrate.run(p.system, x, times[n - 1], times[n], "ros2", p.dt, rtol=1e-4)
            accepted += r.n_steps
            rejected += r.n_rejected
        x = g(times[n - 1], times[n], x)
    assert steps[0] == {"accepted": accepted, "rejected": rejected, "switches": 0}
    assert accepted > 0
    # iteration k runs G on slices n = k+1..N: fewer solves, fewer steps
    assert 0 < steps[2]["accepted"] < steps[1]["accepted"] < steps[0]["accepted"]


def test_adaptive_coarse_counts_serial_equal_processes(ros2_serial, pool):
    _, serial = ros2_serial
    _, pooled = _solve(pool, "ros2", lagrange={"epsilon": [1.03, 1.06]})
    assert pooled.timings.coarse_steps == serial.timings.coarse_steps
    assert np.array_equal(pooled.states, serial.states)


def test_pipelined_counts_equal_the_standard_schedules_on_serial_and_processes(ros2_serial,
                                                                               pool):
    """The pipelined schedule takes each coarse step's counts as it combines its auxiliary
    solves and sums them per iteration (docs/parareal.md): Algorithm 1's counts, bit for bit."""
    _, standard = ros2_serial
    with parallel.make_executor("serial") as executor:
        _, serial = _solve(executor, "ros2", lagrange={"epsilon": [1.03, 1.06]},
                           schedule="pipelined")
    _, pooled = _solve(pool, "ros2", lagrange={"epsilon": [1.03, 1.06]}, schedule="pipelined")
    assert len(standard.timings.coarse_steps) == standard.iterations + 1
    assert serial.timings.coarse_steps == standard.timings.coarse_steps
    assert pooled.timings.coarse_steps == standard.timings.coarse_steps
    assert np.array_equal(serial.states, standard.states)


def test_fixed_coarse_reports_no_counts():
    rod = _rod()
    coarse = parareal.extrapolated(rod, "euler", 2e-5)
    result = parareal.run(integrate.Propagator(rod, "rk2", 1e-6), coarse, rod.initial_state(),
                          t0=0.0, t1=T1, n_slices=N_SLICES, tol=0.0, max_iterations=1)
    assert result.timings.coarse_steps == []


def test_auto_coarse_converges_and_processes_equal_serial(pool):
    with parallel.make_executor("serial") as executor:
        rod, serial = _solve(executor, "auto", iterations=N_SLICES)
    _, pooled = _solve(pool, "auto", iterations=N_SLICES)
    assert np.array_equal(pooled.states, serial.states)
    assert pooled.timings.coarse_steps == serial.timings.coarse_steps
    # k = N: Parareal is the serial fine solution (Algorithm 1's exactness)
    exact = parareal.serial_solution(integrate.Propagator(rod, "rk2", 1e-6), rod.initial_state(),
                                     0.0, T1, N_SLICES)
    np.testing.assert_allclose(serial.states, exact, rtol=0, atol=1e-12)
    assert serial.increments[-1] < serial.increments[0]
    # auto's accepted steps over the initial sweep equal its direct runs
    direct = 0
    x = rod.initial_state()
    g = integrate.Propagator(rod, "auto", 2e-5, rtol=1e-4)
    for n in range(1, N_SLICES + 1):
        r = g.run(serial.times[n - 1], serial.times[n], x)
        direct += r.n_steps
        x = r.state
    assert serial.timings.coarse_steps[0]["accepted"] == direct


# ---- tune: an adaptive F (rtol, or "auto") ---------------------------------------------------

def _tune_rod():
    return models.rod_swimmer(n_points=21, length=4.0, epsilon=1.0)


@pytest.mark.parametrize("scheme", ["rk23", "auto"])
def test_tune_runs_an_adaptive_fine_solver_with_its_rtol(scheme):
    from parastokes import tuning
    from parastokes.parareal.metrics import relative_change

    rod = _tune_rod()
    fine = integrate.Propagator(rod, scheme, 1e-6, rtol=1e-7)
    space = tuning.Space(schemes=("euler",), parameters=(), richardson=(0,),
                         step_fractions=(1.0,))
    res = tuning.tune(fine, t0=0.0, t1=2e-3, n_slices=2, cores=2, target=1e-3, space=space)
    assert res.report["problem"]["fine"] == {"scheme": scheme, "dt": 1e-6, "rtol": 1e-7,
                                             "atol": None}
    pilot = res.pilot
    x0, t1 = pilot.reference[0], pilot.times[1]
    adaptive = integrate.run(rod, x0, 0.0, t1, scheme, 1e-6, rtol=1e-7)
    assert np.array_equal(pilot.reference[1], adaptive.state)  # F ran with its rtol
    tighter = integrate.propagate(rod, x0, 0.0, t1, scheme, 1e-6, rtol=1e-8)
    assert pilot.fine_error == relative_change(adaptive.state, tighter, rod.positions)
    assert res.chosen is not None


def test_tune_schemes_auto_searches_auto_on_the_rtol_ladder(tmp_path):
    """``--schemes auto``: adaptive candidates only (docs/tuning.md), beside the plain Euler
    baseline; each measured with its steps per slice, auto's switches among them."""
    import json

    from test_tune import CONFIG

    from parastokes import cli

    source = tmp_path / "rod.toml"
    source.write_text(CONFIG.replace("nodes = [2, 3]", "nodes = [2]"))
    out = tmp_path / "TUNED.toml"
    assert cli.main(["tune", str(source), "--cores", "4", "--target", "1e-4", "--out", str(out),
                     "-q", "--schemes", "auto", "--coarse-rtols", "1e-3", "--parameters",
                     "--exhaustive", "--pilot-slices", "2", "--set", "time.t1=0.004"]) == 0
    report = json.loads(out.with_suffix(".json").read_text())
    assert report["baseline"]["scheme"] == "euler" and report["baseline"]["rtol"] is None
    (row,) = [c for c in report["candidates"] if c["scheme"] == "auto"]
    assert (row["scheme"], row["rtol"], row["richardson"]["m"]) == ("auto", 1e-3, 0)
    assert row["screen"]["steps"]["accepted"] > 0 and "switches" in row["adaptive_steps"]
    assert "--schemes auto --parameters --coarse-rtols 0.001 --pilot-slices 2" in out.read_text()


# ---- plan: adaptive runs (and auto) in the serial baseline -----------------------------------

#: test_plan's small rod over a shorter T (a quarter).
PLAN_CONFIG = PLAN_ROD.replace("t1 = 0.002", "t1 = 0.0005")


def test_plan_candidates_hold_every_adaptive_scheme_and_auto_on_the_rtol_ladder():
    from parastokes.planning import baseline

    target = 1e-6
    runs = baseline.candidates(1e-5, target, span=1.0, auto=baseline._auto_available(_rod()))
    ladder = {(r.scheme, r.rtol) for r in runs if r.rtol is not None}
    adaptive = [n for n, s in integrate.SCHEMES.items() if s.adaptive] + ["auto"]
    assert {"rk23", "rk45", "ros2", "ros34pw2"} <= set(adaptive)
    for name in adaptive:
        assert {(name, target), (name, target / 10), (name, target / 100)} <= ladder, name
    assert not any(r.rtol is not None for r in runs if not integrate.lookup(r.scheme).adaptive)
    # an explicit pair on a fixed step is refused by check (a PLAN.toml must pass it)
    assert not any(r.rtol is None for r in runs if r.scheme in ("rk23", "rk45"))


@pytest.mark.parametrize(("scheme", "rtol"), [("auto", 1e-7), ("ros34pw2", 1e-6)])
def test_an_adaptive_best_serial_run_is_written_and_passes_check(scheme, rtol, tmp_path):
    from parastokes import cli, config
    from parastokes.planning import routes
    from parastokes.planning.baseline import Run
    from parastokes.planning.command import plan_config
    from parastokes.tuning.report import toml_dumps

    source = tmp_path / "rod.toml"
    source.write_text(PLAN_CONFIG)
    cfg, _ = config.load(source)
    best = Run(scheme, 1e-6, rtol, f"{scheme} adaptive", "measured", 4e-7, 0.1, 0.2)
    fine = Run("rk2", 1e-6, None, "F", "reference", 0.0, 0.3, 0.6)
    data = plan_config(cfg, routes.serial_route(best.cost, best.label()), fine, best, None)
    assert data["fine"] == {"scheme": scheme, "dt": 1e-6, "rtol": rtol}
    assert data["run"] == {"mode": "serial"}
    out = tmp_path / "PLAN.toml"
    out.write_text(toml_dumps(data, "# plan"))
    assert cli.main(["check", str(out)]) == 0


def test_plan_runs_with_an_auto_fine_solver_and_measures_adaptive_rows(tmp_path):
    import json

    from parastokes import cli

    source = tmp_path / "rod.toml"
    source.write_text(PLAN_CONFIG.replace("dt = 1e-6", 'dt = 1e-6\nscheme = "auto"\nrtol = 1e-8'))
    out = tmp_path / "PLAN.toml"
    assert cli.main(["plan", str(source), "--cores", "2", "--target", "1e-5", "--out", str(out),
                     "--budget", "4"]) == 0
    plan = json.loads(out.with_suffix(".json").read_text())
    rows = plan["baseline"]["rows"]
    assert plan["fine"]["scheme"] == "auto" or any(r["rtol"] is not None for r in rows)
    assert {"scheme", "dt", "rtol", "error", "cpu_seconds"} <= set(plan["best_serial"])
    assert cli.main(["check", str(out)]) == 0


# ---- a config: [coarse] scheme = "auto" end to end, counts in summary.json and on screen ----

def test_a_config_with_an_auto_coarse_solver_reports_its_steps(tmp_path, capsys):
    import json

    from parastokes import cli

    source = tmp_path / "rod.toml"
    source.write_text(PLAN_CONFIG.replace("t1 = 0.0005", "t1 = 0.0003").replace(
        "dt_ratio = 10", 'dt_ratio = 20\nscheme = "auto"\nrtol = 1e-4').replace(
        "n_slices = 2", "n_slices = 3\nmax_iterations = 2\ntol = 0.0").replace(
        'formats = ["png"]', 'formats = ["png"]\nfigures = false'))
    assert cli.main(["run", str(source), "--out", str(tmp_path / "out")]) == 0
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    counts = summary["timings"]["coarse_steps"]
    assert len(counts) == summary["iterations"] + 1
    assert counts[0]["accepted"] > counts[1]["accepted"] > 0
    total = sum(c["accepted"] for c in counts)
    assert f"in all {total} accepted" in capsys.readouterr().out


def test_coarse_steps_line_sums_the_sweeps():
    from parastokes.cli.run import coarse_steps_line

    line = coarse_steps_line([{"accepted": 5, "rejected": 1, "switches": 0},
                              {"accepted": 3, "rejected": 0, "switches": 2}])
    assert line == ("adaptive coarse steps (accepted/rejected per sweep k = 0..1): 5/1, 3/0/2; "
                    "in all 8 accepted, 1 rejected, 2 switches")


def test_a_bound_copy_starts_counting_from_zero_and_take_resets():
    rod = _rod()
    g = parareal.extrapolated(rod, "ros2", 2e-5, rtol=1e-4)
    g(0.0, 1e-4, rod.initial_state())
    with parallel.make_executor("serial") as executor:
        bound = g.with_executor(executor)
        assert bound.take_step_counts() == {"accepted": 0, "rejected": 0, "switches": 0}
    direct = g.auxiliary[0][0].run(0.0, 1e-4, rod.initial_state())
    assert g.take_step_counts() == {"accepted": direct.n_steps, "rejected": direct.n_rejected,
                                    "switches": 0}
    assert g.take_step_counts() == {"accepted": 0, "rejected": 0, "switches": 0}


def test_an_adaptive_auxiliary_solve_stays_a_gpu_call():
    """The GPU executor runs a propagator's ``counted`` hosted (its products on the device),
    as it ran the propagator itself before the counts were carried back."""
    from parastokes.gpu import batch

    p = integrate.Propagator(_rod(), "ros2", 2e-5, rtol=1e-4)
    args = (0.0, 1e-4, _rod().initial_state())
    assert batch.gpu_call(p.counted, args, {}) and batch.hosted_call(p.counted, args, {})
    assert batch.gpu_call(p, args, {}) and not batch.gpu_call(p.run, args, {})
