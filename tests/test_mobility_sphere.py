"""Resistance and mobility of rigid bodies in free space (parastokes.mobility).

Closed forms: a translating sphere's drag 6πμaU and uniform traction 3μU/(2a) (the forces on
the fluid, Cortez, Fauci & Medovikov 2005, section 4; Khatri & Cortez's example), a rotating
sphere's torque 8πμa³Ω; their convergence order with ε tied to the spacing (ε = h/2, as Khatri &
Cortez); Lorentz reciprocity (R symmetric), R positive definite; mobility inverts resistance;
the reused body-frame factorization equals a fresh one; dense and GMRES agree; bad input.
"""

from functools import lru_cache

import numpy as np
import pytest
from documented import check

from parastokes.mobility import (
    RigidSurface,
    SolveError,
    resistance_matrix,
    rigid_motion,
    solve_mobility,
    solve_resistance,
)
from parastokes.mobility.sphere import fibonacci_sphere, sphere_spacing

MU = 1.3
A = 0.8  # sphere radius


@lru_cache(maxsize=16)
def sphere(n: int, radius: float = A) -> RigidSurface:
    """A Fibonacci sphere of n points, ε = half the spacing."""
    return RigidSurface(fibonacci_sphere(n, radius), 0.5 * sphere_spacing(n, radius), name="sphere")


@lru_cache(maxsize=4)
def ellipsoid(n: int = 400) -> RigidSurface:
    """Points of an ellipsoid with semi-axes (1, 0.6, 0.4), reference point off its center."""
    pts = fibonacci_sphere(n) * np.array([1.0, 0.6, 0.4]) + np.array([0.2, -0.1, 0.05])
    return RigidSurface(pts, 1.3 / np.sqrt(n), name="ellipsoid")


def rotation(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


Q = rotation((1.0, 2.0, -0.5), 0.9)


def sphere_errors(n: int) -> tuple[float, float, float]:
    """Relative errors of drag, torque and the L2 traction (translation along Q's x axis)."""
    s = sphere(n)
    u = Q[:, 0]
    res = solve_resistance(s.place((0.3, -1.0, 2.0), Q), U=u, mu=MU)
    drag = abs(res.force[0] @ u / (6 * np.pi * MU * A) - 1)
    rot = solve_resistance(s.place((0.3, -1.0, 2.0), Q), Omega=u, mu=MU)
    torque = abs(rot.torque[0] @ u / (8 * np.pi * MU * A**3) - 1)
    traction = res.forces * n / (4 * np.pi * A**2)  # point force / area of its cell
    exact = 1.5 * MU * u / A
    l2 = np.sqrt(np.mean(np.sum((traction - exact) ** 2, axis=1))) / np.linalg.norm(exact)
    return drag, torque, l2


def test_translating_and_rotating_sphere():
    """400 points: drag within 2%, torque within 6%, the traction uniform within 17% (L2; the
    point forces of the method are noisy, the error falls at order 1, see the slow test)."""
    drag, torque, traction = sphere_errors(400)
    assert drag < 0.02
    assert torque < 0.06
    assert traction < 0.17
    for name, value in (("drag", drag), ("torque", torque), ("traction", traction)):
        check("rigid_free", name, value, 0)  # docs/validation.md, the table's N = 400 row


def fitted_orders(sizes):
    h = np.array([sphere_spacing(n, A) for n in sizes])
    errors = np.array([sphere_errors(n) for n in sizes])
    return [np.polyfit(np.log(h), np.log(errors[:, k]), 1)[0] for k in range(3)], errors


def test_convergence_order_small():
    """N = 100, 200, 400 with ε = h/2: drag and torque errors fall at a fitted order near 1 in
    the spacing h (the O(ε) error of the method at the surface), the traction's near 0.8."""
    (drag, torque, traction), _ = fitted_orders((100, 200, 400))
    assert 0.8 < drag < 1.5
    assert 0.8 < torque < 1.5
    assert 0.6 < traction < 1.5
    check("rigid_free", "orders_small", [drag, torque, traction])


@pytest.mark.slow
def test_convergence_order_large():
    """N = 400 .. 3200: orders near 1 for drag, torque and traction (measured 1.1, 1.0, 0.9)."""
    (drag, torque, traction), errors = fitted_orders((400, 800, 1600, 3200))
    assert 0.85 < drag < 1.3
    assert 0.85 < torque < 1.3
    assert 0.75 < traction < 1.3
    assert errors[-1, 0] < 0.006
    check("rigid_free", "orders", [drag, torque, traction])
    for k, name in enumerate(("drag", "torque", "traction")):
        check("rigid_free", name, list(errors[:, k]))


def test_resistance_matrix_symmetric_positive_definite():
    """An off-center ellipsoid, turned: R is symmetric (reciprocity; exactly, since M is) and
    positive definite; its coupling blocks are not zero (the test would see a transpose error)."""
    r = resistance_matrix(ellipsoid(), (1.0, 2.0, 3.0), Q, mu=MU)
    assert np.max(np.abs(r - r.T)) < 1e-10 * np.max(np.abs(r))
    assert np.min(np.linalg.eigvalsh(r)) > 0
    assert np.max(np.abs(r[:3, 3:])) > 0.05 * np.max(np.abs(r[:3, :3]))


def test_resistance_matrix_rotates_as_a_tensor():
    """R at rotation Q equals diag(Q, Q) R(I) diag(Q, Q)ᵀ, and the reused body-frame
    factorization equals a fresh factorization in the lab (two bodies far apart: dense lab)."""
    s = ellipsoid()
    r0 = resistance_matrix(s, (0.0, 0.0, 0.0), None, mu=MU)
    q6 = np.kron(np.eye(2), Q)
    r = resistance_matrix(s, (1.0, 2.0, 3.0), Q, mu=MU)
    np.testing.assert_allclose(r, q6 @ r0 @ q6.T, atol=1e-10 * np.abs(r).max())
    from parastokes.mobility.selfsolve import LabFactor, RotatedFactor

    placed = s.place((1.0, 2.0, 3.0), Q)
    fresh = LabFactor(placed.points, placed.epsilon, MU, False, placed.motion(), "lab")
    reused = RotatedFactor(placed, MU)
    b = np.random.default_rng(1).normal(size=3 * len(s))
    np.testing.assert_allclose(reused.solve(b), fresh.solve(b), rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(reused.resistance, fresh.resistance, rtol=1e-9)


def test_mobility_inverts_resistance():
    """Loads (F, T) = R (U, Ω) give back (U, Ω), and the forces of both problems agree."""
    s = ellipsoid()
    placed = s.place((0.5, 0.0, -1.0), Q)
    u, w = np.array([0.3, -1.0, 0.4]), np.array([0.7, 0.2, -0.5])
    res = solve_resistance(placed, U=u, Omega=w, mu=MU)
    mob = solve_mobility(placed, mu=MU, external_force=res.force, external_torque=res.torque)
    np.testing.assert_allclose(mob.U[0], u, rtol=1e-9)
    np.testing.assert_allclose(mob.Omega[0], w, rtol=1e-9)
    np.testing.assert_allclose(mob.forces, res.forces, atol=1e-9 * np.abs(res.forces).max())
    assert mob.info.reused and res.info.reused and mob.info.residual < 1e-12


def test_sedimenting_sphere_sign():
    """Forces on the fluid: a sphere under F_ext = -e_z moves down at about F/(6πμa) and pushes
    the fluid with Σ f = F_ext; a torque-free, force-free body does not move."""
    placed = sphere(400).place((0.0, 0.0, 0.0))
    mob = solve_mobility(placed, mu=MU, external_force=(0.0, 0.0, -1.0))
    assert mob.U[0, 2] == pytest.approx(-1 / (6 * np.pi * MU * A), rel=0.02)
    np.testing.assert_allclose(mob.forces.sum(axis=0), [0, 0, -1], atol=1e-12)
    free = solve_mobility(placed, mu=MU)
    assert np.all(free.U == 0) and np.all(free.forces == 0)


def test_slip_and_background_shift_the_rigid_motion():
    """A uniform slip s on every point moves a force-free body at -s; a uniform background
    velocity v carries it at +v; both with zero forces."""
    placed = ellipsoid().place((0.0, 1.0, 0.0), Q)
    n = len(placed.points)
    s, v = np.array([0.1, 0.2, -0.3]), np.array([-0.5, 0.05, 0.4])
    mob = solve_mobility(placed, mu=MU, slip=np.tile(s, (n, 1)), background=np.tile(v, (n, 1)))
    np.testing.assert_allclose(mob.U[0], v - s, atol=1e-10)
    np.testing.assert_allclose(mob.Omega[0], 0, atol=1e-10)
    assert np.abs(mob.forces).max() < 1e-10


def test_rigid_motion_matrix():
    """K [U, Ω] = U + Ω × (x - c), and Kᵀ f = (Σ f, Σ (x - c) × f)."""
    rng = np.random.default_rng(3)
    x, c = rng.normal(size=(5, 3)), rng.normal(size=3)
    u, w, f = rng.normal(size=3), rng.normal(size=3), rng.normal(size=(5, 3))
    k = rigid_motion(x, c)
    np.testing.assert_allclose((k @ np.r_[u, w]).reshape(-1, 3), u + np.cross(w, x - c))
    np.testing.assert_allclose(k.T @ f.ravel(), np.r_[f.sum(0), np.cross(x - c, f).sum(0)])


@pytest.mark.parametrize("wall", [False, True])
def test_dense_and_gmres_agree_for_three_bodies(wall):
    """Three bodies (two spheres, an ellipsoid), loads on each: the direct and the GMRES solves
    agree to the tolerance; GMRES reports its iterations and a residual below tol."""
    bodies = [
        sphere(100).place((0.0, 0.0, 2.5)),
        sphere(100).place((2.0, 0.5, 2.0)),
        ellipsoid(150).place((0.5, 2.5, 2.2), Q),
    ]
    loads = dict(
        external_force=[(0, 0, -1), (1, 0, 0), (0, 0.5, 0)],
        external_torque=[(0, 0, 0), (0, 0, 1), (1, 0, 0)],
    )
    dense = solve_mobility(bodies, mu=MU, wall=wall, method="dense", **loads)
    krylov = solve_mobility(bodies, mu=MU, wall=wall, method="gmres", tol=1e-11, **loads)
    assert dense.info.method == "dense" and krylov.info.method == "gmres"
    assert 1 <= krylov.info.iterations <= 30 and krylov.info.residual < 1e-10
    assert dense.info.residual < 1e-12
    for name in ("U", "Omega", "forces"):
        ref = getattr(dense, name)
        np.testing.assert_allclose(getattr(krylov, name), ref, atol=1e-8 * np.abs(ref).max())
    res_d = solve_resistance(bodies, U=dense.U, Omega=dense.Omega, mu=MU, wall=wall, method="dense")
    res_g = solve_resistance(bodies, U=dense.U, Omega=dense.Omega, mu=MU, wall=wall, method="gmres")
    np.testing.assert_allclose(res_d.force, loads["external_force"], atol=1e-9)
    np.testing.assert_allclose(res_g.forces, res_d.forces, atol=1e-8 * np.abs(res_d.forces).max())


def test_gmres_not_converged_is_an_error(monkeypatch):
    from parastokes.mobility import krylov

    monkeypatch.setattr(krylov, "RESTART", 2)
    monkeypatch.setattr(krylov, "MAX_ITERATIONS", 2)
    bodies = [sphere(200).place((0.0, 0.0, 1.1)), sphere(200).place((1.7, 0.0, 1.1))]
    with pytest.raises(SolveError, match="GMRES did not reach"):
        solve_mobility(bodies, mu=MU, wall=True, external_force=(0, 0, 1), method="gmres")


def test_ill_conditioned_is_an_error():
    """ε far larger than the spacing (the surface check skipped): a named error, no result."""
    s = RigidSurface(fibonacci_sphere(300), 2.0, check=False)
    with pytest.raises(SolveError, match="ill-conditioned"):
        solve_resistance(s.place(), U=(1, 0, 0), mu=1.0)


def test_bad_input_is_refused_before_solving():
    pts = fibonacci_sphere(100)
    with pytest.raises(ValueError, match="tail: surface too coarse"):
        RigidSurface(pts, 0.02, name="tail")
    with pytest.raises(ValueError, match="repeated"):
        RigidSurface(np.vstack([pts, pts[:1]]), 0.2)
    s = sphere(200)
    with pytest.raises(ValueError, match="overlap"):
        solve_mobility([s.place((0, 0, 0)), s.place((0.5, 0, 0))], mu=1.0)
    with pytest.raises(ValueError, match="below the wall"):
        solve_mobility([s.place((0, 0, 0.5))], mu=1.0, wall=True)
    with pytest.raises(ValueError, match="rotation"):
        s.place((0, 0, 0), 2 * np.eye(3))
    with pytest.raises(ValueError, match="method"):
        solve_resistance(s.place(), U=(1, 0, 0), mu=1.0, method="lu")
    with pytest.raises(ValueError, match="external_force"):
        solve_mobility([s.place()], mu=1.0, external_force=np.ones((2, 3)))


def test_auto_choice():
    """ "auto": the reused factorization for one body in free space, a fresh LU for small sets,
    GMRES beyond DENSE_MAX_POINTS (docs/benchmarks.md); the override is obeyed."""
    from parastokes.mobility.choice import DENSE_MAX_POINTS, chosen_method
    from parastokes.mobility.system import SurfaceSet

    big, small = sphere(400), sphere(100)
    assert chosen_method(SurfaceSet([big.place()], MU, False), "auto") == "dense"
    assert chosen_method(SurfaceSet([big.place((0, 0, 2))], MU, True), "auto") == "gmres"
    pair = SurfaceSet([small.place((0, 0, 2)), small.place((3, 0, 2))], MU, True)
    assert pair.n_points <= DENSE_MAX_POINTS and chosen_method(pair, "auto") == "dense"
    assert chosen_method(pair, "gmres") == "gmres"


def test_factorization_kept_per_viscosity_and_not_pickled():
    """One body-frame factorization per viscosity, shared by every placement; a pickled surface
    leaves it behind (a worker makes its own) and solves the same."""
    import pickle

    s = RigidSurface(fibonacci_sphere(150), 0.5 * sphere_spacing(150))
    first = solve_resistance(s.place((1, 2, 3), Q), U=(1, 0, 0), mu=MU)
    assert s.self_factor(MU) is s.self_factor(MU) is not s.self_factor(2 * MU)
    copy = pickle.loads(pickle.dumps(s))
    assert copy._factors == {} and len(pickle.dumps(s)) < 20_000
    again = solve_resistance(copy.place((1, 2, 3), Q), U=(1, 0, 0), mu=MU)
    np.testing.assert_allclose(again.forces, first.forces, rtol=1e-12)


@pytest.mark.parametrize("method", ["dense", "gmres"])
def test_slip_in_the_body_frame(method):
    """A slip given in the body frame equals the same slip turned to the lab (both solvers); the
    reused factorization solves a body-frame slip once and then reuses it (same bits, at
    another placement as well)."""
    s = ellipsoid(150)
    rng = np.random.default_rng(5)
    slip_body = rng.normal(size=(len(s), 3))
    placed = s.place((0.0, 0.0, 3.0), Q)
    lab = solve_mobility(placed, mu=MU, slip=slip_body @ Q.T, method=method)
    body = solve_mobility(placed, mu=MU, slip=slip_body, slip_frame="body", method=method)
    for name in ("U", "Omega", "forces"):
        ref = getattr(lab, name)
        np.testing.assert_allclose(getattr(body, name), ref, atol=1e-9 * np.abs(ref).max())
    res = solve_resistance(placed, U=(1, 0, 0), slip=slip_body, slip_frame="body", mu=MU)
    res_lab = solve_resistance(placed, U=(1, 0, 0), slip=slip_body @ Q.T, mu=MU)
    np.testing.assert_allclose(res.forces, res_lab.forces, atol=1e-9 * np.abs(res.forces).max())
    if method == "dense":
        factor = s.self_factor(MU)
        assert any(np.array_equal(v[0], slip_body.ravel()) for v in factor._recent.values())
        q2 = rotation((0.0, 1.0, 1.0), 2.0)
        again = solve_mobility(
            s.place((5.0, 1.0, 0.0), q2), mu=MU, slip=slip_body, slip_frame="body"
        )
        np.testing.assert_allclose(q2.T @ again.U[0], Q.T @ body.U[0], rtol=1e-10)


def test_two_spheres_settling_stimson_jeffery():
    """Two spheres (200 points each) settling along their line of centers under equal forces
    move faster than one by 1/λ of Stimson & Jeffery (1926), within 1% at center distances
    2.26a-7.5a (GMRES, several bodies), and by the documented ratio (docs/numbers.toml
    [rigid_pairs]); the series tends to 0.645 at contact and to 1/(1 + 3a/(4d)) far apart."""
    from parastokes.mobility.two_spheres import stimson_jeffery

    assert stimson_jeffery(1.0001) == pytest.approx(0.645, abs=5e-4)
    assert stimson_jeffery(100.0) == pytest.approx(1 / (1 + 3 / 400), rel=1e-5)
    s = sphere(200, 1.0)
    single = solve_mobility(s.place(), mu=MU, external_force=(0, 0, -1)).U[0, 2]
    for i, d in enumerate((1.1276, 1.5431, 2.3524, 3.7622)):  # docs/validation.md's rows
        pair = solve_mobility(
            [s.place((0, 0, d)), s.place((0, 0, -d))], mu=MU, external_force=(0, 0, -1)
        )
        assert pair.info.method == "gmres"
        np.testing.assert_allclose(pair.U[:, 2] / single, 1 / stimson_jeffery(d), rtol=0.01)
        check("rigid_pairs", "ratio_200", float(np.mean(pair.U[:, 2]) / single), i)
