"""Scenes from a config file (parastokes/config/scene.py): [[bodies]] tables and [scene]."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest
from configs import small_rod

from parastokes import cli, integrate
from parastokes.config import ConfigError, build, loads
from parastokes.output import trajectory as io
from parastokes.scene import Scene

REST = """
[time]
t1 = 4e-3
[fine]
dt = 1e-4
[coarse]
dt_ratio = 5
lagrange = {lagrange}
[output]
formats = ["png"]
[execution]
executor = "serial"
allow_oversubscribe = true
[parareal]
n_slices = 4
max_iterations = 4
"""

ROD = """
[[bodies]]
kind = "rod"
n_points = 11
length = 6.0
wavelength = 3.0
height = 3.0
"""

VESICLE = """
[[bodies]]
kind = "vesicle"
subdivisions = 1
center = [3.0, 2.5, 3.0]
"""


def scene_text(*, lagrange: str = '{ "rod.epsilon" = [5.6, 5.8] }', bodies: str = ROD + VESICLE,
               fluid: str = "viscosity = 1e-3\nwall = true\nshear_rate = 0.0") -> str:
    """A rod of 11 nodes and a vesicle of 42 points above the wall, 4 slices of 10 steps."""
    return f"[scene]\n{fluid}\n{bodies}{REST.format(lagrange=lagrange)}"


def issues(text: str) -> dict[str, str]:
    with pytest.raises(ConfigError) as info:
        loads(text)
    return dict(info.value.issues)


def run_both(text: str, t1: float) -> tuple[np.ndarray, np.ndarray]:
    """The fine and the coarse propagator of ``text`` applied to its initial state on [0, t1]."""
    cfg, resolved = loads(text)
    setup = build(cfg, resolved)
    x0 = setup.system.initial_state()
    return setup.fine(0.0, t1, x0), setup.coarse(0.0, t1, x0)


@pytest.mark.parametrize(
    ("body", "lagrange"),
    [("kind = 'rod'\nn_points = 21\nlength = 4.0", "epsilon"),
     ("kind = 'vesicle'\nsubdivisions = 1", "stiffness")],
    ids=["rod", "vesicle"],
)
def test_one_body_in_bodies_is_the_model_shorthand_bit_for_bit(body, lagrange):
    """The same body as [model] and as one [[bodies]] table (the scene's fluid taken from the
    body's defaults): same fine and coarse (Lagrange-extrapolated) states, bit for bit."""
    rest = ("[time]\nt1 = 2e-5\n[fine]\ndt = 1e-6\n[coarse]\ndt_ratio = 4\n"
            "[parareal]\nn_slices = 2\n[execution]\nexecutor = 'serial'\n"
            "allow_oversubscribe = true\n[coarse.lagrange]\n")
    nodes = "{ nodes = [1.1, 1.2], unit = 'relative' }"
    name = body.split("'")[1]
    scene = f"[[bodies]]\n{body}\n{rest}'{name}.{lagrange}' = {nodes}\n"
    model = f"[model]\n{body}\n{rest}{lagrange} = {nodes}\n"
    cfg, resolved = loads(scene)
    assert isinstance(build(cfg, resolved).system, Scene)
    for a, b in zip(run_both(scene, 2e-5), run_both(model, 2e-5), strict=True):
        np.testing.assert_array_equal(a, b)


def test_scene_nodes_resolve_in_their_bodys_units():
    """ε of the rod in σ_f (its section's unit), ε of the vesicle in l_max, μ shared."""
    text = scene_text(lagrange='{ "rod.epsilon" = [5.6, 5.8], '
                               '"vesicle.epsilon" = [0.35, 0.4], viscosity = [1.1e-3, 1.2e-3] }')
    cfg, resolved = loads(text)
    sigma = 6.0 / 10
    rod_eps = cfg.model.bodies[0].resolve().theta0["epsilon"]
    assert rod_eps == pytest.approx(5.0 * sigma)
    assert resolved.lagrange["rod.epsilon"] == pytest.approx([5.6 * sigma, 5.8 * sigma])
    l_max = cfg.model.bodies[1].resolve().grid_spacing
    assert resolved.lagrange["vesicle.epsilon"] == pytest.approx([0.35 * l_max, 0.4 * l_max])
    assert resolved.lagrange["viscosity"] == [1.1e-3, 1.2e-3]
    assert resolved.n_auxiliary == 8 and resolved.n_points == 11 + 42
    system = build(cfg, resolved).system
    assert system.params == resolved.theta0
    assert (system.viscosity, system.wall, system.shear_rate) == (1e-3, True, 0.0)
    assert system.bodies[0].viscosity == system.bodies[1].viscosity == 1e-3


@pytest.fixture(scope="module")
def scene_run(tmp_path_factory):
    """The two-body scene run through the CLI: serial + Parareal with k = N = 4 iterations."""
    root = tmp_path_factory.mktemp("scene")
    path = root / "scene.toml"
    path.write_text(scene_text())
    assert cli.main(["check", str(path)]) == 0
    out = root / "out"
    assert cli.main(["run", str(path), "--out", str(out), "-q"]) == 0
    return path, out


def test_scene_parareal_reaches_the_serial_solution_when_k_is_n(scene_run):
    _, out = scene_run
    summary = io.read_summary(out / "summary.json")
    assert summary["iterations"] == 4
    assert summary["errors"][-1] < 1e-13 < summary["errors"][0]
    # and the serial solution it is compared with is the scene's fine solution
    cfg, resolved = loads(scene_text())
    setup = build(cfg, resolved)
    x = setup.system.initial_state()
    length = resolved.slice_length
    for k in range(4):
        x = setup.fine(k * length, (k + 1) * length, x)
    _, arrays = io.load_arrays(out / "reference.npz")
    np.testing.assert_allclose(arrays["states"][-1], x, rtol=0, atol=1e-12)


def test_scene_output_holds_every_body_at_its_rows(scene_run):
    _, out = scene_run
    _, arrays = io.load_arrays(out / "reference.npz")
    states = arrays["states"]
    data = io.read_trajectory(out / "trajectory.h5", "serial")
    assert data["kind"] == "scene"
    bodies = data["bodies"]
    assert {name: body["kind"] for name, body in bodies.items()} == {"rod": "rod",
                                                                     "vesicle": "vesicle"}
    np.testing.assert_array_equal(bodies["rod"]["positions"], states[:, :11, :3])
    np.testing.assert_array_equal(bodies["rod"]["D3"], states[:, :11, 9:12])
    np.testing.assert_array_equal(bodies["vesicle"]["positions"], states[:, 11:, :3])
    assert bodies["vesicle"]["connectivity"].max() == 41  # its own rows, from 0
    parareal = io.read_trajectory(out / "trajectory.h5", "parareal")["bodies"]
    np.testing.assert_allclose(parareal["vesicle"]["positions"], states[:, 11:, :3], atol=1e-12)
    grids = {g.get("Name"): g for g in ET.parse(out / "trajectory.xdmf").iter("Grid")
             if g.get("GridType") == "Uniform"}
    assert {"rod", "vesicle"} <= set(grids)
    for name, rows in (("rod", 11), ("vesicle", 42)):
        item = grids[name].find("Geometry/DataItem")
        assert item.get("Dimensions") == f"{rows} 3"
    figures = {p.name for p in out.iterdir()}
    assert {"structure.png", "structure_rod.png", "structure_vesicle.png"} <= figures


def test_predict_works_on_a_scene(scene_run, capsys):
    path, out = scene_run
    assert cli.main(["predict", str(path), "--cores", "4", "8", "--measured", str(out)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in lines[-2:]] == ["4", "8"]


def test_scene_blocks_integrate_as_their_bodies_alone_when_far_apart():
    """A vesicle 10⁵ μm away from the rod moves as if alone: the scene couples, nothing else."""
    text = scene_text(bodies=ROD + VESICLE.replace("[3.0, 2.5, 3.0]", "[1e5, 0.0, 3.0]"))
    cfg, resolved = loads(text)
    scene = build(cfg, resolved).system
    x0 = scene.initial_state()
    together = integrate.propagate(scene, x0, 0.0, 1e-3, "rk2", 1e-4)
    rod = scene.bodies[0]
    alone = integrate.propagate(rod, rod.initial_state(), 0.0, 1e-3, "rk2", 1e-4)
    np.testing.assert_allclose(together[:11], alone, rtol=0, atol=1e-9)


# ---- bad input: errors naming the key ---------------------------------------------------------
def test_model_and_bodies_together_are_refused_naming_both():
    found = issues(small_rod() + ROD)
    assert "[[bodies]]" in found["model"] and "[model]" in found["bodies"]


def test_unknown_kind_in_one_table_is_named():
    found = issues(scene_text(bodies=ROD + VESICLE.replace('"vesicle"', '"vesical"')))
    assert "bodies[1].kind" in found and "vesical" in found["bodies[1].kind"]


def test_unknown_key_in_a_body_table_gets_a_hint():
    found = issues(scene_text(bodies=ROD.replace("height", "hieght") + VESICLE))
    assert "did you mean 'height'" in found["bodies[0].hieght"]


@pytest.mark.parametrize("name", ["rodx.epsilon", "rod.stiffness", "epsilon"])
def test_lagrange_node_of_an_unknown_body_or_parameter_is_named(name):
    found = issues(scene_text(lagrange=f'{{ "{name}" = [5.6, 5.8] }}'))
    message = found[f"coarse.lagrange.{name}"]
    assert "unknown parameter" in message and "rod.epsilon" in message


def test_scene_nodes_are_checked_like_model_nodes():
    found = issues(scene_text(lagrange='{ "rod.epsilon" = { nodes = [4.0, 6.0] }, '
                                       '"vesicle.stiffness" = { nodes = [1, 2], '
                                       'unit = "l_max" } }'))
    assert "outside the node interval" in found["coarse.lagrange.rod.epsilon"]
    assert "'l_max' is not a unit" in found["coarse.lagrange.vesicle.stiffness.unit"]


def test_a_body_contradicting_the_scene_fluid_is_named():
    found = issues(scene_text(bodies=ROD + "viscosity = 2e-3\nwall = false\n" + VESICLE))
    assert "scene.viscosity" in found["bodies[0].viscosity"]
    assert "scene.wall" in found["bodies[0].wall"]
    # without [scene], the bodies must agree with each other
    found = issues(scene_text(fluid="", bodies=ROD + "viscosity = 2e-3\n" + VESICLE
                              + "viscosity = 1e-3\n"))
    assert "bodies[0].viscosity" in found["bodies[1].viscosity"]


def test_a_body_whose_viscosity_is_required_makes_the_scene_ask_for_it(tmp_path, monkeypatch):
    # regression: the scene's viscosity was read from that field's missing default
    (tmp_path / "reqvisc.py").write_text(
        "from typing import Literal\n"
        "from parastokes.registry.kinds import BodyKind, BodySection, point_layout\n"
        "class Section(BodySection):\n"
        "    kind: Literal['reqvisc:KIND']\n"
        "    viscosity: float\n"
        "KIND = BodyKind('reqvisc:KIND', Section, lambda *a: [point_layout('p', 'p', 0, 1)])\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    found = issues(scene_text(fluid="", bodies="[[bodies]]\nkind = 'reqvisc:KIND'\n"))
    assert found["scene.viscosity"].startswith("required key is missing")


def test_a_scene_of_a_body_that_cannot_join_one_fails_its_check(tmp_path):
    # regression: `check` passed and `run` failed at its first step with an AttributeError
    path = tmp_path / "cloud_scene.toml"
    path.write_text(scene_text(fluid="viscosity = 1.0", lagrange="{}",
                               bodies="[[bodies]]\nkind = 'user_body:SedimentingCloud'\n"))
    assert cli.main(["check", str(path), "-q"]) == cli.ExitCode.CONFIG
    assert "cannot join a scene" in issues(path.read_text())["bodies"]


def test_scene_without_bodies_and_bad_names_are_named():
    assert "[[bodies]]" in issues(small_rod(rest="[scene]\nwall = true\n"))["scene"]
    found = issues(scene_text(bodies=ROD + "name = 'a'\n" + VESICLE + "name = 'a'\n"))
    assert "distinct" in found["bodies[1].name"]
    # names that would break trajectory.h5 (regression: found only after the whole run)
    for name in ("time", "a/b"):
        found = issues(scene_text(bodies=ROD + f"name = '{name}'\n" + VESICLE))
        assert "without '.' or '/', and not 'time'" in found["bodies[0].name"]
    assert "did you mean" in issues(scene_text(fluid="wal = true"))["scene.wal"]


def test_tune_writes_a_scene_config_that_loads_as_the_same_scene(tmp_path):
    path = tmp_path / "scene.toml"
    path.write_text(scene_text())
    out = tmp_path / "tuned" / "scene.toml"
    status = cli.main(["tune", str(path), "--cores", "4", "--target", "1e-6", "--out", str(out),
                       "--budget", "30", "-q"])
    assert status == 0
    text = out.read_text()
    assert text.count("[[bodies]]") == 2 and "[scene]" in text and "[model]" not in text
    tuned, _ = loads(text)
    original, _ = loads(scene_text())
    assert tuned.model == original.model


def test_repeated_kinds_are_numbered_and_each_extrapolated_in_its_own_units():
    """Two rods of different grid spacings: rod0 and rod1; σ_f nodes scale with each rod's σ_f."""
    second = ROD.replace("n_points = 11", "n_points = 21").replace("height = 3.0", "height = 5.0")
    cfg, resolved = loads(scene_text(bodies=ROD + second,
                                     lagrange='{ "rod1.epsilon" = [5.6, 5.8] }'))
    assert cfg.model.names == ["rod0", "rod1"]
    assert resolved.lagrange["rod1.epsilon"] == pytest.approx([5.6 * 0.3, 5.8 * 0.3])
    assert resolved.theta0["rod0.epsilon"] == pytest.approx(5 * 0.6)
    layout = cfg.model.layout(build(cfg, resolved).system, False, None)
    assert [(b.name, b.first, b.rows) for b in layout] == [("rod0", 0, 11), ("rod1", 11, 21)]


def test_default_names_are_those_a_scene_gives_in_python():
    from parastokes.config.scene import _default_names
    from parastokes.kinds.chain import ChainSystem

    assert _default_names(["rod", "mybodies:CloudSystem", "chain", "chain"]) == [
        "rod", "cloud", "chain0", "chain1"]
    scene = Scene((ChainSystem(n_beads=4), ChainSystem(n_beads=4, height=2.0)), viscosity=1.0)
    assert list(scene.names) == _default_names(["chain", "chain"])


def tracking(text: str, tracked: str) -> str:
    """``text`` with ``output.tracked_points = tracked``."""
    return text.replace("[output]\n", f"[output]\ntracked_points = {tracked}\n", 1)


def test_tracked_points_of_a_scene_are_given_by_body_and_marked_at_that_body():
    two = ROD + VESICLE + VESICLE.replace("[3.0, 2.5, 3.0]", "[3.0, -2.5, 3.0]")
    cfg, resolved = loads(tracking(scene_text(bodies=two, lagrange="{}"), "{vesicle1 = [0, 41]}"))
    system = build(cfg, resolved).system
    parts = cfg.model.layout(system, False, cfg.output.tracked_points)
    layout = {part.name: part for part in parts}
    np.testing.assert_array_equal(np.flatnonzero(layout["vesicle1"].marks["tracked"]), [0, 41])
    default = cfg.model.bodies[1].layout(system.bodies[1], False, None)[0].marks["tracked"]
    np.testing.assert_array_equal(layout["vesicle0"].marks["tracked"], default)  # left out
    assert len(np.flatnonzero(default)) == 3
    assert not layout["rod"].marks
    # [] marks none of that body's points
    none = cfg.model.layout(system, False, {"vesicle0": []})
    assert not next(p for p in none if p.name == "vesicle0").marks["tracked"].any()


@pytest.mark.parametrize(
    ("tracked", "fragment"),
    [("[0, 5]", "give a table, e.g. {vesicle = [0, 5]}"),
     ("{vesicel = [0]}", "no body is named 'vesicel'; the bodies that mark points: vesicle"),
     ("{rod = [0]}", "rod: a rod model marks no points"),
     ("{vesicle = [42]}", "vesicle: indices must be below 42, got 42")],
    ids=["list", "unknown body", "rod", "index"],
)
def test_bad_tracked_points_of_a_scene_are_named(tracked, fragment):
    found = issues(tracking(scene_text(lagrange="{}"), tracked))
    assert fragment in found["output.tracked_points"]


def test_a_table_of_tracked_points_for_one_body_is_named():
    found = issues(small_rod(rest="[output]\ntracked_points = {rod = [0]}\n"))
    assert "a table by body name is for scenes" in found["output.tracked_points"]
