"""The second fault campaign (issue 39) as regression tests, beside tests/test_output_claims.py (the
files of flow, movie, tune and plot): rigid bodies too large for memory, failed mobility solves,
--resume of a finished run without its resume files, slips of the wrong signature, flow output
settings checked by `check`, wall advice when the step is the cause, a pipe as configuration,
and the smaller ones. docs/validation.md, "Faults and bad input", lists them."""

from __future__ import annotations

import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from configs import SERIAL_SOLVERS
from test_faults import TINY, finished  # noqa: F401  (the fixture: a finished TINY run)
from test_flow import scene_run  # noqa: F401  (the fixture: a scene run of 5 frames)
from test_run_directory import _config, _run

from parastokes import cli, config
from parastokes import run as runner
from parastokes.config import checks
from parastokes.integrate import BlowUpError
from parastokes.mobility import SolveError
from parastokes.run import advice

ROOT = Path(__file__).resolve().parents[1]
ENV = {**os.environ, "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1"}


def _sphere(extra: str = "", *, wall: bool = True, points: int = 40, shape: str = "sphere",
            before: str = "") -> str:
    """A small rigid body (a sphere of 40 points; serial solvers, a few steps) with ``extra``
    keys in its model (``before``: lines before its tables)."""
    return (f'{before}[model]\nkind = "rigid"\nshape = "{shape}"\nn_points = {points}\nwall = '
            f'{str(wall).lower()}\nposition = [0.0, 0.0, 3.0]\n{extra}\n' + SERIAL_SOLVERS
            + '[run]\nmode = "serial"\n[output]\nfigures = false\n')


def _check(tmp_path: Path, text: str, *overrides: str) -> int:
    path = _config(tmp_path, text, "c.toml")
    sets = [item for key in overrides for item in ("--set", key)]
    return cli.main(["check", str(path), *sets])


# ---- 2: a rigid body too large is refused before it is built ---------------------------------
@pytest.mark.parametrize("text, key", [
    (_sphere(points=1000000000), "model.n_points: 1000000001 points"),
    (_sphere("rings = 100000000", shape="rod"), "model.rings, model.around: 800000003 points"),
    (_sphere().replace('kind = "rigid"\nshape = "sphere"\nn_points = 40',
                       'kind = "bacterium"\ntail_points = 1000000000'),
     "model.head_points, model.tail_points: 1000000201 points"),
    (_sphere(points=20000), "model.n_points: 20001 points"),  # its states fit, its dense
])                                                            # (3N)² mobility matrix does not
def test_a_rigid_body_too_large_for_memory_is_refused_before_it_is_built(
    tmp_path, capsys, monkeypatch, text, key
):
    from parastokes.kinds.rigid.kind import RigidBase

    def built(*args, **kwargs):
        raise AssertionError("the body was built before its size was checked")

    monkeypatch.setattr(RigidBase, "build", built)
    monkeypatch.setattr(checks, "physical_memory", lambda: 16.0 * 2**30)
    assert _check(tmp_path, text) == cli.ExitCode.CONFIG  # (was: 22.5 GB, then killed)
    err = capsys.readouterr().err
    assert key in err and "and this machine has 16 GiB" in err
    assert "the dense mobility matrices of its rigid surfaces (each surface's (3N)²" in err


def test_a_scene_with_a_rigid_body_too_large_names_the_bodies(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(checks, "physical_memory", lambda: 16.0 * 2**30)
    scene = ('[scene]\nwall = true\n[[bodies]]\nkind = "rigid"\nn_points = 20000\nposition = '
             '[0, 0, 3]\n[[bodies]]\nkind = "rigid"\nposition = [5, 0, 3]\nn_points = 40\n')
    assert _check(tmp_path, scene + SERIAL_SOLVERS) == cli.ExitCode.CONFIG
    assert "bodies: 20042 points: the run's states and the dense mobility matrices" in \
        capsys.readouterr().err


# ---- 4: a failed mobility solve is an error, never zero motion --------------------------------
def test_a_solve_that_overflows_is_a_solve_error_not_zero_motion():
    import dataclasses

    cfg, _ = config.loads(_sphere())
    body = dataclasses.replace(cfg.model.build(1), force=(0.0, 0.0, -1e200))
    with pytest.raises(SolveError, match="floating point holds"):  # (was U = 0, residual NaN)
        body.solve(0.0, body.initial_state())


def test_check_refuses_the_sedimenting_sphere_with_a_force_beyond_floating_point(capsys):
    path = ROOT / "experiments" / "quick" / "sphere_sediments_to_wall.toml"
    assert cli.main(["check", str(path), "--set", "model.force=[0, 0, -1e200]"]) == 2
    err = capsys.readouterr().err
    assert "model: rigid: at the initial state, GMRES gave a non-finite result" in err
    assert "Warning" not in err


def test_a_solve_that_fails_inside_a_step_is_a_blow_up_with_the_last_good_state():
    import dataclasses

    from parastokes import integrate
    from parastokes.kinds.rigid.system import RigidBody

    cfg, _ = config.loads(_sphere("force = [0.0, 0.0, -1.0]"))
    body = cfg.model.build(1)

    @dataclasses.dataclass(frozen=True)
    class Failing(RigidBody):  # its solve fails from t = 0.05 on (GMRES that stalls, say)
        def solve(self, t, state):
            if t >= 0.05:
                raise SolveError("GMRES did not reach the relative residual 1e-10")
            return super().solve(t, state)

    failing = Failing(**{f.name: getattr(body, f.name) for f in dataclasses.fields(body)
                         if f.init})
    with pytest.raises(BlowUpError) as caught:  # (was: the solve's exception, exit 1)
        integrate.run(failing, failing.initial_state(), 0.0, 0.1, "rk2", 0.01)
    error = caught.value
    assert error.t == pytest.approx(0.05) and error.step == 4
    assert error.reason == "GMRES did not reach the relative residual 1e-10"
    assert error.last_state[0, 2] < 3.0 and np.isfinite(error.last_state).all()
    assert cli.exit_code(error) == cli.ExitCode.BLOWUP


def test_a_slip_that_turns_nan_later_is_a_blow_up_naming_it(tmp_path, capsys, monkeypatch):
    module = tmp_path / "late_slip.py"
    module.write_text("import numpy as np\ndef slip(t, points):\n"
                      "    return np.full_like(points, np.nan if t > 0.04 else 0.0)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    path = _config(tmp_path, _sphere('slip = "late_slip:slip"'))
    assert _run(path, "--out", tmp_path / "out") == cli.ExitCode.BLOWUP
    err = capsys.readouterr().err
    assert "slip: 'late_slip:slip' returned non-finite velocities at t = 0.05" in err
    assert "reduce fine.dt" not in err and "a smaller step does not help" in err


# ---- 6: --resume of a finished run without its resume files -----------------------------------
def test_resume_of_a_finished_run_without_its_resume_files_keeps_to_its_configuration(
    finished, tmp_path, capsys  # noqa: F811
):
    path, source = finished
    out = Path(shutil.copytree(source, tmp_path / "out"))
    for name in (runner.CHECKPOINT, runner.REFERENCE, runner.HISTORY):
        (out / name).unlink(missing_ok=True)
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    assert _run(path, "--out", out, "--resume", "--set", "model.n_points=31") == 2
    err = capsys.readouterr().err  # (was exit 0, the results of another problem)
    assert f"{out / 'summary.json'} (the run to resume)" in err
    assert "model.n_points: 31 now, 21 in the run to resume" in err
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == before
    assert _run(path, "--out", out, "--resume") == 0  # the same run: written again


# ---- 9: a slip of the wrong signature ----------------------------------------------------------
@pytest.mark.parametrize("target, found", [("one_arg:slip", "(points)"), ("os:getcwd", "()")])
def test_a_slip_of_the_wrong_signature_is_one_line_in_check_and_run(tmp_path, capsys,
                                                                   monkeypatch, target, found):
    (tmp_path / "one_arg.py").write_text("def slip(points):\n    return 0 * points\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    path = _config(tmp_path, _sphere(f'slip = "{target}"'))
    assert cli.main(["check", str(path)]) == 2
    assert _run(path, "--out", tmp_path / "out") == 2  # (was exit 1 with a traceback)
    err = capsys.readouterr().err
    assert err.count(f"slip: {target!r} takes {found}, but a slip is called as "
                     "function(t, points)") == 2
    assert "Traceback" not in err and not (tmp_path / "out").exists()


# ---- 10: the flow output's settings are checked with the rest -----------------------------------
@pytest.mark.parametrize("setting, fix", [
    ('output.flow_plane="z=-5"', "'z=-5' is below the wall z = 0"),
    ('output.flow_plane="z=abc"', "give AXIS=VALUE with a number"),
    ('output.flow_plane="x=1e300"', "with a number of at most 1e+30"),
    ("output.flow_resolution=100000", "less than or equal to 4096"),
])
def test_check_refuses_a_flow_output_the_run_could_not_write(tmp_path, capsys, setting, fix):
    assert _check(tmp_path, _sphere(), "output.flow_every=1", setting) == 2
    err = capsys.readouterr().err  # (was ok; the run failed at its end)
    assert setting.split("=")[0] in err and fix in err


# ---- 11: the wall advice when the step is the cause ----------------------------------------------
def test_a_step_that_drives_the_body_into_the_wall_is_told_to_shrink(tmp_path, capsys):
    out = tmp_path / "out"
    code = cli.main(["demo", "--out", str(out), "-q", "--set", "model.height=0.9", "--set",
                     "fine.dt=2e-5", "--set", 'run.mode="serial"'])
    assert code == cli.ExitCode.BLOWUP
    err = capsys.readouterr().err
    assert "a point reached the wall z = 0" in err and "reduce fine.dt (now 2e-05)" in err
    assert "does not help" not in err and "keeps it off" not in err  # (said both before)
    # a step 20 times smaller runs past that time
    assert cli.main(["demo", "--out", str(out), "-q", "--overwrite", "--set", "model.height=0.9",
                     "--set", "fine.dt=1e-6", "--set", 'run.mode="serial"', "--set",
                     "time.t1=4e-4", "--set", "parareal.n_slices=2"]) == 0


def test_the_advice_names_the_keys_of_the_kind_and_of_the_coarse_family(tmp_path):
    rigid, _ = config.loads(_sphere())
    assert advice.height_keys(rigid) == "model.position (its z)"
    hodmd, _ = config.load(ROOT / "experiments" / "hodmd" / "authors_rod.toml")
    text = advice.fix(hodmd, "coarse solve of slice 2 in iteration 1")
    assert "coarse.g1 and coarse.g2" in text and "coarse.dt_ratio or" not in text
    cfg, resolved = config.loads(TINY)
    setup = config.preflight(cfg, resolved)
    x = setup.system.initial_state()
    nan = BlowUpError(0.01, 3, math.nan, x, "non-finite state; LateNaN.rates(t, state) "
                                            "returned NaN at the last good state (t = 0.01)")
    text = advice.advice(setup, "serial", nan, "the serial run", None)
    assert "does not help" in text and "reduce" not in text  # (was "reduce fine.dt")


# ---- 12: a pipe as configuration -----------------------------------------------------------------
def test_a_pipe_as_configuration_or_base_is_refused_at_once(tmp_path):
    pipe = tmp_path / "p"
    os.mkfifo(pipe)
    based = _config(tmp_path, f'base = "{pipe}"\n', "based.toml")
    done = subprocess.run([sys.executable, "-m", "parastokes", "check", str(pipe), str(based)],
                          env=ENV, capture_output=True, text=True, timeout=60)  # (was: forever)
    assert done.returncode == 2
    assert done.stderr.count("a named pipe (FIFO), not a regular file") == 2


# ---- the smaller ones ----------------------------------------------------------------------------
@pytest.mark.parametrize("text, expected, blamed", [
    (_sphere("epsilon = 1e300"), "epsilon: must lie in [1e-18, 1e+18], got ", None),
    (_sphere("radius = 1e300"), "its sizes (radius, length, ...) are beyond what floating point",
     "epsilon"),
    (_sphere(before='base = "\\u0000"\n'), "base: must be a file name, got '\\x00'", None),
])
def test_bad_values_get_one_short_line_naming_the_right_key(tmp_path, capsys, text, expected,
                                                           blamed):
    assert _check(tmp_path, text) == 2
    err = capsys.readouterr().err
    assert expected in err and len(err) < 300 and len(err.strip().splitlines()) == 2
    assert blamed is None or blamed not in err


def test_a_surface_of_one_point_and_a_scene_body_below_the_wall_are_named(tmp_path, capsys,
                                                                         monkeypatch):
    (tmp_path / "one_point.py").write_text("import numpy as np\ndef cloud():\n"
                                           "    return np.zeros((1, 3))\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert _check(tmp_path, _sphere('points = "one_point:cloud"', shape="points")) == 2
    err = capsys.readouterr().err
    assert "points: the surface has 1 point; a rigid body needs at least 2" in err
    assert "epsilon" not in err
    scene = ('[scene]\nwall = true\n[[bodies]]\nname = "high"\nkind = "rigid"\nn_points = 40\n'
             'position = [0, 0, 3]\n[[bodies]]\nname = "low"\nkind = "rigid"\nn_points = 40\n'
             'position = [5, 0, -2]\n')
    assert _check(tmp_path, scene + SERIAL_SOLVERS) == 2
    assert "bodies[1] ('low'): position: the body reaches z = -2.97" in capsys.readouterr().err


def test_an_empty_hodmd_window_is_a_configuration_error(capsys):
    path = ROOT / "experiments" / "hodmd" / "authors_rod.toml"
    assert cli.main(["check", str(path), "--set", "coarse.window=[]"]) == 2
    err = capsys.readouterr().err
    assert "coarse.window: List should have at least 1 item" in err and "min()" not in err


def test_a_closed_standard_output_ends_the_command_quietly(tmp_path):
    paths = [str(_config(tmp_path, TINY, f"c{i}.toml")) for i in range(4)]
    # (from tmp_path: in the checkout's root, an installed copy adds a note on stderr, cli.launch)
    process = subprocess.Popen([sys.executable, "-m", "parastokes", "check", *paths], env=ENV,
                               cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True)
    process.stdout.close()  # (`parastokes check ... | head -0`)
    _, err = process.communicate(timeout=120)
    assert process.returncode == 141 and err == ""  # (was exit 1 or 2, "Errno 32")


def test_out_of_memory_in_flow_names_what_to_make_smaller(capsys):
    error = MemoryError()
    assert cli.report(error, cli.Console(quiet=False), "flow") == cli.ExitCode.CONFIG
    err = capsys.readouterr().err
    assert "use a smaller --resolution or --dpi" in err and "slices or workers" not in err


# ---- from the first trial of the new bodies ------------------------------------------------------
def test_the_scene_figure_draws_a_rigid_surface_beside_a_rod():
    from matplotlib.figure import Figure

    from parastokes.output import plots

    times = np.linspace(0.0, 1.0, 4)
    rod = {"positions": np.tile(np.linspace([0, 0, 5], [4, 0, 5], 9), (4, 1, 1)),
           "connectivity": np.array([[k, k + 1] for k in range(8)])}
    sphere = {"positions": np.tile(np.random.default_rng(3).normal(size=(30, 3)) + [6, 0, 3],
                                   (4, 1, 1)), "connectivity": np.arange(30)[:, None]}
    fig = Figure()
    plots.scene_snapshots(fig, {"rod": rod, "sphere_surface": sphere}, times, "serial")
    for ax in fig.axes:  # (was: zero-length segments, so no sphere at all)
        (dots,) = [line for line in ax.get_lines() if line.get_label() == "sphere_surface"]
        assert len(dots.get_xdata()) == 30


def test_movie_panels_are_at_true_scale_and_the_flow_picture_fills_its_canvas(
    scene_run, tmp_path  # noqa: F811
):
    from matplotlib.figure import Figure
    from PIL import Image

    from parastokes import flow
    from parastokes.flow.fields import frames_velocity, run_grid, save_png
    from parastokes.flow.movie import _bodies_limits, draw_bodies_frame, render_frame

    run = flow.load_run(scene_run[0])
    fig = Figure(figsize=(8, 6), dpi=100, layout="constrained")
    draw_bodies_frame(fig, run, 2, _bodies_limits(run))
    render_frame(fig)
    for ax in fig.axes:  # a micrometre as long across as up (a 45° body looked 18°)
        (x0, y0), (x1, y1) = ax.transData.transform([(0.0, 0.0), (1.0, 1.0)])
        assert x1 - x0 == pytest.approx(y1 - y0, rel=1e-6)
    grid = run_grid(run, [4], None, None, (40,))
    path = save_png(tmp_path / "f.png", grid, frames_velocity(run, [4], [1.0], grid.points()),
                    run, 4, "t")
    drawn = np.asarray(Image.open(path).convert("L")) < 245
    assert drawn.mean() > 0.6  # (was 0.27: a 7 x 4 in canvas around a tall plane)
    columns = np.flatnonzero(drawn.any(axis=0))
    assert (columns[-1] - columns[0]) / drawn.shape[1] > 0.9


def test_wall_contact_is_checked_on_the_shape_not_only_its_points(tmp_path, capsys):
    # (a sphere of radius 1 at z = 0.997: all 40 points above the wall; it ran)
    assert _check(tmp_path, _sphere().replace("[0.0, 0.0, 3.0]", "[0.0, 0.0, 0.997]")) == 2
    assert "the body's shape reaches below the wall z = 0 between its surface points" in \
        capsys.readouterr().err
    assert _check(tmp_path, _sphere().replace("[0.0, 0.0, 3.0]", "[0.0, 0.0, 1.05]")) == 0


def test_a_base_of_another_kind_gives_no_keys_of_its_kind(tmp_path):
    quick = ROOT / "experiments" / "hodmd" / "quick_rod.toml"  # base: an extrapolated G
    cfg, resolved = config.load(quick)  # (was: the base's lagrange, dt_ratio "unknown keys")
    assert cfg.coarse.kind == "hodmd" and resolved.n_auxiliary == 1
    assert cfg.coarse.g2.grid_factor == 2 and cfg.model.n_points == 61
    based = _config(tmp_path, f'base = "{quick}"\n[model]\nkind = "chain"\n'
                              "[coarse.g2]\ngrid_factor = 1\n", "chain.toml")
    cfg, _ = config.load(based)  # another body: none of the rod's keys (n_points, length)
    assert cfg.model.kind == "chain" and cfg.coarse.kind == "hodmd"


def test_a_background_flow_that_went_nan_is_a_solve_failure_not_a_configuration_error():
    from parastokes import rigid
    from parastokes.core.contracts import StepFailure
    from parastokes.mobility import solve_mobility

    surface = rigid.sphere(1.0, 40).place((0.0, 0.0, 3.0))
    background = np.zeros((40, 3))
    background[7, 1] = np.nan  # (another body of the scene blew up)
    with pytest.raises(StepFailure, match=r"background: contains non-finite values \(1 of 120\); "
                                          r"the other bodies' flow is not finite"):
        solve_mobility(surface, mu=1.0, background=background)
