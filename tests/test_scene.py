"""Scenes (parastokes/scene/): several bodies of any kinds in one fluid, as one system."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from parastokes import integrate, models, mrs, parareal
from parastokes.kinds.chain import ChainSystem
from parastokes.scene import Scene
from parastokes.testing import check_system


def swimmer():
    return models.rod_swimmer(1, 31, 1.0, length=6.0, wavelength=3.0)


@pytest.mark.parametrize(
    "body",
    [swimmer(), models.vesicle(subdivisions=1, shear_rate=0.3),
     ChainSystem(n_beads=6, shear_rate=0.5, stretch=1.2, wall=True, height=3.0)],
    ids=["rod", "vesicle", "chain"],
)
def test_a_scene_of_one_body_is_that_body_bit_for_bit(body):
    scene = Scene((body,), viscosity=body.viscosity, wall=getattr(body, "wall", False),
                  shear_rate=getattr(body, "shear_rate", 0.0))
    x0 = body.initial_state()
    np.testing.assert_array_equal(scene.initial_state(), x0)
    np.testing.assert_array_equal(scene.rates(0.01, x0), body.rates(0.01, x0))
    dt = 1e-6 if body.viscosity < 1e-3 else 1e-3
    np.testing.assert_array_equal(integrate.propagate(scene, x0, 0.0, 5 * dt, "rk4", dt),
                                  integrate.propagate(body, x0, 0.0, 5 * dt, "rk4", dt))


def test_a_mixed_scene_keeps_the_system_contract():
    chain = ChainSystem(n_beads=8, stiffness=0.02, bending=0.002, viscosity=1e-3,
                        shear_rate=0.1, height=4.0, stretch=1.05)
    vesicle = models.vesicle(subdivisions=1, shear_rate=0.1)
    scene = Scene((chain, vesicle), viscosity=1e-3, shear_rate=0.1)
    assert scene.names == ("chain", "vesicle")
    assert set(scene.params) == {"viscosity", "chain.epsilon", "chain.stiffness",
                                 "chain.bending", "vesicle.epsilon", "vesicle.stiffness"}
    x = scene.initial_state()
    x[: chain.n_beads, 2] += 0.2 * np.sin(np.linspace(0, np.pi, chain.n_beads))
    x[chain.n_beads :] *= [1.02, 1.0, 1 / 1.02]  # a stretched vesicle: its springs pull
    check_system(scene, x, horizon=0.02)


def sedimenting_pair(distance: float) -> tuple[float, float]:
    """Mean fall speed of a chain alone, and of the same chain with a twin ``distance`` above."""
    low = ChainSystem(n_beads=5, bending=0.0, load=(0.0, 0.0, -1.0))
    high = ChainSystem(n_beads=5, bending=0.0, load=(0.0, 0.0, -1.0), height=distance)
    alone = -low.rates(0.0, low.initial_state())[:, 2].mean()
    scene = Scene((low, high), viscosity=1.0)
    together = -scene.rates(0.0, scene.initial_state())[:5, 2].mean()
    return alone, together


def test_bodies_interact_through_the_fluid_and_far_apart_as_stokeslets():
    """A twin above a sedimenting chain drags it down faster; far away, the extra speed is the
    twin's Stokeslet, F_tot 2 / (8πμ d) along the line joining them."""
    for distance in (40.0, 80.0):
        alone, together = sedimenting_pair(distance)
        assert together > alone
        stokeslet = 5 * 2 / (8 * np.pi * distance)
        assert together - alone == pytest.approx(stokeslet, rel=0.01)


def test_parareal_extrapolates_in_any_bodys_parameter():
    chain = ChainSystem(n_beads=6, stiffness=20.0, bending=2.0, shear_rate=1.0, stretch=1.2)
    other = ChainSystem(n_beads=6, stiffness=20.0, bending=2.0, shear_rate=1.0, height=2.0,
                        tilt=0.5)
    scene = Scene((chain, other), viscosity=1.0, shear_rate=1.0)
    assert scene.names == ("chain0", "chain1")
    assert scene.with_params(**{"chain1.stiffness": 18.0}).bodies[1].stiffness == 18.0
    assert scene.with_params(viscosity=2.0).bodies[0].viscosity == 2.0
    fine = integrate.Propagator(scene, "rk2", 0.002)
    coarse = parareal.extrapolated(scene, "euler", 0.02, lagrange={"chain0.stiffness": [16, 18]},
                                   richardson={"m": 1, "r": 0.5})
    # the auxiliary scenes vary the first chain's stiffness only, at the Richardson steps
    varied = [[(p.system.bodies[0].stiffness, p.system.bodies[1].stiffness, p.dt) for p in row]
              for row in coarse.auxiliary]
    assert varied == [[(16.0, 20.0, 0.02), (16.0, 20.0, 0.01)],
                      [(18.0, 20.0, 0.02), (18.0, 20.0, 0.01)]]
    x0 = scene.initial_state()
    reference = parareal.serial_solution(fine, x0, 0.0, 0.4, 8)
    errors = {}
    for name, solver in (("extrapolated", coarse),
                         ("plain", integrate.Propagator(scene, "euler", 0.02))):
        res = parareal.run(fine, solver, x0, 0.0, 0.4, 8, tol=0.0, max_iterations=2,
                           reference=reference)
        errors[name] = res.errors
    # eq. 30 with these weights beats its plain member by far (measured: 3.7e-8 against 7.4e-5)
    assert errors["extrapolated"][0] < 1e-2 * errors["plain"][0]
    assert errors["extrapolated"][1] < errors["extrapolated"][0]


def test_bad_scenes_are_named():
    with pytest.raises(ValueError, match=r"vesicle\.shear_rate"):
        Scene((models.vesicle(1, shear_rate=0.1),), viscosity=1e-3, shear_rate=0.0)
    with pytest.raises(ValueError, match="viscosity"):
        Scene((swimmer(),), viscosity=1.0, wall=True)
    with pytest.raises(ValueError, match="unknown parameter"):
        Scene((swimmer(),), viscosity=1e-6, wall=True).with_params(epsilon=2.0)
    body = ChainSystem(n_beads=4)
    for names in (("a.b",), ("",)):
        with pytest.raises(ValueError, match=r"without '\.'"):
            Scene((body,), viscosity=body.viscosity, names=names)


@dataclasses.dataclass(frozen=True)
class _Points:
    """A System of points that cannot join a scene (no loads, angular, body_rates, epsilon)."""

    viscosity: float = 1.0

    @property
    def params(self):
        return {}


class _FixedViscosity(ChainSystem):
    """A chain whose viscosity is not a parameter: the scene could not vary it."""

    @property
    def params(self):
        return {k: v for k, v in super().params.items() if k != "viscosity"}


def test_a_body_that_cannot_join_a_scene_is_named_when_the_scene_is_made():
    body = _FixedViscosity(n_beads=4)
    with pytest.raises(ValueError, match="viscosity is not among its params"):
        Scene((body,), viscosity=body.viscosity)
    # regression: such a scene was made, and its first step failed with an AttributeError
    with pytest.raises(ValueError, match="lacks loads, angular, body_rates, epsilon"):
        Scene((_Points(),), viscosity=1.0)


def test_a_swimmer_beside_a_vesicle_above_the_wall_keeps_the_contract():
    """The issue's scene in miniature: a beating rod (forces, torques, frames) and a vesicle
    (forces only) above the wall, coupled through the wall's image systems."""
    rod = models.rod_swimmer(1, 31, 1.0, length=6.0, wavelength=3.0, viscosity=1e-3, height=3.0)
    vesicle = dataclasses.replace(models.vesicle(subdivisions=1, shear_rate=0.0, viscosity=1e-3),
                                  center=(3.0, 2.5, 3.0))
    scene = Scene((rod, vesicle), viscosity=1e-3, wall=True)
    x = scene.initial_state()
    np.testing.assert_allclose(x[31:, :3].mean(axis=0), [3.0, 2.5, 3.0], atol=1e-14)
    x[31:, :3] = (x[31:, :3] - [3.0, 2.5, 3.0]) * [1.02, 1.0, 1 / 1.02] + [3.0, 2.5, 3.0]
    check_system(scene, x, horizon=2e-3)
    # the vesicle feels the rod: its rates differ from its rates alone
    alone = vesicle.rates(0.0, x[31:, :3])
    assert np.abs(scene.rates(0.0, x)[31:, :3] - alone).max() > 1e-3 * np.abs(alone).max()


class _TwistingChain(ChainSystem):
    """A chain that also exerts a torque at every bead, though its rates have no w."""

    def loads(self, t, state):
        forces, _ = super().loads(t, state)
        return forces, np.tile([0.0, 0.3, 1.0], (len(state), 1))


def test_torques_of_a_body_without_angular_rates_drive_the_fluid():
    # regression: Scene.rates allocated the torques only when some body's rates have w, and
    # indexed None (TypeError) for a body that gives torques but is not angular
    body = _TwistingChain(n_beads=5, stretch=1.2)
    scene = Scene((body,), viscosity=body.viscosity)
    x = scene.initial_state()
    forces, torques = body.loads(0.0, x)
    expected = mrs.velocity(x, x, forces, epsilon=body.epsilon, mu=body.viscosity,
                            torques=torques)
    np.testing.assert_allclose(scene.rates(0.0, x), expected, rtol=1e-12, atol=1e-15)
    assert not np.allclose(expected, body.rates(0.0, x))  # the torques do move the fluid


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "python"])
@pytest.mark.parametrize("in_scene", [False, True], ids=["chain", "scene"])
def test_a_body_driven_through_the_wall_is_a_blow_up(compiled, in_scene):
    """The images hold for z > 0 only: a step that puts a point on or below the wall is named
    a blow-up by both loops (regression: the run went on with meaningless velocities)."""
    chain = ChainSystem(n_beads=4, wall=True, height=0.3, load=(0.0, 0.0, -20.0), epsilon=0.25)
    system = Scene((chain,), viscosity=chain.viscosity, wall=True) if in_scene else chain
    x0 = system.initial_state()
    with pytest.raises(integrate.BlowUpError, match="reached the wall z = 0") as info:
        integrate.run(system, x0, 0.0, 1.0, "euler", 0.5, compiled=compiled)
    assert info.value.monitor == np.inf and np.all(info.value.last_state[:, 2] > 0)


def test_a_rod_node_on_the_wall_makes_the_monitor_infinite():
    rod = swimmer()
    assert rod.wall
    x = rod.initial_state()
    assert np.isfinite(rod.monitor(x))
    x[3, 2] = 0.0
    assert rod.monitor(x) == np.inf


def test_a_scene_refuses_a_body_below_its_wall():
    with pytest.raises(ValueError, match="on or below the wall"):
        Scene((models.vesicle(1, shear_rate=0.1),), viscosity=1e-3, wall=True, shear_rate=0.1)
