"""Rigid and prescribed-motion bodies (parastokes/kinds/rigid): closed forms of Stokes flow,
exact rotations, the state's invariants, and the input checks that name the body.

The convergence studies at larger N are in tests/test_rigid_validation.py (marked slow, with a
CI-sized variant each)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from parastokes import integrate
from parastokes.bodies.sources import fluid_sources
from parastokes.kinds.rigid import (
    Bacterium,
    Helix,
    PointCloud,
    RigidBody,
    Rod,
    Sphere,
    Spheroid,
    Squirmer,
    rotation,
)
from parastokes.kinds.rigid.kind import check_solvable
from parastokes.kinds.rigid.shapes import spacing

MU = 1.7


def sphere_body(n=200, ratio=0.5, **kw):
    shape = Sphere(1.0, n)
    return RigidBody(shape=shape, epsilon=ratio * spacing(shape), viscosity=MU, **kw)


def test_quaternion_exp_map_is_the_rotation_by_the_angle_about_the_axis():
    omega = np.array([0.3, -1.2, 0.5])
    q = rotation.exp_rotate(np.array(rotation.IDENTITY), omega, 0.7)
    r = rotation.matrix(q)
    angle = np.linalg.norm(omega) * 0.7
    e = omega / np.linalg.norm(omega)
    k = np.array([[0, -e[2], e[1]], [e[2], 0, -e[0]], [-e[1], e[0], 0]])
    np.testing.assert_allclose(r, np.eye(3) + math.sin(angle) * k
                               + (1 - math.cos(angle)) * k @ k, atol=1e-15)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-15)


def test_a_torque_turns_the_sphere_by_the_exact_rotation_of_its_rates():
    """Ω ≈ T / (8πμa³); ``advance`` turns the pose and the surface by exactly dt Ω (the
    exponential map): no drift of |q| and rigid distances kept to round-off."""
    torque = np.array([0.0, 0.0, 8 * math.pi * MU])  # Ω = e_z for the continuum sphere
    body = sphere_body(torque=tuple(torque))
    x0 = body.initial_state()
    rates = body.rates(0.0, x0)
    omega = rates[0, 3:6]
    assert omega[2] == pytest.approx(1.0, rel=0.1)  # converges: test_rigid_validation.py
    x = body.advance(x0, rates, 0.9)
    q = rotation.exp_rotate(x0[0, 3:7], omega, 0.9)
    np.testing.assert_array_equal(x[0, 3:7], q)
    turned = (x0[1:, :3] - x0[0, :3]) @ rotation.matrix(q).T
    np.testing.assert_allclose(x[1:, :3] - x[0, :3], turned, atol=1e-14)
    y = integrate.propagate(body, x0, 0.0, 3.0, "rk4", 0.3)
    assert body.monitor(y) < 1e-14
    assert y[0, 3] == pytest.approx(math.cos(0.5 * 3.0 * omega[2]), abs=1e-5)


def test_the_surface_rows_follow_the_pose_and_project_renormalizes():
    body = sphere_body(60, position=(1.0, 2.0, 3.0), orientation=(1.0, 0.2, 0.0, 0.1))
    x = body.initial_state()
    assert x.shape == (61, 8)
    np.testing.assert_allclose(np.linalg.norm(x[1:, :3] - x[0, :3], axis=1), 1.0, rtol=1e-14)
    y = x.copy()
    y[0, 3:7] *= 1.01
    z = body.project(y)
    np.testing.assert_allclose(z, x, atol=1e-14)
    np.testing.assert_array_equal(body.project(z), z)


def test_sedimenting_sphere_force_balance_and_stokes_law():
    weight = np.array([0.0, 0.0, -6 * math.pi * MU])  # U = -e_z for the continuum sphere
    body = sphere_body(400, force=tuple(weight))
    x = body.initial_state()
    sources = fluid_sources(body, 0.0, x)
    np.testing.assert_allclose(sources.forces.sum(axis=0), weight, atol=1e-10)
    np.testing.assert_allclose(np.cross(sources.points - x[0, :3], sources.forces).sum(axis=0),
                               0.0, atol=1e-10)
    u = body.rates(0.0, x)[0, :3]
    assert u[2] == pytest.approx(-1.0, rel=0.03)
    assert np.abs(u[:2]).max() < 1e-3


def test_squirmer_swims_at_two_thirds_b1_whatever_b2():
    speeds = []
    for b2 in (0.0, 3.0, -3.0):
        body = sphere_body(300, ratio=0.3, slip=Squirmer(1.5, b2))
        speeds.append(body.rates(0.0, body.initial_state())[0, :3])
    speeds = np.array(speeds)
    assert speeds[0, 0] == pytest.approx(1.0, rel=0.1)  # 2 B1 / 3; converges: test_rigid_validation
    np.testing.assert_allclose(speeds[1:, 0], speeds[0, 0], rtol=2e-3)
    assert np.abs(speeds[:, 1:]).max() < 2e-3


def test_the_bacterium_is_free_of_force_and_torque_and_its_head_counter_rotates():
    shape = Bacterium(Spheroid(1.0, 0.5, 120), Helix(0.25, 2.0, 2.0, 60), 0.25, 2 * math.pi)
    body = RigidBody(shape=shape, epsilon=0.5 * spacing(shape), viscosity=MU)
    x = body.initial_state()
    r = body.rates(0.0, x)
    sources = fluid_sources(body, 0.0, x)
    np.testing.assert_allclose(sources.forces.sum(axis=0), 0.0, atol=1e-10)
    assert r[0, 6] == 2 * math.pi  # the phase turns at the motor's rate
    assert r[0, 3] < 0 < shape.motor_rate  # the head turns against the flagellum
    assert abs(r[0, 3]) < shape.motor_rate
    # a phase-shifted flagellum is the same body turned about its axis by that phase
    phase = 0.4
    turned = body.state_of(np.zeros(3), np.array(rotation.IDENTITY), phase)
    spun = body.state_of(np.zeros(3), rotation.rotation_about([1, 0, 0], phase), 0.0)
    np.testing.assert_allclose(turned[1 + 120:, :3], spun[1 + 120:, :3], atol=1e-14)


def test_input_errors_name_the_body_and_what_to_change():
    with pytest.raises(ValueError, match=r"too coarse for ε = 0.01.*use more points or ε >="):
        RigidBody(shape=Sphere(1.0, 50), epsilon=0.01)
    with pytest.raises(ValueError, match=r"on or below the wall z = 0; raise position\[2\]"):
        RigidBody(shape=Sphere(1.0, 50), epsilon=0.3, wall=True, position=(0, 0, 0.5))
    with pytest.raises(ValueError, match=r"squirmer's slip is defined on a sphere"):
        RigidBody(shape=Spheroid(2.0, 1.0, 50), slip=Squirmer(), epsilon=0.5)
    line = PointCloud.of(np.stack([np.linspace(0, 3, 20), np.zeros(20), np.zeros(20)], 1))
    with pytest.raises(ValueError, match=r"rod: the mobility system is singular"):
        check_solvable(RigidBody(shape=line, epsilon=0.3), "rod")
    check_solvable(RigidBody(shape=Rod(3.0, 0.3, 12, 6), epsilon=0.3), "tube")  # a tube is not


def test_a_wall_slows_a_sedimenting_sphere_and_the_body_never_crosses_it():
    weight = (0.0, 0.0, -6 * math.pi * MU)
    far = sphere_body(200, force=weight, wall=True, position=(0, 0, 30.0))
    near = sphere_body(200, force=weight, wall=True, position=(0, 0, 1.5431))
    u_far = far.rates(0.0, far.initial_state())[0, 2]
    u_near = near.rates(0.0, near.initial_state())[0, 2]
    # Brenner (1961): at h/a = 1.5431 the drag is 3.0361 x Stokes' (docs/physics.md section 5)
    assert u_near / u_far == pytest.approx(1 / 3.0361, rel=0.06)
    x = near.initial_state()
    x[0, 2] = 0.5
    assert near.monitor(near.project(x)) == math.inf


def test_the_kept_body_frame_factorization_gives_a_fresh_solve():
    """One free rigid body keeps its surface (and so its body-frame factorization) between
    solves; a fresh surface at the same pose gives the same (U, Ω) and forces at any pose."""
    import dataclasses

    from parastokes.kinds.rigid.solve import mobility

    body = sphere_body(120, slip=Squirmer(1.0, 2.0), force=(0.3, -0.2, 1.0),
                       torque=(0.0, 0.5, 0.1))
    for q in ((0.8, 0.3, -0.4, 0.2), (0.1, 0.9, 0.3, -0.2)):
        y = body.state_of(np.array([1.0, 2.0, 3.0]), rotation.normalized(np.array(q)), 0.0)
        surface = body.surface(0.0, y)
        assert surface.key is not None
        kept = mobility([surface], MU, False, None)
        fresh = mobility([dataclasses.replace(surface, key=None)], MU, False, None)
        assert kept.info.reused
        np.testing.assert_allclose(kept.U, fresh.U, atol=1e-12)
        np.testing.assert_allclose(kept.Omega, fresh.Omega, atol=1e-12)
        np.testing.assert_allclose(kept.forces, fresh.forces, atol=1e-10)
        assert kept.residual < 1e-10


def test_resistance_inverts_mobility():
    """The resistance problem at the (U, Ω) the mobility problem found gives back the external
    force and torque (with the same slip): the two are inverses."""
    body = sphere_body(150, slip=Squirmer(1.0, 1.0), force=(0.2, 0.0, -1.0),
                       torque=(0.0, 0.3, 0.1), orientation=(0.9, 0.2, 0.1, -0.3))
    x = body.initial_state()
    solution = body.solve(0.0, x)
    back = body.resistance(0.0, x, solution.U[0], solution.Omega[0])
    np.testing.assert_allclose(back.force[0], body.force, atol=1e-9)
    np.testing.assert_allclose(back.torque[0], body.torque, atol=1e-9)
    np.testing.assert_allclose(back.forces, solution.forces, atol=1e-9)


@pytest.mark.parametrize("name", ["rigid", "squirmer", "bacterium"])
def test_the_rigid_kinds_keep_the_contract_ci(name):
    """check_system on each kind's example with fewer steps than tests/test_system_contract.py
    (there marked slow): every part of the contract, orders fitted over 8-32 steps."""
    from parastokes.registry import kinds as registry
    from parastokes.testing import check_system

    system, state, horizon = registry.get(name).example()
    check_system(system, state, horizon=horizon, counts=(8, 16, 32))
