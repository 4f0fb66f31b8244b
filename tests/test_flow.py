"""The flow anywhere (parastokes.flow): closed formulas, the wall, the bodies' own rates, far-field
decay, time averages, the XDMF grid read back, and the commands flow and movie on a small run."""

from __future__ import annotations

import itertools
import json
import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, replace

import h5py
import numpy as np
import pytest
from documented import check

from parastokes import config, flow, integrate, models
from parastokes.bodies.sources import FluidSources, fluid_sources
from parastokes.cli import main
from parastokes.flow.evaluate import sources_velocity
from parastokes.flow.grids import PlaneSpec, grid_for
from parastokes.kinds.chain import ChainSystem
from parastokes.mrs import reference
from parastokes.output import trajectory as io
from parastokes.scene import Scene

RNG = np.random.default_rng(31)


@dataclass(frozen=True)
class PointLoads:
    """Fixed point forces (scaled by t with ``grow``) as a system: the smallest body with loads."""

    points: np.ndarray
    forces: np.ndarray
    epsilon: float = 0.3
    viscosity: float = 2.0
    wall: bool = False
    grow: bool = False

    def loads(self, t, state):
        return self.forces * (t if self.grow else 1.0), None


def stokeslet(x: np.ndarray, y: np.ndarray, f: np.ndarray, eps: float, mu: float) -> np.ndarray:
    """docs/physics.md (1): u = [H1 f + H2 (f·r) r] / μ, H1 = (r² + 2ε²)/(8π r_ε³),
    H2 = 1/(8π r_ε³)."""
    r = x - y
    r2 = np.sum(r * r, axis=1, keepdims=True)
    re3 = (r2 + eps**2) ** 1.5
    return ((r2 + 2 * eps**2) * f + (r @ f)[:, None] * r) / (8 * math.pi * re3 * mu)


def test_a_regularized_stokeslet_and_a_force_dipole_follow_the_closed_formulas():
    y, f = np.array([[0.5, -1.0, 2.0]]), np.array([[0.3, -1.2, 0.8]])
    system = PointLoads(y, f)
    targets = RNG.uniform(-5, 5, size=(50, 3))
    u = flow.velocity(system, y, targets)
    np.testing.assert_allclose(u, stokeslet(targets, y[0], f[0], 0.3, 2.0), rtol=1e-12,
                               atol=1e-15)
    # a force dipole: +f e at +d/2 e and -f e at -d/2 e; far away the stresslet
    # u = f d (3 (e·x̂)² - 1) x̂ / (8π μ r²)
    e, d = np.array([0.0, 0.6, 0.8]), 0.5
    pair = PointLoads(np.array([d / 2 * e, -d / 2 * e]), np.array([e, -e]), epsilon=0.05,
                      viscosity=1.0)
    near = RNG.uniform(-3, 3, size=(40, 3))
    np.testing.assert_allclose(
        flow.velocity(pair, pair.points, near),
        stokeslet(near, pair.points[0], e, 0.05, 1.0) + stokeslet(near, pair.points[1], -e,
                                                                 0.05, 1.0),
        rtol=1e-12, atol=1e-15)
    hat = np.random.default_rng(40).normal(size=(40, 3))  # its own draws: a documented number
    hat /= np.linalg.norm(hat, axis=1, keepdims=True)
    r = 200.0
    far = (3 * (hat @ e) ** 2 - 1)[:, None] * hat * d / (8 * math.pi * r**2)
    u = flow.velocity(pair, pair.points, r * hat)
    error = np.max(np.linalg.norm(u - far, axis=1)) / np.max(np.linalg.norm(far, axis=1))
    assert error < 1e-4
    check("flow", "dipole_error", error)


def test_above_the_wall_the_field_is_the_image_system_and_vanishes_on_the_wall():
    y = np.array([[0.3, -0.2, 2.0], [1.0, 0.5, 3.5]])
    f, n = RNG.normal(size=(2, 3)), RNG.normal(size=(2, 3))
    sources = FluidSources(y, f, n, np.array([0.4, 0.25]))
    targets = np.column_stack([RNG.uniform(-6, 6, size=(60, 2)), RNG.uniform(0.1, 6, 60)])
    u = sources_velocity(sources, targets, 1.5, wall=True)
    expected = sum(reference.velocity(targets, y[k : k + 1], f[k : k + 1], torques=n[k : k + 1],
                                      epsilon=e, mu=1.5, wall=True)
                   for k, e in enumerate(sources.epsilon))
    np.testing.assert_allclose(u, expected, rtol=1e-10, atol=1e-14)
    on_wall = np.column_stack([RNG.uniform(-10, 10, size=(100, 2)), np.zeros(100)])
    assert np.max(np.abs(sources_velocity(sources, on_wall, 1.5, wall=True))) < 1e-12 * np.max(
        np.abs(u))
    below = on_wall - [0, 0, 1.0]  # no fluid below the wall
    assert not np.any(sources_velocity(sources, below, 1.5, wall=True))
    sphere = replace(models.vesicle(1, viscosity=1e-6, shear_rate=2.0), center=(0.0, 0.0, 3.0))
    shear = Scene((sphere,), 1e-6, wall=True, shear_rate=2.0)
    assert not np.any(flow.velocity(shear, shear.initial_state(), below))


def _active_rod(**kw):
    rod = models.rod_swimmer(1, 21, 1.0, length=4.0, wavelength=2.0, **kw)
    return rod, integrate.propagate(rod, rod.initial_state(), t0=0.0, t1=1e-4, scheme="rk2",
                                    dt=1e-6)


def test_the_flow_at_a_bodys_points_is_the_velocity_its_rates_move_them_with():
    rod, x = _active_rod()
    np.testing.assert_array_equal(flow.velocity(rod, x, x[:, :3], t=1e-4),
                                  rod.rates(1e-4, x)[:, :3])
    vesicle = models.vesicle(subdivisions=1)
    v = vesicle.initial_state() * [1.1, 1.0, 0.95]
    np.testing.assert_array_equal(flow.velocity(vesicle, v, v), vesicle.rates(0.0, v))
    chain = ChainSystem(n_beads=8, stiffness=20.0, bending=2.0, shear_rate=1.0)
    c = chain.initial_state() + RNG.normal(scale=0.05, size=(8, 3))
    np.testing.assert_array_equal(flow.velocity(chain, c, c), chain.rates(0.0, c))
    sphere = replace(models.vesicle(1, viscosity=1e-6, shear_rate=0.0), center=(1.0, 0.0, 14.0))
    scene = Scene((rod, sphere), 1e-6, wall=True)
    s = scene.initial_state()
    s[: len(x), : x.shape[1]] = x
    rates = scene.rates(1e-4, s)
    np.testing.assert_array_equal(flow.velocity(scene, s, s[:, :3], t=1e-4), rates[:, :3])
    sources = fluid_sources(scene, 1e-4, s)
    assert sources.torques is not None and not np.any(sources.torques[len(x):])
    np.testing.assert_array_equal(sources.epsilon, scene.source_epsilon())


def test_a_body_that_does_not_say_what_it_exerts_is_refused_by_name():
    from user_body import SedimentingCloud

    with pytest.raises(ValueError, match=r"SedimentingCloud.*loads"):
        flow.velocity(SedimentingCloud(), np.zeros((2, 3)), np.ones((1, 3)))


def _slope(system, state, centre, t=0.0):
    hat = np.random.default_rng(16).normal(size=(16, 3))  # its own draws: a documented number
    hat /= np.linalg.norm(hat, axis=1, keepdims=True)
    radii = np.geomspace(50.0, 500.0, 6)
    mags = [np.linalg.norm(flow.velocity(system, state, centre + r * hat, t), axis=1).mean()
            for r in radii]
    return np.polyfit(np.log(radii), np.log(mags), 1)[0]


@dataclass(frozen=True)
class TowedChain(ChainSystem):
    """A chain pulled by a constant force per bead (a sedimenting polymer): a net force."""

    def forces(self, state):
        return super().forces(state) + np.array([0.0, 0.0, -1.0])


def test_a_force_free_swimmer_decays_like_r_minus_2_and_a_towed_body_like_r_minus_1():
    rod, x = _active_rod(wall=False)
    assert np.allclose(fluid_sources(rod, 1e-4, x).forces.sum(axis=0), 0.0, atol=1e-12)
    swimmer = _slope(rod, x, x[:, :3].mean(axis=0), 1e-4)
    assert abs(swimmer + 2.0) < 0.02
    chain = TowedChain(n_beads=8, stiffness=20.0, bending=2.0)
    c = chain.initial_state()
    towed = _slope(chain, c, c.mean(axis=0))
    assert abs(towed + 1.0) < 0.02
    check("flow", "slope_swimmer", swimmer)
    check("flow", "slope_towed", towed)


def test_the_time_average_of_a_flow_linear_in_time_is_the_flow_at_the_middle():
    system = PointLoads(np.array([[0.0, 0.0, 1.0]]), np.array([[1.0, 0.0, 0.0]]), grow=True)
    times = np.array([0.0, 0.1, 0.3, 0.4, 0.7, 1.0])  # uneven frames: the trapezoidal rule
    states = [system.points] * len(times)
    points = RNG.uniform(-2, 2, size=(10, 3))
    mean = flow.time_average(system, states, times, points, 0.1, 0.7)
    np.testing.assert_allclose(mean, flow.velocity(system, system.points, points, t=0.4),
                               rtol=1e-12)
    with pytest.raises(ValueError, match="no saved frame"):
        flow.time_average(system, states, times, points, 0.75, 0.9)


@dataclass(frozen=True)
class Rotlet:
    """One point torque n = (0, 0, 1) at the origin: u = n × r / (8π μ r_ε³), circles about z."""

    epsilon: float = 0.5
    viscosity: float = 1.0

    def loads(self, t, state):
        return np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]])


def test_streamlines_of_a_rotlet_are_circles_about_its_axis():
    seeds = np.array([[1.0, 0.0, 0.0], [0.0, 2.0, 0.5], [-0.5, 0.0, -1.0]])
    lines = flow.streamlines(Rotlet(), np.zeros((1, 3)), seeds, length=2 * math.pi, samples=65)
    for seed, line in zip(seeds, lines, strict=True):
        assert line.shape == (129, 3)
        np.testing.assert_allclose(line[64], seed)
        radius = np.hypot(seed[0], seed[1])
        np.testing.assert_allclose(np.hypot(line[:, 0], line[:, 1]), radius, rtol=1e-6)
        np.testing.assert_allclose(line[:, 2], seed[2], atol=1e-9)
        angle = np.unwrap(np.arctan2(line[:, 1], line[:, 0]))
        np.testing.assert_allclose(np.diff(angle), 2 * math.pi / 64 / radius, rtol=1e-6)


def test_the_xdmf_grid_reads_back_with_its_shape_origin_spacing_and_node_order(tmp_path):
    box = np.array([[-1.0, 3.0], [0.0, 2.0], [0.5, 1.5]])
    grid = grid_for(box, (5, 3, 2))
    points = grid.points()
    values = np.stack([points, 2 * points])  # u = x at t0, 2x at t1: where each value sits
    h5, xdmf = flow.write_grid(tmp_path / "f", grid, np.array([0.0, 0.5]), values)
    root = ET.parse(xdmf).getroot()
    steps = root.findall("./Domain/Grid/Grid")
    assert [float(s.find("Time").get("Value")) for s in steps] == [0.0, 0.5]
    topology = steps[1].find("Topology")
    assert topology.get("TopologyType") == "3DRectMesh"
    assert topology.get("Dimensions") == "2 3 5"  # nz ny nx
    with h5py.File(h5, "r") as f:
        axes = []
        for item in steps[1].find("Geometry").findall("DataItem"):
            name, path = item.text.split(":")
            assert name == h5.name
            axes.append(f[path][()])
        np.testing.assert_allclose([a[0] for a in axes], box[:, 0])
        np.testing.assert_allclose([a[1] - a[0] for a in axes], [1.0, 1.0, 1.0])
        slab = steps[1].find("Attribute[@Name='velocity']/DataItem")
        start, stride, count = np.array(slab[0].text.split(), dtype=int).reshape(3, -1)
        data = f[slab[1].text.split(":")[1]][()]
        assert data.shape == (2, 2, 3, 5, 3)
        frame = data[tuple(slice(a, a + s * c, s) for a, s, c in zip(start, stride, count,
                                                                    strict=True))][0]
        zz, yy, xx = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")
        np.testing.assert_allclose(frame, 2 * np.stack([xx, yy, zz], axis=-1))
    back, _, velocity = flow.read_grid(h5)
    assert back == grid and velocity.shape == (2, 2, 3, 5, 3)


def test_a_plane_below_the_wall_or_outside_the_box_is_refused():
    box = np.array([[0.0, 1.0], [0.0, 1.0], [0.0, 1.0]])
    with pytest.raises(ValueError, match="below the wall"):
        grid_for(box, (8,), PlaneSpec(2, -1.0), wall=True)
    with pytest.raises(ValueError, match="outside the box"):
        grid_for(box, (8,), PlaneSpec(0, 2.0))


# ---- commands on a small run written directly (no solve) ------------------------------------
SCENE = """
[scene]
viscosity = 1e-6
wall = true
[[bodies]]
name = "rod"
kind = "rod"
n_points = 11
length = 2.0
wavelength = 2.0
height = 3.0
[[bodies]]
name = "vesicle"
kind = "vesicle"
subdivisions = 1
center = [1.0, 0.0, 5.0]
[time]
t1 = 4e-5
[fine]
dt = 1e-6
[coarse]
dt_ratio = 10
[parareal]
n_slices = 4
[execution]
workers = 4
"""


@pytest.fixture(scope="module")
def scene_run(tmp_path_factory):
    """A scene's run directory: five frames of the scene, as the runner writes them."""
    cfg, resolved = config.loads(SCENE)
    scene = cfg.model.build(1)
    directory = tmp_path_factory.mktemp("run")
    layout = cfg.model.layout(scene, True, None)
    times = np.linspace(0.0, 4e-5, 5)
    states = [scene.initial_state()]
    for t0, t1 in itertools.pairwise(times):
        states.append(integrate.propagate(scene, states[-1], t0=t0, t1=t1, scheme="rk2",
                                          dt=1e-6))
    with io.TrajectoryWriter(directory / "trajectory.h5", layout,
                             config=config.resolved_dict(cfg, resolved)) as writer:
        for t, x in zip(times, states, strict=True):
            writer.append("serial", t, x)
    return directory, scene, times, states


def test_a_run_is_rebuilt_with_its_full_states(scene_run):
    directory, scene, _, states = scene_run
    run = flow.load_run(directory)
    assert run.system == scene
    for i in (0, 4):
        np.testing.assert_array_equal(run.state(i), states[i])
    assert run.frame(time=2.1e-5) == 2


def test_flow_writes_the_grid_and_picture_of_a_frame(scene_run, tmp_path):
    directory, scene, times, states = scene_run
    out = tmp_path / "f"
    assert main(["flow", str(directory), "--frame", "3", "--plane", "z=4",
                 "--resolution", "12x10", "--out", str(out), "-q"]) == 0
    grid, saved_times, velocity = flow.read_grid(out.with_suffix(".h5"))
    assert grid.shape == (12, 10, 1) and saved_times[0] == times[3]
    expected = flow.velocity(scene, states[3], grid.points(), t=times[3])
    np.testing.assert_allclose(velocity[0].reshape(-1, 3), expected, rtol=1e-12)
    assert (tmp_path / "f.png").stat().st_size > 0
    assert main(["flow", str(directory), "--average", "0", "4e-5", "--box", "-1", "3", "-1", "1",
                 "0", "6", "--resolution", "4", "--out", str(tmp_path / "m"), "-q"]) == 0
    grid, _, velocity = flow.read_grid(tmp_path / "m.h5")
    assert velocity.shape == (1, grid.shape[2], grid.shape[1], grid.shape[0], 3)


@pytest.mark.parametrize("argv, fix", [
    (["--frame", "9"], "choose an index from 0 to 4"),
    (["--time", "1.0"], "outside the saved frames"),
    (["--plane", "z=-1"], "below the wall"),
    (["--plane", "q=1"], "AXIS=VALUE"),
])
def test_bad_flow_requests_exit_2_naming_what_to_change(scene_run, argv, fix, capsys):
    directory = scene_run[0]
    assert main(["flow", str(directory), *argv]) == 2
    err = capsys.readouterr().err
    assert fix in err and len(err.strip().splitlines()) == 1


def test_flow_of_a_directory_without_trajectory_exits_2(tmp_path, capsys):
    assert main(["flow", str(tmp_path)]) == 2
    assert "holds no trajectory.h5" in capsys.readouterr().err


def test_movies_have_the_requested_frames_and_size(scene_run, tmp_path):
    imageio = pytest.importorskip("imageio.v2")
    pytest.importorskip("imageio_ffmpeg")
    from PIL import Image

    directory = scene_run[0]
    assert main(["movie", str(directory), "--out", str(tmp_path / "a.mp4"), "--frames", "3",
                 "--size", "320x240", "-q"]) == 0
    reader = imageio.get_reader(tmp_path / "a.mp4")
    assert reader.count_frames() == 3 and reader.get_meta_data()["size"] == (320, 240)
    reader.close()
    assert main(["movie", str(directory), "--out", str(tmp_path / "b.gif"), "--flow",
                 "--resolution", "8", "--size", "160x120", "-q"]) == 0
    with Image.open(tmp_path / "b.gif") as gif:
        assert gif.n_frames == 5 and gif.size == (160, 120)


def test_a_runs_own_flow_output_and_its_config_check(scene_run):
    from parastokes.flow.command import write_run_flow

    directory = scene_run[0]
    write_run_flow(directory, 2, "y=0", 8)
    grid, times, velocity = flow.read_grid(directory / "flow.h5")
    np.testing.assert_array_equal(times, scene_run[2][::2])
    assert grid.plane_axes == (0, 2) and velocity.shape[0] == 3
    with pytest.raises(config.ConfigError, match=r"output\.flow_every"):
        config.loads(SCENE + "[output]\ntrajectory = false\nflow_every = 2\n")


def test_a_rod_run_without_its_frames_is_refused_naming_the_option(tmp_path):
    cfg, resolved = config.loads(SCENE + "[output]\nframes = false\n")
    scene = cfg.model.build(1)
    with io.TrajectoryWriter(tmp_path / "trajectory.h5", cfg.model.layout(scene, False, None),
                             config=config.resolved_dict(cfg, resolved)) as writer:
        writer.append("serial", 0.0, scene.initial_state())
    with pytest.raises(ValueError, match=r"rod.*output\.frames = true"):
        flow.load_run(tmp_path)


def test_vtk_reads_the_flow_grid_as_paraview_would(tmp_path):
    """VTK's XDMF reader (behind ParaView's "XDMF Reader"; skipped without the vtk package, as in
    tests/test_io.py): the time steps, the axes and the velocity at every node as written."""
    xdmf2 = pytest.importorskip("vtkmodules.vtkIOXdmf2", reason="VTK (pip install vtk) not found")
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkCommonExecutionModel import vtkStreamingDemandDrivenPipeline

    grid = grid_for(np.array([[-1.0, 3.0], [0.0, 2.0], [0.5, 1.5]]), (5, 3, 2))
    points = grid.points()
    _, xdmf = flow.write_grid(tmp_path / "f", grid, np.array([0.0, 0.5]),
                              np.stack([points, 2 * points]))
    reader = xdmf2.vtkXdmfReader()
    reader.SetFileName(str(xdmf))
    reader.UpdateInformation()
    info = reader.GetOutputInformation(0)
    assert info.Get(vtkStreamingDemandDrivenPipeline.TIME_STEPS()) == pytest.approx((0.0, 0.5))
    reader.UpdateTimeStep(0.5)
    read = reader.GetOutputDataObject(0)
    assert read.GetDimensions() == (5, 3, 2)
    for axis, values in zip((read.GetXCoordinates(), read.GetYCoordinates(),
                             read.GetZCoordinates()), grid.axes(), strict=True):
        np.testing.assert_array_equal(vtk_to_numpy(axis), values)
    np.testing.assert_array_equal(vtk_to_numpy(read.GetPointData().GetArray("velocity")),
                                  2 * points)


def test_a_run_with_flow_every_writes_its_flow_and_lists_it_with_its_results(tmp_path):
    from configs import small_rod

    path = tmp_path / "rod.toml"
    path.write_text(small_rod(rest='[execution]\nexecutor = "serial"\n[run]\nmode = "serial"\n'
                                   "[output]\nfigures = false\nflow_every = 2\n"
                                   "flow_resolution = 10\n"))
    out = tmp_path / "run"
    assert main(["run", str(path), "--out", str(out), "-q"]) == 0
    grid, times, velocity = flow.read_grid(out / "flow.h5")
    saved = io.read_trajectory(out / "trajectory.h5")["time"]
    np.testing.assert_array_equal(times, saved[::2])  # 5 frames: 0, 2, 4
    run = flow.load_run(out)
    np.testing.assert_allclose(velocity[-1].reshape(-1, 3),
                               flow.velocity(run.system, run.state(4), grid.points(), saved[4]),
                               rtol=1e-12)
    assert {"flow.h5", "flow.xdmf", "flow.png"} <= set(
        json.loads((out / ".parastokes-results.json").read_text())["files"])
