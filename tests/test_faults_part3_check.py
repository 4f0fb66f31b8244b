"""The third fault campaign (issue 50, items 3-6 and the low items beside them): `check` runs what
`run` will run first. A user's Jacobian hooks are called and checked, the GPU executor is refused
where it cannot start, a scene's first mobility solve and a rod's first fine step are made, and a
suspension that cannot be placed or cannot fit in memory is refused before any body is built.
docs/validation.md, "Faults and bad input: `check` runs what `run` runs", lists them."""

from __future__ import annotations

import importlib
import math
import os
import pickle
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import test_body_faults as body_faults
import user_hooks as uh
from configs import SERIAL_SOLVERS, small_rod

from parastokes import cli, config, integrate
from parastokes.bodies import contract
from parastokes.config import checks, placement, preflight, suspension
from parastokes.config.schema import Suspension
from parastokes.kinds.rigid.kind import RigidModel
from parastokes.run import advice
from parastokes.scene import Scene
from parastokes.stiff import jacobian

ROOT = Path(__file__).resolve().parents[1]


def _rod(model: str = "") -> str:
    """tests/configs.py's small rod on the serial executor."""
    return small_rod(model=model, rest='[execution]\nexecutor = "serial"\n')


def _write(folder: Path, text: str, name: str = "c.toml") -> Path:
    path = folder / name
    path.write_text(text)
    return path


def _errors(capsys) -> list[str]:
    return [line for line in capsys.readouterr().err.splitlines() if line.strip()]


# ---- item 3: a user's Jacobian hooks -------------------------------------------------------------
#: test_body_faults.py's small run with an implicit scheme, which calls the hooks (ros2)
RUN = body_faults.RUN.replace("[fine]\n", '[fine]\nscheme = "ros2"\n')
HOOKED = '[model]\nkind = "user_hooks:{name}"\n' + RUN

#: variant -> what the one line says (after "Variant.")
HOOK_FAULTS = {
    "ShapeHook": "load_jacobian(t, state) returned shape (5, 5); expected (24, 24): a row per "
                 "load and a column per rate",
    "NaNHook": "load_jacobian(t, state) returned NaN at the initial state; expected finite",
    "InfHook": "load_jacobian(t, state) returned infinite entries at the initial state; expected "
               "finite",
    "TextHook": "load_jacobian(t, state) returned str that is no matrix",
    "NonSquareHook": "stiff_jacobian(t, state) returned shape (24, 23); expected (24, 24): one "
                     "row and column per rate",
    "RaisingHook": "load_jacobian(t, state) raised RuntimeError at t = 0: the springs' table is "
                   "missing",
    "NoTimeHook": "load_jacobian(state) cannot be called as load_jacobian(t, state) (too many "
                  "positional arguments); expected def load_jacobian(self, t, state)",
}


def test_a_correct_hook_passes_the_probe_and_is_the_one_the_scheme_uses():
    body = uh.Hooked()
    x = contract.probe(body, 0.0, 0.01)
    jacobian.probe_hooks(body, 0.0, x)
    k = jacobian.load_jacobian(body, 0.0, x).toarray()
    assert np.array_equal(k, -body.stiffness * np.eye(3 * body.n_points))


@pytest.mark.parametrize("name", sorted(HOOK_FAULTS))
def test_each_broken_hook_is_one_line_naming_it(name):
    """On main the probe never called the hooks: each passed `check`."""
    body = getattr(uh, name)()
    with pytest.raises(contract.BodyError) as caught:
        x = contract.probe(body, 0.0, 0.01)
        jacobian.probe_hooks(body, 0.0, x)
    text = str(caught.value)
    assert text.startswith(f"{name}.{HOOK_FAULTS[name]}") and "\n" not in text, text


@pytest.mark.parametrize("name", ["ShapeHook", "NaNHook", "RaisingHook", "NoTimeHook"])
def test_check_calls_the_hooks_and_refuses_a_broken_one(tmp_path, capsys, name):
    """On main: `check` ok; the run failed after its directory was claimed (a raising hook:
    exit 4 on the process pool, "rerun with --resume")."""
    path = _write(tmp_path, HOOKED.format(name=name, executor="serial", workers=""))
    assert cli.main(["check", str(path)]) == 2
    (line,) = _errors(capsys)
    assert line.startswith(f"{path}: {name}.{HOOK_FAULTS[name]}")


def test_a_hook_raising_later_is_a_body_error_that_crosses_processes_as_exit_2():
    """What a worker's fine solve meets (the end-to-end run on the process pool below is
    marked slow): a BodyError naming the hook and the time, whole after pickling, exit 2 inside
    a failed task (on main: the KeyError itself, a failed task: exit 4)."""
    from parastokes.parallel import TaskError

    body = uh.LateRaisingHook()
    with pytest.raises(contract.BodyError) as caught:
        integrate.run(body, body.initial_state(), 0.0, 0.1, "ros2", 0.01)
    assert str(caught.value) == ("LateRaisingHook.load_jacobian(t, state) raised KeyError at "
                                 "t = 0.05: 'frame'")
    again = pickle.loads(pickle.dumps(caught.value))
    assert cli.exit_code(TaskError("fine solve of slice 2 in iteration 1", again)) == 2


@pytest.mark.slow
def test_a_hook_raising_inside_a_worker_is_exit_2_naming_it_not_a_task_to_resume(tmp_path,
                                                                                 capsys):
    """LateRaisingHook is right at the initial state and raises from t = 0.03 on, inside the
    fine solve of slice 2 on the process pool. On main: exit 4, "fine solve of slice 2 in
    iteration 1 failed: KeyError: 'frame'" and "rerun with --resume"."""
    path = _write(tmp_path, HOOKED.format(name="LateRaisingHook", executor="processes",
                                          workers='workers = 2\n[run]\nmode = "parareal"\n'
                                                  "[output]\nfigures = false"))
    assert cli.main(["run", str(path), "--out", str(tmp_path / "out"), "-q"]) == 2
    err = _errors(capsys)
    assert err[0] == ("error: LateRaisingHook.load_jacobian(t, state) raised KeyError at "
                      "t = 0.05: 'frame'")
    assert not any("--resume" in line for line in err)


def test_a_late_nan_from_a_hook_is_a_blow_up_naming_it():
    """Finite at the probe, NaN from t = 0.03: a blow-up where it is called (exit 3, the last
    good state kept), not a broken contract (on main: exit 2)."""
    body = uh.LateNaNHook()
    x0 = contract.probe(body, 0.0, 0.01)
    jacobian.probe_hooks(body, 0.0, x0)
    with pytest.raises(integrate.BlowUpError,
                       match=r"LateNaNHook\.load_jacobian\(t, state\) returned NaN at t = 0\.05"
                       ) as caught:  # (the Jacobian is rebuilt every 5 steps: from 0.05)
        integrate.run(body, x0, 0.0, 0.1, "ros2", 0.01)
    assert cli.exit_code(caught.value) == cli.ExitCode.BLOWUP and caught.value.step == 5
    assert np.isfinite(caught.value.last_state).all()


SCENE = """[scene]
viscosity = 1.0
shear_rate = 1.0
[[bodies]]
name = "good"
kind = "user_hooks:Hooked"
[[bodies]]
name = "bad"
kind = "user_hooks:ShapeHook"
height = 5.0
""" + RUN.format(executor="serial", workers="")


def test_a_scenes_hook_error_names_the_body(tmp_path, capsys):
    """On main, the class only (two bodies of one class could not be told apart)."""
    path = _write(tmp_path, SCENE)
    assert cli.main(["check", str(path)]) == 2
    (line,) = _errors(capsys)
    assert line.startswith(f"{path}: bodies[1] ('bad'): ShapeHook.load_jacobian(t, state) "
                           "returned shape (5, 5)")
    scene = Scene((uh.Hooked(), uh.LateRaisingHook(height=5.0)), viscosity=1.0, shear_rate=1.0,
                  names=("good", "late"))
    with pytest.raises(contract.BodyError, match=r"^bodies\[1\] \('late'\): LateRaisingHook\."
                                                 r"load_jacobian\(t, state\) raised KeyError"):
        scene.stiff_jacobian(0.05, scene.initial_state())
    # a NaN only later: a blow-up (exit 3) that names the body too, not only its class
    scene = Scene((uh.Hooked(), uh.LateNaNHook(height=5.0)), viscosity=1.0, shear_rate=1.0,
                  names=("good", "late"))
    with pytest.raises(jacobian.NonFiniteJacobian,
                       match=r"^bodies\[1\] \('late'\): LateNaNHook\.load_jacobian\(t, state\) "
                             r"returned NaN at t = 0\.05") as caught:
        scene.stiff_jacobian(0.05, scene.initial_state())
    assert caught.value.t == 0.05
    with pytest.raises(integrate.BlowUpError, match=r"bodies\[1\] \('late'\): LateNaNHook"
                       ) as blown:  # and so in a run: a blow-up there
        integrate.run(scene, scene.initial_state(), 0.0, 0.1, "ros2", 0.01)
    assert cli.exit_code(blown.value) == cli.ExitCode.BLOWUP


# ---- item 4: the GPU executor without a device ---------------------------------------------------
def test_the_gpu_executor_is_refused_where_it_cannot_start(monkeypatch):
    from parastokes.gpu import device

    text = small_rod(rest='[execution]\nexecutor = "gpu"\n')
    monkeypatch.setattr(device, "missing", lambda: "no CUDA GPU here")
    with pytest.raises(config.ConfigError, match=r'execution\.executor: "gpu": no CUDA GPU here; '
                                                 r'or use executor = "processes" here'):
        config.loads(text)
    config.loads(text, overrides=['run.mode="serial"'])  # no executor is started
    monkeypatch.setattr(device, "missing", lambda: None)  # a GPU, or the simulator (the tests')
    config.loads(text)


@pytest.mark.skipif(shutil.which("nvidia-smi") is not None, reason="this machine has a GPU")
def test_without_cuda_check_and_run_say_so_in_one_line(tmp_path):
    """In a fresh process without the simulator (the GPU tests choose it in this one). On main:
    `check` ok, `run` exit 1 with a RuntimeError traceback from the executor's start."""
    path = _write(tmp_path, small_rod(rest='[execution]\nexecutor = "gpu"\n'))
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_ENABLE_CUDASIM"}
    env["PYTHONPATH"] = str(ROOT)
    # (a run checks its configuration as `check` does; from tmp_path: in the checkout's root, an
    # installed copy adds a note on stderr, cli.launch)
    done = subprocess.run([sys.executable, "-m", "parastokes", "run", str(path), "--out",
                           str(tmp_path / "o")], cwd=tmp_path, env=env, capture_output=True,
                          text=True, timeout=300)
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr
    assert lines[-1].startswith('  execution.executor: "gpu": no CUDA GPU is available')
    assert len(lines) == 2  # "error: invalid configuration in PATH:" and the one issue
    assert not (tmp_path / "o").exists()


# ---- item 5: a scene whose first mobility solve fails --------------------------------------------
TWO_SPHERES = """[scene]
viscosity = 1.0
{scene}
[[bodies]]
name = "light"
kind = "rigid"
n_points = 40
position = [0.0, 0.0, 0.0]
[[bodies]]
name = "heavy"
kind = "rigid"
n_points = 40
position = [5.0, 0.0, 0.0]
force = [0.0, 0.0, {force}]
""" + SERIAL_SOLVERS


@pytest.mark.parametrize("scene, force, named", ids=["force", "repulsion"], argvalues=[
    ("", "-1e200", "body 'heavy' has a load (force or torque) of 1e+200"),
    ("repulsion = { range = 1e300, force = 1e300 }", "-1.0",
     "has a load (force or torque) of 1e+300, mostly from [scene] repulsion (range 1e+300, "
     "force 1e+300)"),
])
def test_a_scene_whose_first_solve_fails_is_refused_by_check_and_run(tmp_path, capsys, scene,
                                                                     force, named):
    """On main: `check` ok; `run` a SolveError traceback from the warm-up (exit 1)."""
    path = _write(tmp_path, TWO_SPHERES.format(scene=scene, force=force))
    assert cli.main(["check", str(path)]) == 2
    err = _errors(capsys)
    assert err[1].startswith("  bodies: the scene's first mobility solve (at the initial state) "
                             "failed: ") and err[1].endswith(named) and len(err) == 2
    out = tmp_path / "out"
    assert cli.main(["run", str(path), "--out", str(out), "-q"]) == 2
    assert _errors(capsys)[1].endswith(named) and not out.exists()


# ---- item 6: a suspension that cannot be placed or cannot fit ------------------------------------
SPHERE = RigidModel.model_validate({"kind": "rigid", "shape": "sphere", "radius": 1.0,
                                    "n_points": 42})


def test_the_packing_of_a_count_in_a_sphere_and_a_box():
    """The exclusion spheres (diameter d) of centres kept r inside the region fill the region
    grown by d/2 - r: by hand, 100 of d = 2.5 in a ball of 12 + 0.25, and in a box."""
    ball = 100 * (math.pi / 6 * 2.5**3) / (4 / 3 * math.pi * 12.25**3)
    assert placement.packing(100, "sphere", None, 12.0, 1.0, 2.5) == pytest.approx(ball, 1e-14)
    box = 7 * (math.pi / 6 * 3.0**3) / (11.0 * 21.0 * 31.0)
    assert placement.packing(7, "box", [10.0, 20.0, 30.0], None, 1.0, 3.0) == pytest.approx(
        box, 1e-14)


def _random_spec(count: int) -> Suspension:
    return Suspension.model_validate({"placement": "random", "region": "sphere", "radius": 12.0,
                                      "center": [0.0, 0.0, 0.0], "count": count,
                                      "body": {"kind": "rigid"}})


def test_a_count_just_over_random_close_packing_is_refused_before_any_try(monkeypatch):
    foot = suspension.Footprint(SPHERE, "position")
    d = 2 * foot.radius + foot.default_gap()
    limit = math.floor(0.64 * 4 / 3 * math.pi * (12.0 + d / 2 - foot.radius) ** 3
                       / (math.pi / 6 * d**3))

    class Tried(Exception):
        pass

    def tried(count, *args):
        raise Tried(count)

    monkeypatch.setattr(placement, "random_centers", tried)
    with pytest.raises(Tried):  # just under: placed (here: tried)
        suspension.expand(_random_spec(limit), SPHERE, "s", False)
    with pytest.raises(placement.PlacementError, match=rf"^{limit + 1} bodies ask a volume "
                       r"fraction .* more than random close packing \(0\.64"):
        suspension.expand(_random_spec(limit + 1), SPHERE, "s", False)


def test_the_quick_clouds_ten_thousand_spheres_are_refused_at_once(capsys, monkeypatch):
    """On main: 85 s of tries before "random placement gave up"."""
    monkeypatch.setattr(placement, "random_centers", None)  # never reached
    path = ROOT / "experiments" / "quick" / "cloud_sediments.toml"
    assert cli.main(["check", str(path), "--set", "suspensions.0.count=10000"]) == 2
    assert _errors(capsys)[1] == (
        "  suspensions[0].count: 10000 bodies ask a volume fraction 5.79 of the sphere, and with "
        "the gap around each they would fill 10.9 of it, more than random close packing (0.64; "
        "the random placement reaches about 0.3): lower count, enlarge the region, lower gap, or "
        'use placement = "lattice"')


def test_the_memory_of_copies_from_their_count():
    """1,000 spheres of 43 rows with dense matrices of 254,016 bytes: their sections (3.6 kB),
    matrices, and 11 states of 3 doubles per row, by hand."""
    assert suspension.planned_bytes(1000, 43, 254016.0) == 1000 * (3600 + 254016 + 11 * 24 * 43)
    assert suspension.planned_bytes(1000, 43, 254016.0) == 268_968_000


def _lattice_spec(counts: list[int]) -> Suspension:
    return Suspension.model_validate({"placement": "lattice", "counts": counts, "spacing": 3.0,
                                      "center": [0.0, 0.0, 0.0], "body": {"kind": "rigid"}})


def test_a_lattice_that_cannot_fit_is_refused_before_its_centres_or_copies(monkeypatch):
    """On main: [100, 100, 100] built a million copies (4 GB, 28 s) before the memory check."""
    monkeypatch.setattr(placement, "lattice", None)  # never reached
    monkeypatch.setattr(checks, "physical_memory", lambda: 268_968_000.0 - 1.0)
    with pytest.raises(placement.PlacementError, match=r"^1000 bodies of 43 rows and dense "
                       r"mobility matrices of 0\.242 MiB each need more than 0\.25 GiB") as caught:
        suspension.expand(_lattice_spec([10, 10, 10]), SPHERE, "s", False)
    assert caught.value.key == "counts"
    monkeypatch.undo()
    monkeypatch.setattr(checks, "physical_memory", lambda: 268_968_000.0)  # just fits
    assert len(suspension.expand(_lattice_spec([10, 10, 10]), SPHERE, "s", False)) == 1000


def test_a_million_lattice_copies_are_refused_by_check(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(placement, "lattice", None)  # never reached
    monkeypatch.setattr(checks, "physical_memory", lambda: 16.0 * 2**30)
    text = (ROOT / "experiments" / "cloud_sediments.toml").read_text().replace(
        'placement = "random"\nregion = "sphere"\nradius = 12.0\ncenter = [0.0, 0.0, 0.0]\n'
        "count = 100\nseed = 1", 'placement = "lattice"\ncounts = [100, 100, 100]\nspacing = 3.0'
        "\ncenter = [0.0, 0.0, 0.0]")
    assert cli.main(["check", str(_write(tmp_path, text))]) == 2
    assert _errors(capsys)[1].startswith(
        "  suspensions[0].counts: 1000000 bodies of 43 rows and dense mobility matrices of "
        "0.242 MiB each need more than 250 GiB, and this machine has 16 GiB")


# ---- the low items ------------------------------------------------------------------------------
def test_a_singular_stage_matrix_is_not_advised_ros2_under_ros2():
    reason = "linear solve failed at t=0.1: I - h*gamma*A is singular (...); use a smaller step"
    cfg, _ = config.loads(_rod(), overrides=['fine.scheme="ros2"'])
    text = advice.fix(cfg, "serial", reason)
    assert text.startswith("reduce fine.dt (I - hγA of ros2 is singular") and "use the" not in text
    cfg, _ = config.loads(_rod(), overrides=['fine.scheme="ros2-krylov"'])
    assert "use the scheme ros2 (a direct solve" in advice.fix(cfg, "serial", reason)


SPHERE_RUN = ('[model]\nkind = "rigid"\nshape = "sphere"\nn_points = 40\nposition = [0, 0, 3]\n'
              + SERIAL_SOLVERS)


@pytest.mark.parametrize("text, scheme, noted", ids=["rigid-ros2", "rigid-rk2", "rod-ros2",
                                                     "rod-rk2"], argvalues=[
    (SPHERE_RUN, "ros2", True), (SPHERE_RUN, "rk2", False), (_rod(), "ros2", False),
    (_rod(), "rk2", False),
])
def test_an_implicit_scheme_without_a_stiff_part_gets_a_note(text, scheme, noted):
    cfg, resolved = config.loads(text, overrides=[f'fine.scheme="{scheme}"'])
    setup = preflight(cfg, resolved)
    note = ("fine.scheme = 'ros2': a linearly implicit scheme, but this body has no stiff part "
            "(no stiff_jacobian, and no loads on the fluid: a rigid or prescribed-motion body), "
            "so it runs with A = 0, as an explicit scheme")
    assert any(w.startswith(note) for w in setup.resolved.warnings) is noted


def test_check_notes_the_implicit_scheme_on_a_rigid_body(tmp_path, capsys):
    path = _write(tmp_path, SPHERE_RUN)
    assert cli.main(["check", str(path), "--set", 'fine.scheme="ros2"']) == 0
    assert "note: fine.scheme = 'ros2': a linearly implicit scheme, but this body has no stiff " \
        "part" in capsys.readouterr().out


def test_an_adaptive_run_has_no_step_count_from_its_first_step(capsys, tmp_path):
    """On main: "1.5e+286 fine steps ... about 1.5e286 years", refused, for fine.dt = 1e-300
    with fine.rtol (the first step tried, not the step)."""
    sets = ['fine.scheme="ros2"', "fine.dt=1e-300"]
    with pytest.raises(config.ConfigError, match=r"fine\.dt: .* fine steps over \[t0, t1\]"):
        config.loads(_rod(), overrides=sets)
    _, resolved = config.loads(_rod(), overrides=[*sets, "fine.rtol=1e-4"])
    assert not any("fine steps" in w or "years" in w for w in resolved.warnings)
    path = _write(tmp_path, _rod())
    cli.main(["check", str(path), "--set", 'fine.scheme="ros2"', "--set", "fine.rtol=1e-4"])
    assert "4 slices of adaptive fine steps (their number set by fine.rtol = 0.0001)" in \
        capsys.readouterr().out


def test_a_parameter_beyond_floating_point_is_named_not_the_step(tmp_path, capsys, monkeypatch):
    """On main: `check` ok, then a blow-up at step 0 advised "reduce fine.dt (now 1e-06)"."""
    path = _write(tmp_path, _rod("bending = 1e300"))
    assert cli.main(["check", str(path)]) == 2
    assert _errors(capsys)[1] == (
        "  model: the rates at the initial state reach 1.16e+303, and one fine step from there "
        "is not finite: values beyond what floating point holds, which no smaller step fixes; "
        "check the parameters' magnitudes and units (the largest: bending = 1e+300)")
    module = importlib.import_module("parastokes.config.preflight")
    monkeypatch.setattr(module, "HUGE_RATES", math.inf)  # rates of any size: the step's fault
    assert cli.main(["check", str(path)]) == 2
    assert _errors(capsys)[1] == ("  fine.dt: one step of rk2 of 1e-06 from the initial state "
                                  "is not finite: reduce fine.dt")
    assert cli.main(["check", str(_write(tmp_path, _rod(), "ok.toml"))]) == 0
