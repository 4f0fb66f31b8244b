"""GMRES of the mobility solves (parastokes/mobility/gmres.py, krylov.py) on many bodies: against
scipy's GMRES and a dense solve, its residual against the true one, and its iterations as bodies
are added (docs/benchmarks.md, "Suspensions")."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse.linalg import gmres as scipy_gmres

from parastokes.mobility import RigidSurface, solve_mobility
from parastokes.mobility.gmres import gmres
from parastokes.mobility.sphere import fibonacci_sphere, sphere_spacing
from parastokes.mobility.system import SurfaceSet


def sphere(n: int = 42) -> RigidSurface:
    return RigidSurface(fibonacci_sphere(n), 0.5 * sphere_spacing(n), name=f"sphere{n}")


def lattice(side: int, spacing: float, height: float = 3.0, n: int = 42) -> list:
    s = sphere(n)
    return [s.place((i * spacing, j * spacing, height + k * spacing))
            for i in range(side) for j in range(side) for k in range(side)]


def test_gmres_matches_scipys_iterations_and_the_true_residual():
    """A nonsymmetric system with a spread spectrum: the same iteration count as scipy's
    GMRES (same Arnoldi process and stopping rule), the solution of numpy's solve, and an
    Arnoldi residual equal to the true one; with a restart shorter than the iterations, the
    restart from the Arnoldi residual's vector converges as well."""
    rng = np.random.default_rng(3)
    n = 120
    a = np.diag(np.linspace(1.0, 30.0, n)) + 0.5 * rng.normal(size=(n, n)) / np.sqrt(n)
    b = rng.normal(size=n)
    result = gmres(lambda x: a @ x, b, 1e-10, restart=200, max_iterations=500)
    count = [0]
    scipy_gmres(a, b, rtol=1e-10, atol=0.0, restart=200, callback_type="pr_norm",
                callback=lambda _: count.__setitem__(0, count[0] + 1))
    assert result.iterations == count[0]
    true = np.linalg.norm(b - a @ result.x)
    assert true <= 1e-10 * np.linalg.norm(b)
    assert abs(result.estimate - true) <= 1e-13 * np.linalg.norm(b)
    np.testing.assert_allclose(result.x, np.linalg.solve(a, b), rtol=0, atol=1e-9)
    short = gmres(lambda x: a @ x, b, 1e-10, restart=7, max_iterations=2000)
    assert short.iterations > result.iterations  # restarts lose the older directions
    assert np.linalg.norm(b - a @ short.x) <= 1.01e-10 * np.linalg.norm(b)
    stopped = gmres(lambda x: a @ x, b, 1e-10, restart=7, max_iterations=5)
    assert stopped.iterations == 5 and stopped.estimate > 1e-10 * np.linalg.norm(b)


@pytest.mark.parametrize("wall", [True, False], ids=["wall", "free"])
def test_gmres_against_a_dense_solve_of_eight_bodies(wall):
    """A 2 x 2 x 2 lattice of spheres under loads and torques, in and out of the wall: GMRES
    (per-body blocks) and the dense LU agree; the reported residual is the true one."""
    bodies = lattice(2, 2.8)
    rng = np.random.default_rng(1)
    loads = {"external_force": rng.normal(size=(8, 3)),
             "external_torque": rng.normal(size=(8, 3))}
    dense = solve_mobility(bodies, mu=1.0, wall=wall, method="dense", **loads)
    iterative = solve_mobility(bodies, mu=1.0, wall=wall, method="gmres", **loads)
    scale = np.abs(dense.U).max()
    np.testing.assert_allclose(iterative.U, dense.U, rtol=0, atol=1e-8 * scale)
    np.testing.assert_allclose(iterative.Omega, dense.Omega, rtol=0,
                               atol=1e-8 * np.abs(dense.Omega).max())
    np.testing.assert_allclose(iterative.forces, dense.forces, rtol=0,
                               atol=1e-8 * np.abs(dense.forces).max())
    sset = SurfaceSet(bodies, 1.0, wall)
    m = sset.operator().dense()
    y = np.concatenate([iterative.U, iterative.Omega], axis=1)
    f = iterative.forces.ravel()
    r_v = m @ f - sset.apply_motion(y)
    r_ft = sset.reduce(f) - np.concatenate([loads["external_force"],
                                            loads["external_torque"]], axis=1)
    from parastokes.mobility.scaling import Scaling, relative_residual

    true = relative_residual(r_v, r_ft, np.zeros_like(f),
                             np.concatenate([loads["external_force"],
                                             loads["external_torque"]], axis=1),
                             Scaling(1.0, sset.length))
    assert iterative.info.residual <= 1e-10
    assert true == pytest.approx(iterative.info.residual, rel=1e-3, abs=1e-14)


def test_iterations_stay_flat_as_bodies_are_added():
    """Lattices of 8, 27 and 64 spheres at spacing 4a above the wall (volume fraction 0.065):
    the per-body blocks keep the iterations within two of each other (7, 8, 8 measured)."""
    counts = [solve_mobility(lattice(side, 4.0), mu=1.0, wall=True, method="gmres",
                             external_force=(0.0, 0.0, -1.0)).info.iterations
              for side in (2, 3, 4)]
    assert max(counts) - min(counts) <= 2 and max(counts) <= 10, counts


def test_the_batched_solves_of_one_surface_equal_each_bodys_own():
    """RotatedBatch (the copies of one surface solved at once) against each placement's own
    RotatedFactor: the saddle solve (forces, motions) and M⁻¹ g to round-off."""
    from scipy.spatial.transform import Rotation

    from parastokes.mobility.selfsolve import RotatedBatch, RotatedFactor, saddle_solve

    s = sphere(42)
    rng = np.random.default_rng(5)
    rotations = Rotation.random(5, random_state=rng).as_matrix()
    factors = [RotatedFactor(s.place(rng.normal(size=3), r), 1.0) for r in rotations]
    g, ft = rng.normal(size=(5, 126)), rng.normal(size=(5, 6))
    forces, motions = RotatedBatch(factors).saddle(g, ft)
    for k, factor in enumerate(factors):
        f_k, y_k = saddle_solve(factor, factor.motion, g[k], ft[k])
        np.testing.assert_allclose(forces[k], f_k, rtol=0, atol=1e-12 * np.abs(f_k).max())
        np.testing.assert_allclose(motions[k], y_k, rtol=0, atol=1e-12 * np.abs(y_k).max())
    np.testing.assert_allclose(RotatedBatch(factors).solve(g)[2], factors[2].solve(g[2]),
                               rtol=0, atol=1e-12 * np.abs(factors[2].solve(g[2])).max())
    with pytest.raises(ValueError, match="share one body-frame"):
        RotatedBatch([factors[0], RotatedFactor(sphere(50).place(), 1.0)])
