"""Resistance problems on a 642-point icosphere (``shared/physics.md`` section 5).

A rigid sphere of radius a = 1 translating at unit speed U: assemble the 3N x 3N mobility matrix
of the regularized Stokeslets at its surface points (free space, or above the wall z = 0), solve for
the point forces giving velocity U at every point, and compare the total force with

- Stokes' drag 6πμaU in free space (within 3%, ε = ½ × mean edge length);
- Brenner's exact correction factors for motion perpendicular to the wall (within 5%);
- Faxén's approximate factor [1 - 9q/16 + q³/8 - 45q⁴/256 - q⁵/16]⁻¹, q = a/h, for motion
  parallel to the wall (within 5%).
"""

from functools import lru_cache

import numpy as np
import pytest
from documented import check

from parastokes import mrs
from parastokes.bodies.geometry import icosphere, mesh_edges

MU = 1.3


@lru_cache(maxsize=1)
def _sphere():
    """The 642 unit-sphere points and ε = ½ × mean edge length."""
    points, triangles = icosphere(3)
    points = np.array(points)
    edges = mesh_edges(triangles)
    assert points.shape == (642, 3)
    np.testing.assert_allclose(np.linalg.norm(points, axis=1), 1.0, rtol=1e-14)
    mean_edge = np.linalg.norm(points[edges[:, 1]] - points[edges[:, 0]], axis=1).mean()
    return points, 0.5 * mean_edge


@lru_cache(maxsize=8)
def _mobility(height, wall):
    """The (3N, 3N) force -> velocity matrix of the sphere centred at (0, 0, height).

    Entry (3i + a, 3j + b) = u_a(x_i) from a unit force e_b at x_j. One batched call per force
    direction: system j has the single source x_j and all N targets.
    """
    points, eps = _sphere()
    points = points + np.array([0.0, 0.0, height])
    n = len(points)
    targets = np.broadcast_to(points, (n, n, 3))
    sources = points[:, None, :]
    a = np.empty((3 * n, 3 * n))
    for b in range(3):
        forces = np.zeros((n, 1, 3))
        forces[:, 0, b] = 1.0
        u = mrs.velocity(targets, sources, forces, epsilon=eps, mu=MU, wall=wall, n_threads=2)
        a[:, b::3] = u.transpose(1, 2, 0).reshape(3 * n, n)  # u[j, i, :] -> rows 3i.., column j
    return a


def _drag_factor(height, direction, wall):
    """Total force on the fluid / (6πμaU) for the rigid translation U = e_direction."""
    a = _mobility(height, wall)
    velocity = np.zeros((a.shape[0] // 3, 3))
    velocity[:, direction] = 1.0
    forces = np.linalg.solve(a, velocity.ravel()).reshape(-1, 3)
    total = forces.sum(axis=0)
    others = np.delete(total, direction)
    assert np.all(np.abs(others) < 1e-6 * abs(total[direction]))  # no sideways force
    return total[direction] / (6 * np.pi * MU)


def test_mobility_matrix_symmetric():
    """The assembled matrix is symmetric (M(x, y) = M(y, x)ᵀ), free and wall."""
    for height, wall in ((0.0, False), (1.5431, True)):
        a = _mobility(height, wall)
        assert np.max(np.abs(a - a.T)) < 1e-13 * np.max(np.abs(a))


def test_stokes_drag():
    """Free space, unit translation along x and along z: drag within 3% of 6πμaU."""
    for direction in (0, 2):
        factor = _drag_factor(0.0, direction, wall=False)
        assert factor == pytest.approx(1.0, rel=0.03)
        check("kernels", "stokes_drag_percent", 100 * (factor - 1))  # docs/validation.md, +1.6%


BRENNER = [(1.5431, 3.0361), (2.3524, 1.8375), (3.7622, 1.4129)]
FAXEN_HEIGHTS = [2.3524, 3.7622]


@pytest.mark.parametrize(("h", "brenner"), BRENNER)
def test_brenner_perpendicular(h, brenner):
    """Sphere centred at height h above the wall moving along z: Brenner's factor within 5%, and
    the documented excess (docs/numbers.toml [kernels])."""
    factor = _drag_factor(h, 2, wall=True)
    assert factor == pytest.approx(brenner, rel=0.05)
    check("kernels", "brenner_percent", 100 * (factor / brenner - 1), BRENNER.index((h, brenner)))


@pytest.mark.parametrize("h", FAXEN_HEIGHTS)
def test_faxen_parallel(h):
    """Sphere centred at height h moving along x: Faxén's parallel factor within 5%, and the
    documented excess."""
    q = 1.0 / h
    faxen = 1.0 / (1 - 9 * q / 16 + q**3 / 8 - 45 * q**4 / 256 - q**5 / 16)
    factor = _drag_factor(h, 0, wall=True)
    assert factor == pytest.approx(faxen, rel=0.05)
    check("kernels", "faxen_percent", 100 * (factor / faxen - 1), FAXEN_HEIGHTS.index(h))
