"""Rigid bodies on a coarser surface for the coarse solver (kinds/rigid/coarse.py, Remark 4):
the grid transfer is exact through the pose, ε scales with the spacing and means the same
parameter on both surfaces, and Parareal with the coarse-surface G converges to the serial fine
solution."""

from __future__ import annotations

import math

import numpy as np
import pytest

from parastokes import config, integrate, parareal
from parastokes.kinds.rigid import Bacterium, Helix, PointCloud, RigidBody, Rod, Sphere, Spheroid
from parastokes.kinds.rigid.shapes import spacing

N_SLICES = 4


def bacterium() -> RigidBody:
    shape = Bacterium(Spheroid(1.0, 0.5, 40), Helix(0.25, 2.0, 1.5, 24), 0.25, 2 * math.pi * 10)
    return RigidBody(shape=shape, epsilon=0.2, viscosity=1e-3, wall=True,
                     position=(0.0, 0.0, 1.2), orientation=(0.995, 0.0, 0.0998, 0.0))


def test_the_transfer_carries_the_pose_and_rebuilds_each_surface_exactly():
    body = bacterium()
    coarse, transfer = body.coarsened(2)
    assert coarse.n_surface == 20 + 12 and coarse.shape.phase_rate == body.shape.phase_rate
    ratio = spacing(coarse.shape) / spacing(body.shape)
    assert ratio > 1 and coarse.epsilon == pytest.approx(body.epsilon * ratio, rel=1e-15)
    assert coarse.params == pytest.approx(body.params, rel=1e-15)  # ε: the same parameter
    assert coarse.with_params(epsilon=0.3).epsilon == pytest.approx(0.3 * ratio, rel=1e-15)
    x = integrate.propagate(body, body.initial_state(), 0.0, 0.01, "rk2", 1e-3)
    xc = transfer.restrict(x)
    np.testing.assert_array_equal(xc[0], x[0])
    np.testing.assert_array_equal(xc, coarse.state_of(x[0, :3], x[0, 3:7], x[0, 7]))
    np.testing.assert_array_equal(transfer.prolong(xc), x)
    np.testing.assert_array_equal(transfer.restrict(transfer.prolong(xc)), xc)
    with pytest.raises(ValueError, match=r"expected shape \(33, 8\)"):
        transfer.prolong(x)


@pytest.mark.parametrize("shape, rows", [(Sphere(1.0, 50), 17), (Rod(4.0, 0.5, 9, 6), 3 * 6 + 2),
                                         (Helix(0.2, 1.0, 2.0, 7), 3)])
def test_each_part_gets_factor_times_fewer_points(shape, rows):
    body = RigidBody(shape=shape, epsilon=spacing(shape))
    assert body.coarsened(3)[0].n_surface == rows


def test_a_point_cloud_or_a_bad_factor_is_refused_by_name():
    cloud = RigidBody(shape=PointCloud.of(np.eye(3) + 0.1 * np.arange(9).reshape(3, 3)),
                      epsilon=1.0)
    with pytest.raises(ValueError, match=r"a user's point cloud cannot .* \(coarse.grid_factor\)"):
        cloud.coarsened(2)
    with pytest.raises(ValueError, match="positive integer"):
        bacterium().coarsened(0)


def test_parareal_with_the_coarse_surface_converges_to_the_serial_fine_solution():
    body = bacterium()
    t1, dt = 0.02, 1e-3
    fine = integrate.Propagator(body, "rk2", dt)
    coarse = parareal.extrapolated(body, "euler", 5 * dt, lagrange={"epsilon": [0.24, 0.26]},
                                   grid=2)
    assert isinstance(coarse, parareal.OnCoarseGrid)
    x0 = body.initial_state()
    reference = parareal.serial_solution(fine, x0, 0.0, t1, N_SLICES)
    result = parareal.run(fine, coarse, x0, 0.0, t1, N_SLICES, tol=0.0,
                          max_iterations=N_SLICES, reference=reference,
                          positions=body.positions, project=body.project)
    errors = np.asarray(result.errors)
    assert errors[0] > 1e-6  # the coarse surface is not the fine one
    assert errors[1] < 0.1 * errors[0] and errors[2] < 0.1 * errors[1]
    assert errors[-1] < 1e-12  # k = N: the serial fine solution, to round-off
    np.testing.assert_allclose(result.states[-1], reference[-1], atol=1e-11)


def test_a_config_with_a_grid_factor_resolves_the_coarse_rows():
    text = """
[model]
kind = "bacterium"
head_points = 40
tail_points = 24
turns = 1.5
wall = true
position = [0.0, 0.0, 1.5]
[time]
t1 = 0.004
[fine]
dt = 2e-4
[coarse]
dt_ratio = 5
grid_factor = 2
[parareal]
n_slices = 2
"""
    _, resolved = config.loads(text)
    assert resolved.coarse_points == 1 + 20 + 12 and resolved.n_points == 1 + 40 + 24
