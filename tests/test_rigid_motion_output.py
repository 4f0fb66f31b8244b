"""A rigid body's motion in its trajectory: the velocity U and the angular velocity Ω of its
centre, written with every frame beside its pose (``velocity``, ``angular_velocity``), equal to the
system's rates at the saved state, in free space against Stokes' laws and the body's own
resistance solve, through the CLI (alone, and in a scene), read back and in the XDMF."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from written_frames import write_frames

from parastokes import config, flow
from parastokes.cli import main
from parastokes.kinds.rigid.rotation import multiply
from parastokes.output import trajectory as io

QUICK = Path(__file__).resolve().parents[1] / "experiments" / "quick"
MU, RADIUS = 2.0, 1.0
LOAD = [0.3, -0.2, 1.0]


def _sphere(load: str) -> str:
    """A free sphere of 400 points under the external ``load`` ("force" or "torque")."""
    return f"""
[model]
kind = "rigid"
shape = "sphere"
radius = {RADIUS}
n_points = 400
epsilon = 0.5
epsilon_unit = "spacing"
viscosity = {MU}
{load} = {LOAD}
[time]
t1 = 0.2
[fine]
dt = 0.1
[coarse]
dt_ratio = 2
[parareal]
n_slices = 2
[execution]
workers = 1
"""


def _frames(directory: Path, text: str):
    """Three frames of the model of ``text``, written as the runner writes them, read back."""
    times = np.array([0.0, 0.1, 0.2])
    system, states = write_frames(directory, text, times, 0.1)
    bodies = io.read_trajectory(directory / "trajectory.h5")["bodies"]
    return system, times, states, bodies["center"]


def test_a_sphere_under_a_force_saves_its_stokes_velocity_and_no_turn(tmp_path):
    system, times, states, center = _frames(tmp_path, _sphere("force"))
    u, omega = center["velocity"], center["angular_velocity"]
    assert u.shape == omega.shape == (3, 1, 3)
    force = np.array(LOAD)
    stokes = force / (6 * math.pi * MU * RADIUS)
    for i, (t, x) in enumerate(zip(times, states, strict=True)):
        # the body's own resistance problem at the saved motion gives back the load
        back = system.resistance(t, x, u[i, 0], omega[i, 0])
        np.testing.assert_allclose(back.force[0], force, rtol=0, atol=1e-8 * np.abs(force).max())
        np.testing.assert_allclose(back.torque[0], 0.0, atol=1e-8 * np.abs(force).max() * RADIUS)
        # Stokes' law within the discretisation's error (1.4 % at 400 points)
        assert np.linalg.norm(u[i, 0] - stokes) < 0.03 * np.linalg.norm(stokes)
        assert np.linalg.norm(omega[i, 0]) < 1e-3 * np.linalg.norm(stokes) / RADIUS
    # the centre moved with the saved velocity (the first frame's, rk2 and a steady motion)
    np.testing.assert_allclose(center["positions"][1, 0] - center["positions"][0, 0],
                               0.1 * u[0, 0], rtol=1e-6)


def test_a_sphere_under_a_torque_saves_its_stokes_angular_velocity_and_no_drift(tmp_path):
    system, times, states, center = _frames(tmp_path, _sphere("torque"))
    u, omega = center["velocity"], center["angular_velocity"]
    torque = np.array(LOAD)
    stokes = torque / (8 * math.pi * MU * RADIUS**3)
    for i, (t, x) in enumerate(zip(times, states, strict=True)):
        back = system.resistance(t, x, u[i, 0], omega[i, 0])
        np.testing.assert_allclose(back.torque[0], torque, rtol=0,
                                   atol=1e-8 * np.abs(torque).max())
        np.testing.assert_allclose(back.force[0], 0.0, atol=1e-8 * np.abs(torque).max() / RADIUS)
        # Stokes' law for the rotlet within the discretisation's error (4.6 % at 400 points)
        assert np.linalg.norm(omega[i, 0] - stokes) < 0.06 * np.linalg.norm(stokes)
        assert np.linalg.norm(u[i, 0]) < 1e-3 * np.linalg.norm(stokes) * RADIUS
    # the saved Ω is the one the quaternion turned with: q̇ = Ω ⊗ q / 2 over the first step
    q0, q1 = center["orientation"][0, 0], center["orientation"][1, 0]
    w, x, y, z = q0
    rate = (q1 - q0) / 0.1
    # Ω = 2 q̇ ⊗ q* (vector part), q* the conjugate
    conj = np.array([w, -x, -y, -z])
    np.testing.assert_allclose(2 * multiply(rate, conj)[1:], omega[0, 0], rtol=0.02)


def test_the_motion_is_written_only_with_the_rates_and_shows_as_vectors_in_the_xdmf(tmp_path):
    cfg, _ = config.loads(_sphere("force"))
    system = cfg.model.build(1)
    layout = cfg.model.layout(system, False, None)
    with pytest.raises(ValueError, match=r"\['center'\].*rates=system\.rates"):
        io.TrajectoryWriter(tmp_path / "none.h5", layout, config={})
    with io.TrajectoryWriter(tmp_path / "short.h5", layout, config={},
                             rates=lambda t, x: np.zeros((1, 4))) as writer:
        with pytest.raises(ValueError, match=r"'center': its angular_velocity is columns 3:6 of "
                                             r"rows 0:1 of the rates, which have shape \(1, 4\)"):
            writer.append("serial", 0.0, system.initial_state())
        assert "serial" not in writer.file  # nothing of the frame was written
    _frames(tmp_path, _sphere("force"))
    tree = ET.parse(io.write_xdmf(tmp_path / "trajectory.h5"))
    kinds = {a.get("Name"): a.get("AttributeType") for a in tree.iter("Attribute")}
    assert kinds["velocity"] == kinds["angular_velocity"] == "Vector"


def _rebuilt(directory: Path, body: str, run: str = "serial"):
    """The run in ``directory``: its frames' saved U and Ω of ``body`` and the rates of its
    system at each saved (rebuilt) state, at the centre's row."""
    frames = flow.load_run(directory, run)
    layout = next(b for b in frames.layout if b.name == body)
    saved = frames.data["bodies"][body]
    rates = np.array([frames.system.rates(t, frames.state(i))[layout.first]
                      for i, t in enumerate(frames.times)])
    return frames, saved, rates


@pytest.mark.parametrize("run", ["serial", "parareal"])
def test_a_sedimenting_sphere_run_saves_its_motion_with_every_frame(tmp_path, run):
    out = tmp_path / "out"
    assert main(["run", str(QUICK / "sphere_sediments_to_wall.toml"), "--out", str(out), "-q",
                 "--set", f"run.mode={run}", "--set", "output.figures=false",
                 "--set", "execution.executor='serial'", "--set", "execution.workers=1"]) == 0
    frames, saved, rates = _rebuilt(out, "center", run)
    n = len(frames.times)
    assert n == 5 and saved["velocity"].shape == saved["angular_velocity"].shape == (n, 1, 3)
    np.testing.assert_allclose(saved["velocity"][:, 0], rates[:, :3], rtol=1e-12, atol=0)
    np.testing.assert_allclose(saved["angular_velocity"][:, 0], rates[:, 3:6], rtol=0,
                               atol=1e-12 * np.abs(rates[:, :3]).max())
    # falling toward the wall, slowing down; the centre's displacement between frames is the
    # mean of the saved velocities at its ends (to second order in the frame spacing)
    u = saved["velocity"][:, 0]
    assert np.all(u[:, 2] < 0) and np.all(np.diff(np.abs(u[:, 2])) < 0)
    moved = np.diff(saved["positions"][:, 0], axis=0) / np.diff(frames.times)[:, None]
    np.testing.assert_allclose(moved, 0.5 * (u[1:] + u[:-1]), rtol=0,
                               atol=1e-3 * np.abs(u).max())


def test_a_scene_saves_the_motion_of_its_rigid_body_from_the_coupled_solve(tmp_path):
    out = tmp_path / "out"
    assert main(["run", str(QUICK / "scene_sphere_and_rod.toml"), "--out", str(out), "-q",
                 "--set", "run.mode=serial", "--set", "output.figures=false",
                 "--set", "time.t1=4e-5", "--set", "parareal.n_slices=2"]) == 0
    frames, saved, rates = _rebuilt(out, "sphere_center")
    assert saved["velocity"].shape == (3, 1, 3)
    np.testing.assert_allclose(saved["velocity"][:, 0], rates[:, :3], rtol=1e-12, atol=0)
    np.testing.assert_allclose(saved["angular_velocity"][:, 0], rates[:, 3:6], rtol=0,
                               atol=1e-12 * np.abs(rates[:, :3]).max())
    # the coupled solve's, not the sphere's alone: the rod's flow moves it too
    sphere = frames.system.bodies[1]
    alone = sphere.rates(frames.times[0], frames.system.blocks(frames.state(0))[1])
    assert not np.allclose(alone[0, :6], rates[0, :6], rtol=1e-6, atol=0)
    # only the rigid body has a motion dataset
    assert "velocity" not in frames.data["bodies"]["rod"]
