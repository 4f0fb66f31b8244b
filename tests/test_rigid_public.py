"""The public names of docs/design.md for rigid bodies and HODMD (issue 39): ``parastokes.rigid``
(shapes, resistance, mobility, the resistance matrix, the spacing helper), a body built from a
configuration table alone and used with them, ``parastokes.parareal.hodmd``, one "surface too
coarse" rule, and one default motor rate."""

from __future__ import annotations

import math

import numpy as np
import pytest

from parastokes import config, rigid
from parastokes.kinds.rigid.kind import BacteriumModel
from parastokes.kinds.rigid.shapes import Bacterium, Helix, Sphere
from parastokes.kinds.rigid.system import RigidBody
from parastokes.mobility.checks import MAX_SPACING_OVER_EPS


def test_a_sphere_has_stokes_drag_and_resistance_and_mobility_are_inverse():
    body = rigid.sphere(radius=1.0, n_points=400)
    assert body.epsilon[0] == pytest.approx(0.5 * rigid.spacing(body))
    force, torque = rigid.resistance(body, U=(1, 0, 0), Omega=(0, 0, 0), center=(0, 0, 0),
                                     mu=1.0)
    assert force[0] / (6 * math.pi) - 1 == pytest.approx(0.015, abs=0.01)  # O(ε): validation.md
    assert np.abs(force[1:]).max() < 1e-3 and np.abs(torque).max() < 0.05
    matrix = rigid.resistance_matrix(body, center=(0, 0, 5.0), mu=1.0, wall=True)
    np.testing.assert_allclose(matrix, matrix.T, atol=1e-10)
    U, Omega = rigid.mobility(body, force=(0.3, 0, -1), torque=(0, 0.2, 0), center=(0, 0, 5.0),
                              mu=1.0, wall=True)
    np.testing.assert_allclose(matrix @ np.r_[U, Omega], [0.3, 0, -1, 0, 0.2, 0], atol=1e-8)
    assert 0 > U[2] > -1 / (6 * math.pi)  # slower than in free space, above the wall


def test_a_body_built_from_a_config_table_is_used_with_its_own_fluid_and_pose():
    table = {"kind": "rigid", "shape": "spheroid", "axial": 2.0, "radius": 1.0,
             "n_points": 200, "viscosity": 2.0, "wall": True, "position": [0.0, 0.0, 4.0],
             "orientation": [math.cos(math.pi / 8), 0.0, math.sin(math.pi / 8), 0.0]}
    body = config.build_body(table)
    assert isinstance(body, RigidBody)
    U, Omega = rigid.mobility(body, force=(0, 0, -1))
    surface = rigid.spheroid(2.0, 1.0, 200, epsilon=float(body.epsilon))
    turn = np.array([[math.cos(math.pi / 4), 0, math.sin(math.pi / 4)], [0, 1, 0],
                     [-math.sin(math.pi / 4), 0, math.cos(math.pi / 4)]])
    U2, Omega2 = rigid.mobility(surface, force=(0, 0, -1), center=(0, 0, 4.0), rotation=turn,
                                mu=2.0, wall=True)
    np.testing.assert_allclose(np.r_[U, Omega], np.r_[U2, Omega2], rtol=1e-9, atol=1e-14)
    with pytest.raises(config.ConfigError, match=r"model\.n_points"):
        config.build_body({"kind": "rigid", "n_points": 2})


def test_hodmd_extrapolates_a_standing_wave_and_a_decay():
    from parastokes.parareal import hodmd

    k = np.arange(20.0)
    phi, psi = np.array([1.0, -2.0, 0.5]), np.array([0.2, 0.1, 1.0])
    snapshots = np.outer(phi, np.cos(0.3 * k)) + np.outer(psi, np.exp(-0.05 * k))
    t = np.array([25.0, 30.5])
    expected = np.outer(phi, np.cos(0.3 * t)) + np.outer(psi, np.exp(-0.05 * t))
    np.testing.assert_allclose(hodmd(snapshots, d=5, tol=1e-10, times=t), expected, atol=1e-9)
    np.testing.assert_allclose(hodmd(snapshots, d=5, tol=1e-10), snapshots, atol=1e-9)


def test_one_rule_for_a_surface_too_coarse():
    shape = Sphere(1.0, 100)
    gap = rigid.spacing(shape)
    epsilon = gap / (MAX_SPACING_OVER_EPS + 0.5)  # (a body accepted it up to 5 ε before)
    with pytest.raises(ValueError, match="too coarse"):
        rigid.sphere(1.0, 100, epsilon=epsilon)
    with pytest.raises(ValueError, match="too coarse"):
        RigidBody(shape=shape, epsilon=epsilon)
    RigidBody(shape=shape, epsilon=gap / (MAX_SPACING_OVER_EPS - 0.5))


def test_the_motor_rate_has_one_default():
    model = BacteriumModel(kind="bacterium")
    default = Bacterium(Sphere(0.5, 30), Helix(0.2, 1.0, 1.5, 24))
    # 10 turns a second about -e1: counter-clockwise seen from behind, as E. coli's in a run
    assert model.motor_rate == default.motor_rate == -2 * math.pi * 10
    assert model.handedness == Bacterium().tail.handedness == -1  # left-handed, as E. coli's
