"""Rigid bodies in scenes (parastokes/scene/): one coupled solve per evaluation, the flow of
the explicit bodies as the rigid surfaces' background, the solved surface forces driving the
explicit bodies; and the checks that refuse overlapping bodies and bad configurations."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from configs import SERIAL_SOLVERS

from parastokes import cli, config
from parastokes.bodies.sources import FluidSources, fluid_sources
from parastokes.kinds.chain import ChainSystem
from parastokes.kinds.rigid import RigidBody, Sphere, Squirmer
from parastokes.kinds.rigid.kind import SQUIRMER_MIN_POINTS
from parastokes.kinds.rigid.shapes import spacing
from parastokes.scene import Scene


def sphere(position, n=60, **kw):
    return RigidBody(shape=Sphere(1.0, n), epsilon=0.3, position=position, **kw)


def test_a_scene_of_one_rigid_body_is_that_body_bit_for_bit():
    body = sphere((0.0, 0.0, 2.0), slip=Squirmer(1.0, 1.0), wall=True, shear_rate=0.5,
                  force=(0.1, 0.0, -1.0))
    scene = Scene((body,), viscosity=1.0, wall=True, shear_rate=0.5)
    x = scene.initial_state()
    np.testing.assert_array_equal(x, body.initial_state())
    np.testing.assert_array_equal(scene.rates(0.3, x), body.rates(0.3, x))


@dataclasses.dataclass(frozen=True)
class GivenForces:
    """An explicit body: fixed points that exert given forces and move with the fluid."""

    points: np.ndarray
    forces: np.ndarray
    epsilon: float = 0.3
    viscosity: float = 1.0
    angular = False

    def initial_state(self):
        return np.array(self.points)

    def loads(self, t, state):
        return self.forces, None

    @staticmethod
    def body_rates(u, w):
        return u

    @property
    def params(self):
        return {"epsilon": self.epsilon, "viscosity": self.viscosity}


def test_the_coupled_solve_is_consistent_with_the_explicit_forces_it_finds():
    """Two sedimenting spheres solved together; then the second replaced by an explicit body
    exerting exactly the surface forces the solve found for it: the first sphere moves as
    before, and the explicit points move as the second sphere's rigid motion."""
    a = sphere((0.0, 0.0, 0.0), force=(0.0, 0.0, -1.0))
    b = sphere((2.6, 0.4, 0.3), force=(0.5, 0.0, -2.0), torque=(0.0, 0.3, 0.0))
    both = Scene((a, b), viscosity=1.0)
    x = both.initial_state()
    rates = both.rates(0.0, x)
    sources = fluid_sources(both, 0.0, x)
    assert isinstance(sources, FluidSources)
    fb = sources.forces[len(a.initial_state()) - 1 :]  # a's 60 surface rows, then b's
    np.testing.assert_allclose(fb.sum(axis=0), b.force, atol=1e-10)
    xb = b.initial_state()
    explicit = GivenForces(xb[1:, :3], fb)
    mixed = Scene((a, explicit), viscosity=1.0)
    y = mixed.initial_state()
    mixed_rates = mixed.rates(0.0, y)
    np.testing.assert_allclose(mixed_rates[0, :6], rates[0, :6], rtol=1e-9, atol=1e-12)
    u, omega = rates[61, :3], rates[61, 3:6]
    rigid = u + np.cross(omega, xb[1:, :3] - xb[0, :3])
    np.testing.assert_allclose(mixed_rates[61:, :3], rigid, rtol=1e-8, atol=1e-10)


def test_two_spheres_fall_faster_together_than_apart():
    """Side by side, two sedimenting spheres drag each other along (Stokes flow)."""
    weight = (0.0, 0.0, -6 * math.pi)
    alone = sphere((0.0, 0.0, 0.0), force=weight)
    u_alone = alone.rates(0.0, alone.initial_state())[0, 2]
    pair = Scene((alone, sphere((3.0, 0.0, 0.0), force=weight)), viscosity=1.0)
    u_pair = pair.rates(0.0, pair.initial_state())[0, 2]
    # far-field estimate: the other sphere's Stokeslet adds (3/4)(a/d) U at distance d = 3a
    assert u_pair / u_alone == pytest.approx(1 + 0.75 / 3.0, rel=0.05)


def test_overlapping_bodies_are_named():
    with pytest.raises(ValueError, match=r"rigidbody0 and rigidbody1 overlap: one lies inside"):
        Scene((sphere((0, 0, 0)), sphere((0.5, 0, 0))), viscosity=1.0)
    chain = ChainSystem(n_beads=4, height=0.0)
    with pytest.raises(ValueError, match=r"chain and rigidbody overlap"):
        Scene((chain, sphere((0.0, 0.0, 0.0))), viscosity=1.0)


def test_check_rejects_bad_rigid_bodies_before_the_run(tmp_path, capsys):
    base = SERIAL_SOLVERS
    cases = {
        "coarse": ('[model]\nkind = "rigid"\nn_points = 40\nepsilon = 0.01\n'
                   'epsilon_unit = "absolute"\n', "too coarse for ε = 0.01"),
        "below": ('[model]\nkind = "squirmer"\nwall = true\nposition = [0, 0, 0.5]\n',
                  "raise position[2]"),
        "singular": ('[model]\nkind = "rigid"\nshape = "points"\n'
                     'points = "test_rigid_scene:collinear"\n',
                     "rigid: the mobility system is singular"),
        "overlap": ('[scene]\nviscosity = 1.0\n[[bodies]]\nkind = "squirmer"\n'
                    '[[bodies]]\nkind = "rigid"\nposition = [1.0, 0, 0]\n',
                    "squirmer and rigid overlap"),
    }
    for name, (model, message) in cases.items():
        path = tmp_path / f"{name}.toml"
        path.write_text(model + base)
        with pytest.raises(config.ConfigError) as error:
            config.load(path)
        assert message in str(error.value), (name, str(error.value))
    good = tmp_path / "good.toml"
    good.write_text('[model]\nkind = "squirmer"\nn_points = 60\n' + base)
    assert cli.main(["check", str(good)]) == 0
    assert "squirmer, 61 points" in capsys.readouterr().out


def test_a_squirmer_with_too_few_points_is_refused_before_any_work(tmp_path, capsys):
    """A 4-point squirmer (its speed 16 % off Blake's, its direction off) is refused by check and
    run, exit 2, with one line naming the key and the minimum, before the run directory is made;
    the shipped squirmer passes."""
    few = tmp_path / "few.toml"
    few.write_text('[model]\nkind = "squirmer"\nn_points = 4\n' + SERIAL_SOLVERS)
    capsys.readouterr()
    for command in (["check", str(few)], ["run", str(few), "--out", str(tmp_path / "out")]):
        assert cli.main(command) == 2
        lines = [line for line in capsys.readouterr().err.splitlines() if "n_points" in line]
        assert len(lines) == 1
        assert ("model.n_points: a squirmer needs at least n_points = "
                f"{SQUIRMER_MIN_POINTS} surface points") in lines[0]
        assert "got 4" in lines[0]
    assert not (tmp_path / "out").exists()
    shipped = Path(__file__).resolve().parents[1] / "experiments" / "squirmer.toml"
    assert cli.main(["check", str(shipped)]) == 0


def test_the_squirmer_minimum_is_where_its_free_speed_starts_to_converge():
    """docs/validation.md, "A squirmer's fewest points" (ε = 0.5 h): below the minimum the
    free speed's error does not fall with more points and the surface's asymmetry drives a
    sideways speed of over 1 % of U (B2 = 2 B1); from the minimum on the error falls with N and
    the sideways speed is below 1 %."""
    def motion(n):
        shape = Sphere(1.0, n)  # the shipped ε rule: 0.5 x the largest gap
        body = RigidBody(shape=shape, slip=Squirmer(1.0, 2.0), epsilon=0.5 * spacing(shape))
        u = body.rates(0.0, body.initial_state())[0]
        return u[0] / (2.0 / 3.0) - 1.0, math.hypot(u[1], u[2]) / u[0]

    below = [motion(n) for n in (12, 20, 30)]
    at, double = motion(SQUIRMER_MIN_POINTS), motion(2 * SQUIRMER_MIN_POINTS)
    assert below[0][0] < below[1][0] < below[2][0]  # more points, a larger error
    assert max(side for _, side in below) > 0.01
    assert 0 < double[0] < at[0] < below[2][0]  # the error falls from the minimum on
    assert at[1] < 0.01 and double[1] < 0.01


def collinear():
    """Points on one line: they cannot resist a turn about it (a singular mobility system)."""
    return np.stack([np.linspace(0.0, 3.0, 20), np.zeros(20), np.zeros(20)], axis=1)


def test_the_flow_at_a_rigid_surface_is_its_prescribed_motion():
    """The flow field of the solved surface forces (parastokes.flow, from ``fluid_sources``)
    meets the no-slip condition: at every surface point it is U + Ω × r + the slip, for a
    squirmer above the wall in shear and for a sphere beside a chain in a scene; far away it
    decays."""
    from parastokes import flow

    body = sphere((0.0, 0.0, 2.0), slip=Squirmer(1.0, 2.0), wall=True, shear_rate=0.5,
                  force=(0.0, 0.0, -1.0), viscosity=1.0)
    x = body.initial_state()
    rates = body.rates(0.0, x)
    u = flow.velocity(body, x, x[1:, :3])
    np.testing.assert_allclose(u, rates[1:, :3], atol=1e-8)
    chain = ChainSystem(n_beads=6, height=3.0, load=(0.0, 0.0, -0.5))
    scene = Scene((chain, sphere((0.0, 0.0, 0.0), force=(0.0, 0.0, -1.0))), viscosity=1.0)
    y = scene.initial_state()
    r = scene.rates(0.0, y)
    np.testing.assert_allclose(flow.velocity(scene, y, y[7:, :3]), r[7:, :3], atol=1e-8)
    np.testing.assert_allclose(flow.velocity(scene, y, y[:6, :3]), r[:6, :3], atol=1e-12)


def test_the_quick_sphere_and_rod_scene_shows_the_sphere_sedimenting(tmp_path):
    """Its comment's physics: the sphere falls at most of its Stokes speed F / (6 pi mu a) in every
    frame interval (the wall and the rod's flow take the rest), rather than being carried up by the
    rod's switch-on flow as with the full run's force over so short a time."""
    import h5py

    path = Path(__file__).parents[1] / "experiments" / "quick" / "scene_sphere_and_rod.toml"
    cfg, _ = config.load(path)
    scene = cfg.model
    sphere_table = scene.bodies[scene.names.index("sphere")]
    stokes = -sphere_table.force[2] / (6 * math.pi * scene.viscosity * sphere_table.radius)
    assert cli.main(["run", str(path), "--out", str(tmp_path / "run"), "--set",
                     "run.mode=serial"]) == 0
    with h5py.File(tmp_path / "run" / "trajectory.h5") as f:
        t, z = f["serial/time"][:], f["serial/sphere_center/positions"][:, 0, 2]
    fall = -np.diff(z) / np.diff(t)
    assert len(fall) >= 4
    assert np.all((0.75 * stokes < fall) & (fall < stokes))
