"""Rigid bodies, squirmers and bacteria (alone and in scenes) rebuilt from a saved trajectory:
the pose written with the frames, the full states read back bit for bit, the flow of a rebuilt
state at the surface equal to the body's motion plus its slip, and the movie of such a run."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from written_frames import write_frames

from parastokes import flow
from parastokes.cli import main
from parastokes.output import trajectory as io

WALL = "viscosity = 1.0\nwall = true\nshear_rate = 0.5\n"
CELL = {"kind": "bacterium", "head": "sphere", "head_points": 30, "tail_radius": 0.2,
        "pitch": 1.0, "turns": 1.5, "tail_points": 24, "gap": 0.2}


def _toml(table: dict, inline: bool = False) -> str:
    items = [f"{k} = {json.dumps(v)}" for k, v in table.items()]
    return "{" + ", ".join(items) + "}" if inline else "\n".join(items) + "\n"


SQUIRMER = f"""
[model]
{_toml({"kind": "squirmer", "n_points": 50, "b1": 1.0, "b2": 2.0})}{WALL}
position = [0.0, 0.0, 2.0]
orientation = [0.95, 0.0, 0.3, 0.1]
"""
BACTERIUM = f"""
[model]
{_toml(CELL)}motor_rate = 6.283185307179586
{WALL}position = [0.0, 0.0, 1.5]
orientation = [0.9, 0.1, 0.2, 0.3]
"""
ROD = {"name": "rod", "kind": "rod", "n_points": 9, "length": 1.6, "wavelength": 1.6,
       "height": 3.5}
SCENE = f"""
bodies = [{_toml(ROD, True)}, {_toml({"name": "cell", **CELL, "position": [1.0, 3.0, 2.0]}, True)}]
[scene]
{WALL}"""
TIMES = """
[time]
t1 = 0.06
[fine]
dt = 0.01
[coarse]
dt_ratio = 2
[parareal]
n_slices = 3
[execution]
workers = 1
"""


def _run(directory, text):
    """A run directory of three frames of the model of ``text``, as the runner writes them."""
    times = np.array([0.0, 0.02, 0.06])
    system, states = write_frames(directory, text + TIMES, times, 0.01)
    return system, times, states


@pytest.mark.parametrize("text", [SQUIRMER, BACTERIUM, SCENE], ids=["squirmer", "bacterium",
                                                                     "scene"])
def test_a_rigid_run_is_rebuilt_with_its_poses_and_its_surface_moves_with_the_flow(
        tmp_path, text):
    system, times, states = _run(tmp_path, text)
    run = flow.load_run(tmp_path)
    assert run.system == system
    for i in range(len(times)):
        np.testing.assert_array_equal(run.state(i), states[i])
    # the pose moved (a turn, and the flagellum's phase), so a rebuild without it would differ
    body = system.bodies[1] if hasattr(system, "bodies") else system
    pose = slice(run.layout[-2].first, run.layout[-2].first + 1)
    assert not np.allclose(states[-1][pose, 3:7], states[0][pose, 3:7])
    rows = slice(run.layout[-1].first, run.layout[-1].first + run.layout[-1].rows)
    surface = run.state(2)[rows, :3]
    u = flow.velocity(run.system, run.state(2), surface, t=times[2])
    expected = system.rates(times[2], states[2])[rows, :3]  # U + Ω × r + slip
    scale = float(np.abs(expected).max())
    np.testing.assert_allclose(u, expected, rtol=0, atol=1e-8 * scale)
    if body.shape.phase_rate:
        assert states[-1][pose, 7] == pytest.approx(0.06 * body.shape.phase_rate)


def test_the_pose_is_written_as_node_data_the_xdmf_names_by_its_width(tmp_path):
    _run(tmp_path, BACTERIUM)
    data = io.read_trajectory(tmp_path / "trajectory.h5")
    center = data["bodies"]["center"]
    assert center["orientation"].shape == (3, 1, 4) and center["phase"].shape == (3, 1, 1)
    tree = ET.parse(io.write_xdmf(tmp_path / "trajectory.h5"))
    kinds = {a.get("Name"): a.get("AttributeType") for a in tree.iter("Attribute")}
    assert kinds["orientation"] == "Matrix" and kinds["phase"] == "Scalar"


def test_movies_of_a_squirmer_run_with_and_without_its_flow(tmp_path):
    from PIL import Image

    _run(tmp_path, SQUIRMER)
    assert main(["movie", str(tmp_path), "--out", str(tmp_path / "m.gif"), "--flow",
                 "--resolution", "6", "--size", "160x120", "-q"]) == 0
    with Image.open(tmp_path / "m.gif") as gif:
        assert gif.n_frames == 3 and gif.size == (160, 120)
    assert main(["movie", str(tmp_path), "--out", str(tmp_path / "b.gif"), "--frames", "2",
                 "--size", "160x120", "-q"]) == 0
    with Image.open(tmp_path / "b.gif") as gif:
        assert gif.n_frames == 2
