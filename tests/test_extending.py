"""docs/extending.md as a new user follows it: its files written into an empty folder, its scripts
run, its config checked and run through the command line, with no edit to parastokes."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BLOCK = re.compile(r"<!-- (file|append|run): (\S+) -->\n```\w*\n(.*?)```", re.S)


def _python(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=f"{cwd}{os.pathsep}{ROOT}")
    return subprocess.run([sys.executable, *args], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=600)


@pytest.fixture(scope="module")
def walk(tmp_path_factory):
    """The folder after every file and script step of the page (scripts' outputs by name)."""
    folder = tmp_path_factory.mktemp("user")
    outputs = {}
    for action, name, text in BLOCK.findall((ROOT / "docs" / "extending.md").read_text()):
        path = folder / name
        if action == "append":
            path.write_text(path.read_text() + "\n\n" + text)
        else:
            path.write_text(text)
        if action == "run":
            done = _python([name], folder)
            assert done.returncode == 0, done.stderr
            outputs[name] = done.stdout
    return folder, outputs


def _check_and_run(folder: Path, name: str, out: str) -> tuple[str, dict]:
    """``parastokes check`` and ``run`` of the page's config ``name``: check's output, the
    run's summary."""
    checked = _python(["-m", "parastokes", "check", name], folder)
    assert checked.returncode == 0, checked.stderr
    done = _python(["-m", "parastokes", "run", name, "--out", out], folder)
    assert done.returncode == 0, done.stderr
    return checked.stdout, json.loads((folder / out / "summary.json").read_text())


def test_the_pages_python_steps_run(walk):
    _, outputs = walk
    assert outputs["check.py"].strip() == "contract ok"
    assert outputs["check_compiled.py"].strip() == "compiled loop ok"
    assert outputs["parareal_cloud.py"].startswith("errors")
    assert outputs["check_beads.py"].strip() == "beads ok"
    coupling, relaxed = outputs["stiff_coarse.py"].splitlines()
    assert coupling == "coupling checked: 0.0e+00"
    assert relaxed == "ros2 at 0.1: monitor 0.00241 of 0.192 at the start"
    assert outputs["broken_beads.py"].strip() == (
        "OneRowShort.forces(state) returned shape (7, 3); expected (8, 3): one row per point")
    assert outputs["check_device.py"].strip() == "device ok"  # the cloud's device parts (11.)
    assert outputs["check_executor.py"].strip() == "executor ok"  # an executor kind (12.)


def test_the_pages_stiff_body_is_stable_at_larger_steps_at_a_larger_epsilon(walk):
    """Section 10: the stable Euler step of the stiff beads grows with ε (the extrapolated G's
    nodes are where the body is softer); the page says 0.0191 and 0.0229."""
    _, outputs = walk
    numbers = re.findall(r"up to (\S+) at ε⁰ = 0\.3, (\S+) at ε = 0\.45", outputs["stiff_step.py"])
    ((at_theta0, wider),) = numbers
    assert 0.015 < float(at_theta0) < 0.025 and float(wider) > 1.15 * float(at_theta0)


def test_a_users_compiled_loop_leaves_the_packages_loops_loadable(walk):
    """numba unpickles every key of a function's cache index when it reads it: after the page's
    compiled loop was cached, a process that cannot import the user's module must still load the
    package's compiled loops (the user's types are cached in an index of their own)."""
    folder, _ = walk
    script = ("from parastokes import integrate\n"
              "from parastokes.kinds.chain import KIND\n"
              "system, x, _ = KIND.example()\n"
              "print(integrate.run(system, x, 0.0, 0.05, 'rk2', 0.01).n_steps)\n")
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    done = subprocess.run([sys.executable, "-c", script], cwd=folder.parent, env=env,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "5"


def test_the_pages_config_checks_and_runs_from_the_command_line(walk):
    folder, _ = walk
    checked, summary = _check_and_run(folder, "cloud.toml", "cloud_run")
    assert "mybodies:SedimentingCloud" in checked
    out = folder / "cloud_run"
    assert summary["config"]["model"]["weight"] == 2.0
    assert summary["errors"][-1] < 1e-8
    assert len(summary["final_positions"]) == 20
    assert 'TopologyType="Polyvertex"' in (out / "trajectory.xdmf").read_text()
    assert (out / "structure.png").exists()


def test_the_pages_body_kind_is_found_by_its_name(walk):
    folder, _ = walk
    text = (folder / "cloud.toml").read_text()
    text = text.replace('kind = "mybodies:SedimentingCloud"', 'kind = "mybodies:CLOUD"')
    (folder / "cloud_kind.toml").write_text(text.replace("weight = 2.0\n", ""))
    done = _python(["-m", "parastokes", "check", "cloud_kind.toml"], folder)
    assert done.returncode == 0, done.stderr
    (folder / "typo.toml").write_text(text)  # weight is not a key of CloudSection
    done = _python(["-m", "parastokes", "check", "typo.toml"], folder)
    assert done.returncode != 0 and "model.weight: unknown key" in done.stderr + done.stdout


def test_the_pages_coarse_family_checks_predicts_and_runs(walk):
    """Section 9: the user's plain G, found by ``[coarse] kind``; Parareal is exact after N_c = 2
    iterations whatever G is, and predict uses the family's own γ_G/γ_F (1 Euler step of 10 τ_f
    against 1 RK2 step of τ_f: 1 x 5 / (2 x 50) = 0.05)."""
    folder, _ = walk
    checked, summary = _check_and_run(folder, "cloud_plain.toml", "plain_run")
    assert "N_G = 1" in checked
    done = _python(["-m", "parastokes", "predict", "cloud_plain.toml", "--cores", "2"], folder)
    assert done.returncode == 0, done.stderr
    assert "coarse-solver family ('mycoarse:Plain') (one auxiliary solve: 0.05;" in done.stdout
    assert summary["config"]["coarse"]["kind"] == "mycoarse:Plain"
    assert summary["errors"][0] > 1e-6 > 1e-13 > summary["errors"][-1]
    (folder / "typo_plain.toml").write_text(
        (folder / "cloud_plain.toml").read_text().replace("dt_ratio", "dt_ratoi"))
    done = _python(["-m", "parastokes", "check", "typo_plain.toml"], folder)
    assert done.returncode != 0 and "coarse.dt_ratoi: unknown key" in done.stderr + done.stdout



def test_the_pages_tuning_reach_is_what_the_tuner_reads(walk):
    folder, _ = walk
    script = ("import mybodies\nfrom parastokes.tuning.space import reach_table\n"
              "print(reach_table(mybodies.SedimentingCloud)['epsilon'])\n")
    done = _python(["-c", script], folder)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "((0.1, 0.2, 0.4), 0.5)"
