"""The compiled loops of scenes (parastokes/scene/compiled.py) and of the chain
(parastokes/kinds/chain/stepping.py): chosen by the exact types involved, and equal to the Python
loop bit for bit.

Bit for bit, not to rounding: both loops run the same compiled functions on the same inputs in the
same order (the bodies' mechanics, one kernel call over all points with ε per source, the
background flow added as ``Scene.rates`` adds it, the tableau combined as ``integrate`` combines
it, no fused multiply-add outside the kernels), so any difference is a bug in the composition."""

from __future__ import annotations

import dataclasses
from typing import ClassVar

import numpy as np
import pytest
from user_body import SedimentingCloud

from parastokes import integrate, models, mrs
from parastokes.kinds.chain import ChainSystem
from parastokes.parallel import make_executor
from parastokes.parallel.spatial import TargetBlocks
from parastokes.registry import loops as registry
from parastokes.scene import Scene
from parastokes.testing import check_system

MU, SHEAR = 1e-3, 0.2


def rod(**kw):
    """A short swimmer above the wall (travelling wave of eq. 36)."""
    return models.rod_swimmer(1, 21, kw.pop("epsilon", 1.0), length=6.0, wavelength=3.0,
                              viscosity=MU, height=kw.pop("height", 3.0), **kw)


def vesicle():
    return dataclasses.replace(models.vesicle(1, shear_rate=SHEAR, viscosity=MU),
                               center=(3.0, 2.5, 3.0))


def chain(**kw):
    return ChainSystem(**(dict(n_beads=8, stiffness=0.02, bending=0.002, viscosity=MU,
                               shear_rate=SHEAR, wall=True, height=5.0, epsilon=0.3,
                               load=(0.0, 0.0, -0.002)) | kw))


SCENES = {
    "rod+vesicle": lambda: Scene((rod(), vesicle()), viscosity=MU, wall=True, shear_rate=SHEAR),
    "rod+chain": lambda: Scene((rod(), chain()), viscosity=MU, wall=True, shear_rate=SHEAR),
    "two rods": lambda: Scene((rod(), rod(epsilon=0.6, height=5.0, frequency=-30.0)),
                              viscosity=MU, wall=True, shear_rate=SHEAR),
}


def active(scene: Scene) -> np.ndarray:
    """The initial state with every point body stretched (and chains bent), so that its springs
    (and bending) pull."""
    x = scene.initial_state()
    for body, (first, rows, _) in zip(scene.bodies, scene.shapes, strict=True):
        points = x[first : first + rows, :3]
        if not body.angular:
            centre = points.mean(axis=0)
            points[:] = (points - centre) * [1.02, 1.0, 1 / 1.02] + centre
        if isinstance(body, ChainSystem):
            points[:, 2] += 0.2 * np.sin(np.linspace(0.0, np.pi, rows))
    return x


def assert_same_runs(system, x, dt, n, scheme):
    a = integrate.run(system, x, 0.0, n * dt, scheme, dt, compiled=True)
    b = integrate.run(system, x, 0.0, n * dt, scheme, dt, compiled=False)
    np.testing.assert_array_equal(a.state, b.state)
    assert a.max_monitor == b.max_monitor and a.n_steps == b.n_steps == n


@pytest.mark.parametrize("scheme", sorted(integrate.SCHEMES))
@pytest.mark.parametrize("name", sorted(SCENES))
def test_a_scenes_compiled_loop_gives_the_python_loops_bits(name, scheme):
    scene = SCENES[name]()
    assert registry.compiled_loop(scene) is not None
    assert_same_runs(scene, active(scene), 1e-4, 6, scheme)


@pytest.mark.parametrize("scheme", sorted(integrate.SCHEMES))
@pytest.mark.parametrize("wall", [False, True], ids=["free", "wall"])
def test_the_chains_compiled_loop_gives_the_python_loops_bits(wall, scheme):
    """Free space (free_u_f) and the wall (the full kernel, no torques), with shear and load."""
    system = chain(wall=wall, stiffness=20.0, bending=2.0, viscosity=1.0, shear_rate=1.0,
                   load=(0.1, 0.0, -0.3))
    x = system.initial_state()
    x[:, 2] += 0.3 * np.sin(np.linspace(0.0, np.pi, len(x)))
    assert registry.compiled_loop(system) is not None
    assert_same_runs(system, x, 0.01, 20, scheme)


def test_a_mixed_scene_with_a_chain_keeps_the_contract():
    """check_system on a rod and a chain above the wall: shapes, Θ, pickling, the compiled loop
    against the Python loop for every scheme, and the fitted orders through the compiled loop."""
    scene = SCENES["rod+chain"]()
    check_system(scene, active(scene), horizon=2e-3)


def test_the_fluid_is_evaluated_once_per_stage_over_all_points(monkeypatch):
    scene = Scene((rod(), vesicle(), chain()), viscosity=MU, wall=True, shear_rate=SHEAR)
    calls = []
    real = mrs.velocity

    def counted(*args, **kwargs):
        calls.append(np.shape(kwargs["epsilon"]))
        return real(*args, **kwargs)

    monkeypatch.setattr(mrs, "velocity", counted)
    scene.rates(0.0, scene.initial_state())
    assert calls == [(len(scene.initial_state()),)]  # one call, one ε per point


@dataclasses.dataclass(frozen=True)
class SceneCloud(SedimentingCloud):
    """The user's body of docs/extending.md with what a scene asks of a body (Python only)."""

    angular: ClassVar[bool] = False

    def loads(self, t, state):
        forces = np.zeros_like(state)
        forces[:, 2] = -self.weight
        return forces, None

    @staticmethod
    def body_rates(u, w):
        return u


def test_the_compiled_loop_is_chosen_by_the_exact_types_never_inherited():
    """A scene with a body that has no compiled parts (a user's Python body, a subclass of a
    body that has them) runs the Python loop, and so does such a body alone; the scene still
    steps, through its Python methods."""

    @dataclasses.dataclass(frozen=True)
    class HeavierChain(ChainSystem):
        def forces(self, state):
            return 2.0 * super().forces(state)

    cloud = SceneCloud(n_points=6, viscosity=MU, weight=1e-4)
    heavier = HeavierChain(n_beads=6, stiffness=0.02, bending=0.002, viscosity=MU,
                           shear_rate=SHEAR, height=8.0)
    for other in (cloud, heavier):
        scene = Scene((chain(wall=False), other), viscosity=MU, shear_rate=SHEAR)
        assert registry.compiled_loop(scene) is None
        result = integrate.run(scene, scene.initial_state(), 0.0, 0.02, "rk2", 0.01)
        assert np.isfinite(result.state).all() and result.n_steps == 2
    assert registry.compiled_loop(heavier) is None
    assert registry.compiled_loop(chain()) is not None
    with make_executor("serial") as executor:  # the blocked fluid has no compiled loop
        blocked = chain(target_blocks=TargetBlocks(executor, 2))
        assert registry.compiled_loop(blocked) is None


@pytest.mark.parametrize("torqued", ["none", "zero", "random"])
def test_the_compiled_fluid_takes_torques_of_bodies_without_angular_rates(torqued):
    # Scene.rates passes the torques of a body whose rates have no w to mrs.velocity (they drive
    # the fluid); the compiled loops' fluid must take them too, bit for bit, and keep the
    # force-only kernel when there are none or all are zero (regression: mrs.velocity took the
    # full kernel for zero torques, the compiled fluid the force-only one; bits differed)
    from parastokes.fluid.compiled import fluid_workspace, velocity_into
    from parastokes.mrs import compiled
    from parastokes.mrs.velocity import EIGHT_PI

    rng = np.random.default_rng(3)
    x = rng.normal(size=(17, 3))
    forces = rng.normal(size=(17, 3))
    torques = {"none": None, "zero": np.zeros((17, 3)), "random": rng.normal(size=(17, 3))}[torqued]
    starts = compiled.tile_starts(compiled.padded_size(17), 1)
    work = fluid_workspace(17, starts[-1])
    work[2][0] = forces
    if torques is not None:
        work[3][0] = torques
    velocity_into(x, work, np.full(1, 0.3), np.full(1, EIGHT_PI * MU), starts, False, False,
                  False)
    expected = mrs.velocity(x, x, forces, epsilon=0.3, mu=MU, torques=torques, n_threads=1)
    np.testing.assert_array_equal(work[4][0], expected)
