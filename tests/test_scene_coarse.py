"""A scene on a coarser grid for the coarse solver (parastokes/scene/coarse.py, Remark 4):
every body that has a coarser grid is coarsened (a rigid sphere's surface, a rod's nodes), the
others are kept; the transfer composes the bodies' own and keeps a rigid body's pose exactly; the
coupling through the coarser sphere changes the rod's rates by a few per cent of the sphere's
effect on them; Parareal with the coarse grid converges to the serial fine solution, and the
process pool gives the serial executor's iterates bit for bit."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from configs import SERIAL_SOLVERS

from parastokes import config, integrate, models, parallel, parareal
from parastokes import run as runner
from parastokes.kinds.chain import ChainSystem
from parastokes.kinds.rigid import RigidBody, Sphere
from parastokes.scene import Scene

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"
N_SLICES = 4


@pytest.fixture(scope="module")
def quick_scene():
    """The sphere (150 points) and the rod (31 nodes) of the scene, the rod bent by 20 fine
    steps (the wave switched on), as a state of the fine scene."""
    cfg, _ = config.load(EXPERIMENTS / "scene_sphere_and_rod.toml")
    scene = cfg.model.build(1)
    x = integrate.propagate(scene, scene.initial_state(), 0.0, 2e-5, "rk2", 1e-6)
    return scene, x


def test_the_coarse_scene_coarsens_each_body_and_keeps_the_others():
    rod = models.rod_swimmer(1, 31, 1.0, length=6.0, wavelength=6.0)
    sphere = RigidBody(shape=Sphere(1.0, 40), epsilon=0.35, viscosity=rod.viscosity, wall=True,
                       position=(3.0, 2.5, 12.0))
    scene = Scene((rod, sphere), viscosity=rod.viscosity, wall=True, names=("rod", "sphere"))
    coarse, _ = scene.coarsened(2)
    assert coarse.bodies == (rod.coarsened(2)[0], sphere.coarsened(2)[0])
    assert coarse.names == scene.names and coarse.params == pytest.approx(scene.params, rel=1e-15)
    assert [rows for _, rows, _ in coarse.shapes] == [16, 1 + 20]
    alone = Scene((sphere,), viscosity=rod.viscosity, wall=True)  # a scene of one rigid body
    body = sphere.coarsened(2)[0]
    x = body.initial_state()
    np.testing.assert_array_equal(alone.coarsened(2)[0].rates(0.0, x), body.rates(0.0, x))
    chain = ChainSystem(n_beads=4, height=5.0, viscosity=rod.viscosity, wall=True)
    mixed, transfer = Scene((chain, sphere), viscosity=rod.viscosity, wall=True).coarsened(3)
    assert mixed.bodies[0] is chain and transfer.transfers[0] is None
    with pytest.raises(ValueError, match=r"none of the scene's bodies \(chain\) has a coarser"):
        Scene((chain,), viscosity=rod.viscosity, wall=True).coarsened(2)
    with pytest.raises(ValueError, match=r"^rod: factor: 7 must divide n_points - 1 = 30"):
        scene.coarsened(7)
    with pytest.raises(ValueError, match="positive integer"):
        scene.coarsened(0)
    only = dataclasses.replace(scene, coarse_bodies=("sphere",))
    coarse, transfer = only.coarsened(7)  # the rod kept: 7 need not divide its segments
    assert coarse.bodies[0] is rod and transfer.transfers[0] is None
    assert coarse.bodies[1] == sphere.coarsened(7)[0]
    with pytest.raises(ValueError, match=r"coarse_bodies: no body is named 'ball'; the bodies: "):
        dataclasses.replace(scene, coarse_bodies=("ball",))
    with pytest.raises(ValueError, match=r"coarse_bodies: chain has no coarser grid"):
        Scene((chain, sphere), viscosity=rod.viscosity, wall=True, coarse_bodies=("chain",))


def test_a_scene_config_with_a_grid_factor_resolves_the_coarse_rows():
    quick = EXPERIMENTS / "scene_sphere_and_rod.toml"
    _, resolved = config.load(quick, ["coarse.grid_factor=2"])
    assert (resolved.n_points, resolved.coarse_points) == (31 + 151, 16 + 76)
    cfg, resolved = config.load(quick, ["coarse.grid_factor=3",
                                        "scene.coarse_bodies=['sphere']"])
    assert resolved.coarse_points == 31 + 51 and cfg.model.build().coarse_bodies == ("sphere",)
    dumped = {k: v for k, v in cfg.model_dump(mode="json", exclude_none=True).items()
              if k != "model"} | cfg.model.tables()  # as the tuner writes a configuration
    assert config.parse(dumped).model.coarse_bodies == ["sphere"]
    plain, _ = config.load(quick)  # the same fine problem: the serial solution can be shared
    assert runner.fine_identity(cfg) == runner.fine_identity(plain)
    assert runner.identity(cfg) != runner.identity(plain)
    cases = {
        "coarse.grid_factor=7": ("coarse.grid_factor", "rod: factor: 7 must divide"),
        "scene.coarse_bodies=['ball']": ("scene.coarse_bodies", "no body is named 'ball'"),
    }
    for override, (where, message) in cases.items():
        with pytest.raises(config.ConfigError) as error:
            config.load(quick, [override])
        assert (where, message) in [(w, m[: len(message)]) for w, m in error.value.issues]
    def vesicle(subdivisions: int) -> str:
        return (f'[scene]\nviscosity = 1e-3\n[[bodies]]\nkind = "vesicle"\n'
                f"subdivisions = {subdivisions}\n"
                + SERIAL_SOLVERS.replace("dt_ratio = 2\n", "dt_ratio = 2\ngrid_factor = 2\n"))

    config.loads(vesicle(1))  # a vesicle has the icosphere one level coarser (round 5)
    with pytest.raises(config.ConfigError, match=r"coarse.grid_factor: vesicle: must be a power "
                                                 r"of 2 of at most 2\^subdivisions = 1"):
        config.loads(vesicle(0))  # ... but not below the icosahedron


def test_the_round_trip_keeps_the_sphere_pose_exactly(quick_scene):
    scene, x = quick_scene
    coarse, transfer = scene.coarsened(2)
    (_, n_rod, _), (first, n_sphere, _) = scene.shapes
    (_, m_rod, _), (first_c, m_sphere, _) = coarse.shapes
    xc = transfer.restrict(x)
    assert xc.shape == (m_rod + m_sphere, 12) and m_sphere < n_sphere
    np.testing.assert_array_equal(xc[first_c], x[first])  # the pose row, bit for bit
    # the rod's coarse nodes are every second fine node (its frames re-orthonormalized)
    np.testing.assert_allclose(xc[:m_rod], x[:n_rod:2], rtol=0, atol=1e-14)
    back = transfer.prolong(xc)
    np.testing.assert_array_equal(back[first:], x[first:])  # pose and surface rebuilt exactly
    np.testing.assert_allclose(back[:n_rod], x[:n_rod], atol=1e-3)  # the rod's spline
    again = transfer.restrict(back)
    np.testing.assert_array_equal(again[first_c:], xc[first_c:])
    np.testing.assert_allclose(again, xc, rtol=0, atol=1e-13)
    with pytest.raises(ValueError, match=r"state: expected shape \(92, 12\), got \(182, 12\)"):
        transfer.prolong(x)


def test_the_coarse_scene_rates_are_close_to_the_fine_ones(quick_scene):
    """Factor 2 (the sphere 150 -> 75 points, the rod 31 -> 16 nodes). Measured: the sphere's
    (U, Ω) within 1.0 % of the fine scene's, though the rod's flow makes nearly all of it; the
    rod's rates at the shared nodes within 1.2 % (u) and 1.6 % (ω), mostly from its own coarser
    grid; with only the sphere coarsened, the rod's velocities move by 3.8e-4 of their largest,
    4.2 % of what the sphere does to them."""
    scene, x = quick_scene
    rod, sphere = scene.bodies
    (_, n_rod, _), (first, _, _) = scene.shapes
    coarse, transfer = scene.coarsened(2)
    fine_rates = scene.rates(0.0, x)
    rates = coarse.rates(0.0, transfer.restrict(x))
    m_rod = coarse.shapes[1][0]
    pose, pose_c = fine_rates[first, :6], rates[m_rod, :6]
    moved_alone = sphere.rates(0.0, x[first:, :8])[0, :6]  # the sphere without the rod
    assert np.linalg.norm(moved_alone - pose) > 0.9 * np.linalg.norm(pose)
    assert 1e-4 < np.linalg.norm(pose_c - pose) / np.linalg.norm(pose) < 0.02
    for cols in (slice(0, 3), slice(3, 6)):
        shared = fine_rates[:n_rod:2, cols]
        assert np.abs(rates[:m_rod, cols] - shared).max() < 0.03 * np.abs(shared).max()
    # the coupling through the coarser sphere alone: the rod kept, the sphere coarsened
    sphere_c, sphere_transfer = sphere.coarsened(2)
    only = dataclasses.replace(scene, bodies=(rod, sphere_c))
    y = only.stack([x[:n_rod], sphere_transfer.restrict(x[first:, :8])])
    u_rod = fine_rates[:n_rod, :3]
    without = Scene((rod,), viscosity=scene.viscosity, wall=True).rates(0.0, x[:n_rod])[:, :3]
    effect = np.abs(without - u_rod).max()
    assert effect > 3e-3 * np.abs(u_rod).max()  # the sphere does move the rod
    assert np.abs(only.rates(0.0, y)[:n_rod, :3] - u_rod).max() < 0.1 * effect


def sphere_and_rod():
    rod = models.rod_swimmer(1, 31, 1.0, length=6.0, wavelength=6.0)
    sphere = RigidBody(shape=Sphere(1.0, 40), epsilon=0.35, viscosity=rod.viscosity, wall=True,
                       position=(3.0, 2.5, 12.0), force=(0.0, 0.0, -3.8e-4))
    return Scene((rod, sphere), viscosity=rod.viscosity, wall=True, names=("rod", "sphere"))


def solve(executor=None):
    system = sphere_and_rod()
    t1, dt = 1e-4, 1e-6
    x0 = system.initial_state()
    fine = integrate.Propagator(system, "rk2", dt)
    coarse = parareal.extrapolated(system, "euler", 5 * dt,
                                   lagrange={"sphere.epsilon": [0.42, 0.44]}, grid=2)
    assert isinstance(coarse, parareal.OnCoarseGrid)
    reference = parareal.serial_solution(fine, x0, 0.0, t1, N_SLICES)
    result = parareal.run(fine, coarse, x0, 0.0, t1, N_SLICES, tol=0.0,
                          max_iterations=N_SLICES, reference=reference,
                          positions=system.positions, project=system.project,
                          executor=executor)
    return result, reference


@pytest.fixture(scope="module")
def serial():
    return solve()


def test_parareal_on_the_coarse_scene_converges_to_the_serial_fine_solution(serial):
    result, reference = serial
    errors = np.asarray(result.errors)
    assert errors[0] > 1e-6  # the coarse grid is not the fine one
    assert np.all(np.diff(errors) < 0)
    assert errors[-1] < 1e-12  # k = N: the serial fine solution, to round-off
    np.testing.assert_allclose(result.states[-1], reference[-1], atol=1e-11)


def test_processes_equal_serial_bit_for_bit(serial):
    result, _ = serial
    with parallel.make_executor("processes", 2) as executor:
        pooled, _ = solve(executor)
    for a, b in zip(pooled.states, result.states, strict=True):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(pooled.increments, result.increments)
