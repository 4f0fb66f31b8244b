"""The short-range repulsion between the rigid bodies of a scene (parastokes/scene/repulsion.py):
its law, equal and opposite, zero beyond its range, found among near pairs only; two spheres
pushed together settle where it balances the push; `[scene] repulsion` in a config; and a cloud
that the mobility solve refused without it runs past that time with it."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from test_suspensions import SPHERE

from parastokes import config
from parastokes.config import ConfigError
from parastokes.config.build import build
from parastokes.kinds.rigid import RigidBody, Sphere
from parastokes.kinds.rigid.shapes import Spheroid
from parastokes.mobility import SolveError
from parastokes.scene import Repulsion, Scene
from parastokes.scene import repulsion as repulsion_module
from parastokes.scene.repulsion import repulsion_loads

MU = 1.0 / (6.0 * np.pi)  # a sphere of radius 1 under a unit force moves at about 1


def sphere(position, n=42, epsilon=0.2, **kw):
    return RigidBody(shape=Sphere(1.0, n), epsilon=epsilon, viscosity=MU, position=position, **kw)


def surfaces(*bodies):
    return [b.surface(0.0, b.initial_state()) for b in bodies]


def test_the_law_between_two_spheres_is_equal_opposite_and_zero_beyond_the_range():
    law = Repulsion(range=0.5, force=2.0)
    direction = np.array([2.0, 1.0, -2.0]) / 3.0
    for gap in (0.0, 0.1, 0.3, 0.49):
        a, b = sphere((0.0, 0.0, 5.0)), sphere(tuple(np.array([0.0, 0.0, 5.0])
                                                     + (2.0 + gap) * direction))
        force, torque = repulsion_loads(surfaces(a, b), law)
        expected = 2.0 * (1.0 - gap / 0.5) ** 2
        np.testing.assert_allclose(force[1], expected * direction, rtol=1e-12)
        np.testing.assert_array_equal(force[0], -force[1])
        np.testing.assert_array_equal(torque, 0.0)  # through the centres
    for gap in (0.5, 0.7, 3.0):
        force, torque = repulsion_loads(surfaces(sphere((0, 0, 0)), sphere((2 + gap, 0, 0))), law)
        np.testing.assert_array_equal(force, 0.0)
    assert law.magnitude(0.25) == pytest.approx(0.5) and law.magnitude(0.5) == 0.0


def test_other_shapes_push_at_their_closest_points_with_a_torque():
    law = Repulsion(range=0.5, force=1.0)
    rod = RigidBody(shape=Spheroid(axial=3.0, radius=0.5, n_points=200), epsilon=0.3,
                    position=(0.0, 0.0, 0.0))
    other = dataclasses.replace(rod, position=(2.0, 1.2, 0.0))  # side by side, offset along x
    ball = sphere((-2.0, 0.0, 1.8))  # above the rod's left half
    s = surfaces(rod, other, ball)
    force, torque = repulsion_loads(s, law)
    np.testing.assert_allclose(force.sum(axis=0), 0.0, atol=1e-15)  # no net force
    assert force[1, 1] > 0 and force[2, 2] > 0  # pushed away from the rod
    # the rods are pushed at their closest points, off their centres: they turn
    assert np.linalg.norm(torque[1]) > 0.1 * np.linalg.norm(force[1])
    np.testing.assert_array_equal(torque[2], 0.0)  # the sphere: through its centre
    # the sphere's push: along the line from the rod's closest point through its centre
    d = s[2].center - s[0].points
    closest = np.linalg.norm(d, axis=1).argmin()
    gap = np.linalg.norm(d[closest]) - 1.0
    assert 0 < gap < 0.5
    np.testing.assert_allclose(force[2], law.magnitude(gap) * d[closest] / (gap + 1.0),
                               rtol=1e-12)


def test_the_wall_pushes_up_at_the_lowest_point():
    law = Repulsion(range=0.5, force=3.0)
    force, torque = repulsion_loads(surfaces(sphere((0.0, 0.0, 1.2)), sphere((5.0, 0.0, 1.6))),
                                    law, wall=True)
    np.testing.assert_array_equal(torque, 0.0)
    np.testing.assert_allclose(force[0], [0.0, 0.0, 3.0 * (1 - 0.2 / 0.5) ** 2], rtol=1e-12)
    np.testing.assert_array_equal(force[1], 0.0)
    force, _ = repulsion_loads(surfaces(sphere((0.0, 0.0, 1.2))), law, wall=False)
    np.testing.assert_array_equal(force, 0.0)


def test_only_near_pairs_are_looked_at(monkeypatch):
    calls = []
    closest = repulsion_module._closest
    monkeypatch.setattr(repulsion_module, "_closest",
                        lambda i, j, *rest: calls.append((i, j)) or closest(i, j, *rest))
    grid = [(2.3 * i, 2.3 * j, 2.3 * k) for i in range(4) for j in range(4) for k in range(4)]
    bodies = [sphere(p, n=12, epsilon=0.4) for p in grid]
    force, _ = repulsion_loads(surfaces(*bodies), Repulsion(0.5, 1.0))
    assert len(calls) == 3 * 4 * 4 * 3  # the lattice's neighbours, not its 2016 pairs
    assert calls == sorted(calls)  # in a fixed order: the same sums at every call
    np.testing.assert_allclose(force.sum(axis=0), 0.0, atol=1e-13)


def test_bad_values_are_refused():
    for bad in (0.0, -1.0, float("inf"), float("nan"), True):
        with pytest.raises(ValueError, match=r"repulsion\.range: must be a finite number > 0"):
            Repulsion(range=bad, force=1.0)
        with pytest.raises(ValueError, match=r"repulsion\.force: must be a finite number > 0"):
            Repulsion(range=1.0, force=bad)
    with pytest.raises(ValueError, match="repulsion: a Repulsion"):
        Scene((sphere((0, 0, 0)),), viscosity=MU, repulsion=(0.5, 1.0))


def test_far_apart_the_rates_are_the_same_bits_and_close_they_differ():
    a, b = sphere((0.0, 0.0, 0.0), force=(1.0, 0.0, 0.0)), sphere((2.6, 0.0, 0.0))
    plain = Scene((a, b), viscosity=MU)
    pushed = dataclasses.replace(plain, repulsion=Repulsion(0.5, 1.0))
    x = plain.initial_state()
    np.testing.assert_array_equal(plain.rates(0.0, x), pushed.rates(0.0, x))
    close = dataclasses.replace(pushed, bodies=(a, sphere((2.4, 0.0, 0.0))))
    x = close.initial_state()
    free = dataclasses.replace(close, repulsion=None).rates(0.0, x)
    assert close.rates(0.0, x)[0, 0] < free[0, 0] - 0.01  # held back by b


def test_the_coarse_scene_has_the_same_repulsion_and_the_same_loads():
    scene = Scene((sphere((0.0, 0.0, 0.0)), sphere((2.3, 0.0, 0.3))), viscosity=MU,
                  repulsion=Repulsion(0.5, 1.0))
    coarse, transfer = scene.coarsened(3)
    assert coarse.repulsion == scene.repulsion
    x = scene.initial_state()
    fine_loads = repulsion_loads(surfaces(*scene.bodies), scene.repulsion)
    xc = transfer.restrict(x)
    coarse_surfaces = [body.surface(0.0, block) for body, block in
                       zip(coarse.bodies, coarse.blocks(xc), strict=True)]
    coarse_loads = repulsion_loads(coarse_surfaces, coarse.repulsion)
    np.testing.assert_array_equal(fine_loads[0], coarse_loads[0])
    assert np.abs(fine_loads[0]).max() > 0


def test_two_spheres_pushed_together_settle_where_the_repulsion_balances_the_push():
    """Equal and opposite pushes P bring two spheres together until F0 (1 - h/δ)² = P: with
    F0 = 9 P, δ = 0.6, at h = 0.4 (their relative velocity then vanishes)."""
    push, law = 1.0, Repulsion(range=0.6, force=9.0)
    scene = Scene((sphere((0.0, 0.0, 0.0), n=100, force=(push, 0.0, 0.0)),
                   sphere((2.55, 0.0, 0.0), n=100, force=(-push, 0.0, 0.0))),
                  viscosity=MU, repulsion=law)
    x, dt = scene.initial_state(), 0.1
    for _ in range(40):
        k1 = scene.rates(0.0, x)
        x = scene.advance(x, 0.5 * (k1 + scene.rates(0.0, scene.advance(x, k1, dt))), dt)
    gap = np.linalg.norm(x[0, :3] - x[101, :3]) - 2.0
    rates = scene.rates(0.0, x)
    approach = rates[0, 0] - rates[101, 0]
    assert gap == pytest.approx(0.6 * (1.0 - (push / 9.0) ** 0.5), abs=2e-3)
    assert abs(approach) < 1e-3
    without = dataclasses.replace(scene, repulsion=None)
    assert without.rates(0.0, x)[0, 0] > 0.05  # the push alone keeps closing the gap


CLOUD = """
title = "a CI-sized cloud"
[scene]
viscosity = 0.05305164769729845   # 1 / 6 pi: a sphere alone falls at 1
{repulsion}
[[suspensions]]
name = "s"
placement = "random"
region = "sphere"
radius = 6.0
center = [0.0, 0.0, 0.0]
count = 30
seed = 1
""" + SPHERE.strip("\n") + """
[time]
t1 = {t1}
[fine]
scheme = "rk2"
dt = 0.1
[coarse]
scheme = "euler"
dt_ratio = 2
[parareal]
n_slices = 1
[run]
mode = "serial"
"""
REPULSION = "repulsion = { range = 0.5, force = 4.0 }"


def test_a_scene_repulsion_loads_builds_and_round_trips():
    cfg, _ = config.loads(CLOUD.format(repulsion=REPULSION, t1=1.0))
    scene = cfg.model.build()
    assert scene.repulsion == Repulsion(0.5, 4.0)
    assert cfg.model.tables()["scene"]["repulsion"] == {"range": 0.5, "force": 4.0}
    cfg, _ = config.loads(CLOUD.format(repulsion="", t1=1.0))
    assert cfg.model.build().repulsion is None and "repulsion" not in cfg.model.tables()["scene"]


@pytest.mark.parametrize("value, key, fragment", [
    ("{ range = -0.5, force = 4.0 }", "scene.repulsion.range", "greater than 0"),
    ("{ range = 0.5, force = inf }", "scene.repulsion.force", "finite"),
    ("{ range = 0.5 }", "scene.repulsion.force", "missing"),
    ("{ range = 0.5, force = 4.0, strength = 1.0 }", "scene.repulsion.strength", ""),
    ("0.5", "scene.repulsion", ""),
])
def test_bad_repulsion_tables_are_named(value, key, fragment):
    with pytest.raises(ConfigError) as info:
        config.loads(CLOUD.format(repulsion=f"repulsion = {value}", t1=1.0))
    found = dict(info.value.issues)
    assert key in found and fragment in found[key].lower(), found


def _fall(repulsion: str, t1: float) -> np.ndarray:
    cfg, resolved = config.loads(CLOUD.format(repulsion=repulsion, t1=t1))
    setup = build(cfg, resolved)
    return setup.fine(0.0, t1, setup.system.initial_state())


def _closest_centres(x: np.ndarray, count: int = 30, rows: int = 43) -> float:
    c = x[::rows][:count, :3]
    d = np.linalg.norm(c[:, None] - c[None], axis=-1)
    np.fill_diagonal(d, np.inf)
    return float(d.min())


def test_a_cloud_runs_with_the_repulsion_past_where_it_was_refused():
    """30 spheres in R = 6a: without the repulsion two surfaces come within half their spacing
    between t = 1.5 and 2 a/U₀ (the slow test below); with it the cloud falls past 2.5."""
    x = _fall(REPULSION, 2.5)
    assert np.isfinite(x).all() and x[0, 2] < -3.0  # it fell
    assert _closest_centres(x) > 2.25  # held apart (surfaces over 0.25a apart)


@pytest.mark.slow
def test_without_the_repulsion_the_cloud_is_refused_before_two():
    with pytest.raises((ValueError, SolveError), match="overlap or touch"):
        _fall("", 2.0)


@pytest.mark.slow
def test_the_quick_cloud_runs_to_five_with_its_repulsion():
    """The shipped cloud's serial solution (its fine solver, the quick variant's placement) to
    t = 5 a/U₀; without the repulsion it is refused before 1.75."""
    cfg, resolved = config.load("experiments/quick/cloud_sediments.toml", ["time.t1=5.0"])
    setup = build(cfg, resolved)
    x = setup.fine(0.0, 5.0, setup.system.initial_state())
    assert _closest_centres(x, 100) > 2.2
