"""Suspensions in a config (parastokes/config/suspension.py, placement.py): many copies of one
body placed on a lattice, at random without overlap (seeded, to a volume fraction) or from a
file, named in order, and refused with the key to change when they cannot be placed."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from configs import SERIAL_SOLVERS

from parastokes import cli, config
from parastokes.config import ConfigError, loads
from parastokes.config import placement as placement_module

SPHERE = """
[suspensions.body]
kind = "rigid"
shape = "sphere"
radius = 1.0
n_points = 42
force = [0.0, 0.0, -1.0]
"""


def text(suspension: str, *, body: str = SPHERE, wall: bool = True, extra: str = "") -> str:
    """A scene of one [[suspensions]] table (``suspension``: its keys) of ``body``."""
    fluid = f"[scene]\nviscosity = 1.0\nwall = {'true' if wall else 'false'}\n"
    return f"title = 't'\n{fluid}\n[[suspensions]]\n{suspension}\n{body}{extra}{SERIAL_SOLVERS}"


def issues(source: str) -> dict[str, str]:
    with pytest.raises(ConfigError) as info:
        loads(source)
    return dict(info.value.issues)


def centers(cfg) -> np.ndarray:
    return np.array([b.position for b in cfg.model.bodies])


LATTICE = ('name = "sphere"\nplacement = "lattice"\ncounts = [2, 3, 2]\n'
           'spacing = [3.0, 4.0, 5.0]\ncenter = [1.0, 2.0, 10.0]')
CLOUD = ('name = "s"\nplacement = "random"\nregion = "sphere"\ncenter = [0.0, 0.0, 20.0]\n'
         "radius = 8.0\ncount = 40\nseed = 7")


def test_a_lattice_is_centred_named_in_order_and_built_as_a_scene():
    cfg, resolved = loads(text(LATTICE))
    assert cfg.model.names == [f"sphere{i}" for i in range(12)]
    got = centers(cfg)
    expect = [[1 + 3 * i, 2 + 4 * j, 10 + 5 * k] for i in (-0.5, 0.5) for j in (-1, 0, 1)
              for k in (-0.5, 0.5)]
    np.testing.assert_allclose(got, expect)
    assert resolved.n_points == 12 * 43  # a pose row and 42 surface points each
    scene = config.build(cfg, resolved).system
    assert scene.names == tuple(cfg.model.names)
    np.testing.assert_allclose(scene.initial_state()[43 * 5, :3], expect[5])


def test_random_placement_is_seeded_reproducible_inside_its_region_and_without_overlap():
    first, _ = loads(text(CLOUD))
    again, _ = loads(text(CLOUD))
    other, _ = loads(text(CLOUD.replace("seed = 7", "seed = 8")))
    c = centers(first)
    assert np.array_equal(c, centers(again))  # the same seed: the same suspension, bit for bit
    assert not np.allclose(c, centers(other))
    assert len(c) == 40
    assert np.max(np.linalg.norm(c - [0, 0, 20], axis=1)) <= 8.0 - 1.0  # wholly in the sphere
    apart = np.linalg.norm(c[:, None] - c[None], axis=-1) + 1e9 * np.eye(len(c))
    # the default gap: the larger of r/5 and 2 eps (the 42-point sphere's eps is 0.5 x gap)
    eps = first.model.bodies[0].build().epsilon
    assert apart.min() >= 2.0 + max(0.2, 2 * eps)
    # spread over the region: the mean centre near the region's centre, the cloud not bunched
    assert np.linalg.norm(c.mean(axis=0) - [0, 0, 20]) < 2.0
    assert np.max(np.linalg.norm(c - [0, 0, 20], axis=1)) > 5.5


@pytest.mark.parametrize(("region", "extent"), [("box", "size = [20.0, 16.0, 12.0]"),
                                                 ("sphere", "radius = 9.0")])
def test_a_volume_fraction_sets_the_count_and_is_reached(region, extent):
    phi = 0.12
    spec = (f'placement = "random"\nregion = "{region}"\n{extent}\ncenter = [0.0, 0.0, 15.0]\n'
            f"volume_fraction = {phi}\nseed = 1\ngap = 0.3")
    cfg, _ = loads(text(spec))
    volume = 20 * 16 * 12 if region == "box" else 4 / 3 * math.pi * 9.0**3
    body = 4 / 3 * math.pi  # radius 1: the sphere's own volume
    n = len(cfg.model.bodies)
    assert n == round(phi * volume / body)
    assert abs(n * body / volume - phi) <= body / volume / 2  # to the nearest whole body
    c = centers(cfg)
    if region == "box":
        assert np.all(np.abs(c - [0, 0, 15]) <= np.array([10, 8, 6]) - 1.0)
    apart = np.linalg.norm(c[:, None] - c[None], axis=-1) + 1e9 * np.eye(n)
    assert apart.min() >= 2.3


def test_random_orientations_are_uniform_seeded_unit_quaternions():
    cfg, _ = loads(text(CLOUD + '\norientations = "random"'))
    q = np.array([b.orientation for b in cfg.model.bodies])
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-12)
    assert len({tuple(np.round(x, 6)) for x in q}) == len(q)
    again, _ = loads(text(CLOUD + '\norientations = "random"'))
    assert np.array_equal(q, [b.orientation for b in again.model.bodies])
    # the positions do not depend on whether orientations are drawn (separate streams)
    plain, _ = loads(text(CLOUD))
    assert np.array_equal(centers(cfg), centers(plain))
    assert all(b.orientation == [1.0, 0.0, 0.0, 0.0] for b in plain.model.bodies)


def test_poses_from_a_file_next_to_the_configuration_and_through_base(tmp_path):
    (tmp_path / "poses.txt").write_text(
        "# x, y, z, qw, qx, qy, qz\n0, 0, 5, 1, 0, 0, 0\n4 0 5 0 0 0 2\n\n0 4 6 1 1 0 0\n")
    path = tmp_path / "suspension.toml"
    path.write_text(text('placement = "file"\nfile = "poses.txt"\nname = "p"'))
    cfg, _ = config.load(path)
    np.testing.assert_allclose(centers(cfg), [[0, 0, 5], [4, 0, 5], [0, 4, 6]])
    q = np.array([b.orientation for b in cfg.model.bodies])
    np.testing.assert_allclose(q, [[1, 0, 0, 0], [0, 0, 0, 1], [2**-0.5, 2**-0.5, 0, 0]])
    assert cfg.model.names == ["p0", "p1", "p2"]
    # a variant in another folder inherits the table; the file is still found next to its base
    (tmp_path / "quick").mkdir()
    (tmp_path / "quick" / "variant.toml").write_text('base = "../suspension.toml"\n')
    variant, _ = config.load(tmp_path / "quick" / "variant.toml")
    assert variant.model == cfg.model
    np.save(tmp_path / "poses.npy", np.array([[0.0, 0.0, 3.0], [3.0, 0.0, 3.0]]))
    path.write_text(text('placement = "file"\nfile = "poses.npy"'))
    cfg, _ = config.load(path)
    np.testing.assert_allclose(centers(cfg), [[0, 0, 3], [3, 0, 3]])


def test_a_suspension_of_vesicles_is_placed_by_their_center():
    body = "[suspensions.body]\nkind = 'vesicle'\nsubdivisions = 1\n"
    cfg, resolved = loads(text('placement = "lattice"\ncounts = [3, 1, 1]\nspacing = 4.0\n'
                               "center = [0.0, 0.0, 5.0]", body=body, wall=False))
    assert cfg.model.names == ["vesicle0", "vesicle1", "vesicle2"]
    np.testing.assert_allclose([b.center for b in cfg.model.bodies],
                               [[-4, 0, 5], [0, 0, 5], [4, 0, 5]])
    assert resolved.n_points == 3 * 42


def test_bodies_and_suspensions_together_every_scene_check_naming_the_body():
    alone = ("[[bodies]]\nname = 'big'\nkind = 'rigid'\nradius = 1.0\nn_points = 42\n"
             "position = [0.0, 0.0, 10.0]\n")
    cfg, _ = loads(text(LATTICE, extra="\n" + alone.replace("10.0]", "30.0]")))
    assert cfg.model.names[0] == "big" and cfg.model.names[1] == "sphere0"
    # a [[bodies]] table inside the lattice: the scene's overlap check names both bodies
    found = issues(text(LATTICE, extra="\n" + alone.replace("[0.0, 0.0, 10.0]",
                                                            "[2.5, 2.0, 7.5]")))
    assert "big and sphere8 overlap: one lies inside the other" in found["bodies"]


def test_each_copy_is_resolved_once(monkeypatch):
    from parastokes.kinds.rigid import kind

    calls = []
    solvable = kind.check_solvable
    monkeypatch.setattr(kind, "check_solvable", lambda *a: calls.append(a) or solvable(*a))
    loads(text(LATTICE))
    assert len(calls) == 1  # twelve copies of one body: its trial solve once


def test_a_suspension_runs_and_the_copies_move_as_one_scene(tmp_path):
    """A row of three spheres sedimenting in free space: one coupled solve per evaluation; by
    symmetry the middle one falls fastest and the outer two alike (mirror images, up to the
    Fibonacci points, which are not mirror symmetric: 1e-5 here)."""
    spec = 'placement = "lattice"\ncounts = [3, 1, 1]\nspacing = 3.0\ncenter = [0.0, 0.0, 0.0]'
    cfg, resolved = loads(text(spec, wall=False))
    system = config.build(cfg, resolved).system
    rates = system.rates(0.0, system.initial_state())
    u = rates[[0, 43, 86], 2]
    assert u[1] < u[0] < 0 and u[0] == pytest.approx(u[2], rel=1e-4)


@pytest.mark.parametrize(
    ("spec", "key", "fragment"),
    [
        (LATTICE.replace("center = [1.0, 2.0, 10.0]", "center = [0.0, 0.0, 3.0]"),
         "center", "body sphere0 reaches z = -0.46"),
        (LATTICE.replace("spacing = [3.0, 4.0, 5.0]", "spacing = 1.5"), "spacing",
         "raise it to at least"),
        (CLOUD.replace("20.0]", "5.0]"), "center", "raise center[2] above 8"),
        (CLOUD.replace("count = 40", "volume_fraction = 0.45"), "volume_fraction",
         "they would fill 0.821 of it, more than random close packing"),  # (at once)
        (CLOUD.replace("count = 40", "volume_fraction = 0.25"), "volume_fraction",
         "random placement gave up"),  # (below that packing, above what the placement reaches)
        (CLOUD + "\ncounts = [2, 2, 2]", "counts", "only placement = 'lattice'"),
        (CLOUD.replace("count = 40", ""), "count", "either count or volume_fraction"),
        (CLOUD.replace("radius = 8.0", "size = [4.0, 4.0, 4.0]"), "radius", "required"),
        (CLOUD.replace("radius = 8.0", "radius = 0.5"), "radius", "too small for one body"),
        (CLOUD.replace("count", "cout"), "cout", "did you mean 'count'"),
        (CLOUD + "\ngap = 0.1", "gap", "less than the bodies' ε"),
        ('placement = "file"', "file", "required by placement = 'file'"),
        ('placement = "file"\nfile = "/nonexistent/poses.txt"', "file", "cannot read"),
    ],
    ids=["lattice below the wall", "lattice too tight", "region below the wall", "too dense",
         "too dense to place", "key of another placement", "no count", "no radius",
         "region too small", "typo", "gap under eps",
         "no file", "missing file"],
)
def test_a_suspension_that_cannot_be_placed_names_its_key(spec, key, fragment):
    found = issues(text(spec))
    assert fragment in found[f"suspensions[0].{key}"], found


def test_random_placement_gives_up_after_a_bounded_effort():
    found = issues(text(CLOUD.replace("count = 40", "count = 150")))  # (packing 0.54: tried)
    message = found["suspensions[0].count"]
    drawn = placement_module.tries_allowed(150)
    assert f"after {drawn} tries" in message and "of 150 bodies placed" in message
    assert "lower count" in message


def test_bad_poses_files_are_named(tmp_path):
    def file_issue(content: str) -> str:
        (tmp_path / "poses.txt").write_text(content)
        path = tmp_path / "c.toml"
        path.write_text(text('placement = "file"\nfile = "poses.txt"'))
        with pytest.raises(ConfigError) as info:
            config.load(path)
        return dict(info.value.issues)["suspensions[0].file"]

    assert "3 numbers (x y z) or 7" in file_issue("1 2 3 4\n")
    assert "3 numbers (x y z) or 7" in file_issue("# no pose\n")
    assert "not a finite number" in file_issue("0 0 5\n0 nan 5\n")
    assert "the quaternion is zero" in file_issue("0 0 5 0 0 0 0\n")
    assert "body rigid1 reaches z = -0.46" in file_issue("0 0 5\n3 0 0.5\n")


def test_bodies_that_cannot_be_copied_or_conflict_are_named():
    chain = "[suspensions.body]\nkind = 'chain'\nn_beads = 4\n"
    found = issues(text(LATTICE, body=chain, wall=False))
    assert "has no position key" in found["suspensions[0].body.kind"]
    found = issues(text(LATTICE, body=SPHERE + "position = [0.0, 0.0, 9.0]\n"))
    assert "remove it" in found["suspensions[0].body.position"]
    found = issues(text(CLOUD + '\norientations = "random"',
                        body=SPHERE + "orientation = [1.0, 0.0, 0.0, 0.0]\n"))
    assert "turns the bodies" in found["suspensions[0].body.orientation"]
    vesicle = "[suspensions.body]\nkind = 'vesicle'\nsubdivisions = 1\n"
    found = issues(text(CLOUD + '\norientations = "random"', body=vesicle, wall=False))
    assert "no orientation key" in found["suspensions[0].orientations"]
    found = issues(text(LATTICE, body=SPHERE.replace("radius = 1.0", "radiuss = 1.0")))
    assert "did you mean 'radius'" in found["suspensions[0].body.radiuss"]
    found = issues(text(LATTICE, body=SPHERE + "name = 'x'\n"))
    assert "give name in [[suspensions]]" in found["suspensions[0].body.name"]
    twice = text(LATTICE) + "\n[[suspensions]]\n" + LATTICE.replace("10.0]", "40.0]") + SPHERE
    found = issues(twice)
    assert "'sphere0' names more than one body" in found["suspensions[0].name"]
    assert "suspensions[1].name" in found


def test_check_exits_2_with_one_line_naming_the_table(tmp_path, capsys):
    path = tmp_path / "dense.toml"
    path.write_text(text(CLOUD.replace("count = 40", "volume_fraction = 0.45")))
    assert cli.main(["check", str(path)]) == cli.ExitCode.CONFIG
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if "suspensions[0]" in line]
    assert len(lines) == 1 and "volume_fraction" in lines[0] and "lower volume_fraction" in lines[0]


def test_the_shipped_suspension_reference_is_generated():
    """docs/config.md documents the [[suspensions]] keys (generated from the schema)."""
    reference = (Path(__file__).resolve().parents[1] / "docs" / "config.md").read_text()
    assert "## `suspensions`" in reference and "`volume_fraction`" in reference
