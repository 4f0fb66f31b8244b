"""The Kirchhoff rod (section 5.1, eqs. 10-12, 36), its system, and the coarse-grid transfer."""

import dataclasses
import math
import pickle

import numpy as np
import pytest
from documented import check
from rods import helix_rod
from scipy.spatial.transform import Rotation

from parastokes import integrate, models, mrs
from parastokes.bodies import frames
from parastokes.kinds.rod import reference
from parastokes.kinds.rod.mechanics import rod_loads
from parastokes.kinds.rod.system import RodSystem


def bent_state(system, seed=0, size=0.05):
    """The initial state, smoothly bent and twisted, with orthonormal frames."""
    rng = np.random.default_rng(seed)
    x = system.initial_state()
    n = len(x)
    rot = Rotation.from_rotvec(size * np.cumsum(rng.standard_normal((n, 3)), axis=0) / 4)
    for i in range(3):
        x[:, 3 + 3 * i : 6 + 3 * i] = rot.apply(x[:, 3 + 3 * i : 6 + 3 * i])
    x[:, :3] += size * rng.standard_normal((n, 3))
    return x


def frame_error(x):
    return frames.orthonormality_error(x)


# ---- mechanics: eqs. (9)-(12) ---------------------------------------------------------------


@pytest.mark.parametrize("frequency", [40.0 * np.pi, -40.0 * np.pi, 0.0])
def test_preferred_strain_is_the_travelling_wave_of_eq_36(frequency):
    """Ω̂ = constant + (0, -k² A sin(k s + f t), 0) at s = (k + ½) Δs, for times up to the
    paper's T = 1 (the tabulated sin(k s), cos(k s) and the addition formula, to round-off)."""
    rod = models.rod_swimmer(n_points=301, frequency=frequency, preferred=(0.3, 0.0, -0.2))
    k = 2 * np.pi / rod.wavelength
    s = (np.arange(300) + 0.5) * rod.ds
    for t in (0.0, 1e-6, 0.37, 1.0):
        expected = np.zeros((300, 3)) + [0.3, 0.0, -0.2]
        expected[:, 1] -= k**2 * rod.amplitude * np.sin(k * s + frequency * t)
        np.testing.assert_allclose(rod.preferred_strain(t), expected, rtol=0, atol=1e-14)


def test_loads_match_plain_numpy_reference():
    rod = models.rod_swimmer(n_rods=3, n_points=41, epsilon=1.0)
    x = bent_state(rod, size=0.1)
    t = 0.013
    args = (3, rod.ds, np.full(3, 1.3), np.array([0.6, 0.7, 0.8]), rod.preferred_strain(t))
    f, n = rod_loads(x, *args)
    f_ref, n_ref = reference.rod_loads(x, *args)
    np.testing.assert_allclose(f, f_ref, rtol=0, atol=1e-13 * np.abs(f_ref).max())
    np.testing.assert_allclose(n, n_ref, rtol=0, atol=1e-13 * np.abs(n_ref).max())
    assert np.abs(f).max() > 0.01 and np.abs(n).max() > 0.01


def test_half_frame_strains_and_moments_analytic():
    """Two nodes whose frames differ by a rotation θ about e: Ω = 2 sin(θ/2)/Δs e (eqs. 9-11)."""
    ds, theta = 0.2, 0.3
    e = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    r0 = Rotation.from_rotvec([0.4, 0.1, -0.7])
    half = Rotation.from_rotvec(0.5 * theta * e) * r0
    r1 = Rotation.from_rotvec(theta * e) * r0
    h = half.as_matrix()  # columns: the half-point frame
    x = np.zeros((2, 12))
    x[0, 3:] = r0.as_matrix().T.ravel()
    x[1, 3:] = r1.as_matrix().T.ravel()
    x[1, :3] = ds * h[:, 2]  # ΔX = Δs H3: no shear or stretch
    a = np.array([1.0, 2.0, 3.0])
    f, n = rod_loads(x, 1, ds, a, np.array([0.6, 0.6, 0.6]), np.zeros((1, 3)))
    omega = 2 * math.sin(theta / 2) / ds * (h.T @ e)
    moment = h @ (a * omega)
    np.testing.assert_allclose(f, 0.0, atol=1e-15)
    np.testing.assert_allclose(n, [moment, -moment], rtol=1e-13)

    x[1, :3] = 1.1 * ds * h[:, 2]  # 10 % stretch: F = b3 · 0.1 · H3, pulls the ends together
    f, _ = rod_loads(x, 1, ds, a, np.array([0.6, 0.6, 0.5]), np.zeros((1, 3)))
    np.testing.assert_allclose(f, [0.05 * h[:, 2], -0.05 * h[:, 2]], rtol=1e-13)


@pytest.mark.parametrize("theta", [0.0, 1e-9, 2.5])
def test_half_frame_at_zero_tiny_and_large_angles(theta):
    """The branch-free half-angle formula holds at θ = 0 (identity), at tiny θ and at large θ."""
    ds = 0.2
    e = np.array([0.6, 0.0, -0.8])
    r0 = Rotation.from_rotvec([0.2, -0.3, 0.5])
    half = Rotation.from_rotvec(0.5 * theta * e) * r0
    x = np.zeros((2, 12))
    x[0, 3:] = r0.as_matrix().T.ravel()
    x[1, 3:] = (Rotation.from_rotvec(theta * e) * r0).as_matrix().T.ravel()
    h = half.as_matrix()
    x[1, :3] = 1.1 * ds * h[:, 2]  # the stretch force lies along the half-point tangent H3
    f, _ = rod_loads(x, 1, ds, np.ones(3), np.array([0.6, 0.6, 0.5]), np.zeros((1, 3)))
    np.testing.assert_allclose(f, [0.05 * h[:, 2], -0.05 * h[:, 2]], rtol=1e-12, atol=1e-15)


def test_half_turn_between_neighbours_gives_non_finite_loads():
    """θ = π has no unique half rotation: the loads are not finite (the integrator then stops)."""
    x = np.zeros((2, 12))
    x[0, 3:] = np.eye(3)[[1, 2, 0]].ravel()  # D1 = e_y, D2 = e_z, D3 = e_x
    x[1, 3:] = (np.eye(3)[[1, 2, 0]] * [[-1], [1], [-1]]).ravel()  # rotated by π about e_z
    x[1, :3] = [0.2, 0.0, 0.0]
    f, n = rod_loads(x, 1, 0.2, np.ones(3), np.full(3, 0.6), np.zeros((1, 3)))
    assert not (np.isfinite(f).all() and np.isfinite(n).all())


def test_loads_balance_force_and_torque():
    """Free ends: Σ f_k = 0 and Σ (n_k + X_k × f_k) = 0 (eq. 12 telescopes)."""
    rod = models.rod_swimmer(n_points=61)
    x = bent_state(rod, seed=3, size=0.2)
    f, n = rod.loads(0.02, x)
    scale = np.abs(n).max() * rod.length
    np.testing.assert_allclose(f.sum(0), 0.0, atol=1e-14 * np.abs(f).max() * len(f))
    np.testing.assert_allclose((n + np.cross(x[:, :3], f)).sum(0), 0.0, atol=1e-12 * scale)


def numpy_rates(system, t, x):
    f, n = reference.rod_loads(
        x,
        system.n_rods,
        system.ds,
        np.full(3, system.bending),
        np.array(system.shear),
        system.preferred_strain(t),
    )
    u, w = mrs.reference.velocity(
        x[:, :3], x[:, :3], f, epsilon=system.epsilon, mu=system.viscosity, torques=n,
        wall=system.wall, angular=True,
    )
    return np.concatenate([u, w], axis=1)


def test_compiled_step_equals_plain_numpy_step():
    """One RK2 step (Heun, physics.md section 3) of two rods near the wall, all in plain numpy."""
    rod = models.rod_swimmer(n_rods=2, n_points=16, epsilon=1.0)
    x = bent_state(rod, seed=5, size=0.1)
    t, dt = 0.004, 2e-6
    k1 = numpy_rates(rod, t, x)
    k2 = numpy_rates(rod, t + dt, reference.advance_rod(x, k1, dt))
    expected = reference.advance_rod(x, 0.5 * (k1 + k2), dt)
    np.testing.assert_allclose(rod.rates(t, x), k1, rtol=0, atol=1e-12 * np.abs(k1).max())
    got = integrate.step(rod, "rk2", t, x, dt)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-13)
    assert np.abs(got - x).max() > 1e-5  # the step moved something


# ---- frames -----------------------------------------------------------------------------------


def test_frames_stay_orthonormal_over_many_steps():
    rod = helix_rod()
    x = rod.initial_state()
    x0 = x
    for i in range(2000):  # raw steps: no projection
        x = integrate.step(rod, "rk2", 0.05 * i, x, 0.05)
    assert np.abs(x[:, 3:] - x0[:, 3:]).max() > 0.5  # the frames did turn (toward the helix)
    assert frame_error(x) < 1e-12


def test_project_restores_orthonormality():
    rod = models.rod_swimmer(n_points=31)
    x = bent_state(rod, seed=2, size=0.3)
    assert frame_error(x) < 1e-14
    np.testing.assert_allclose(rod.project(x), x, rtol=0, atol=1e-15)
    noisy = x + 1e-3 * np.random.default_rng(4).standard_normal(x.shape)
    fixed = rod.project(noisy)
    assert frame_error(noisy) > 1e-4 and frame_error(fixed) < 1e-14
    np.testing.assert_array_equal(fixed[:, :3], noisy[:, :3])
    u, _, vt = np.linalg.svd(noisy[:, 3:].reshape(-1, 3, 3))  # polar factor = nearest rotation
    np.testing.assert_allclose(fixed[:, 3:], (u @ vt).reshape(-1, 9), atol=1e-14)
    flipped = x.copy()
    flipped[0, 3:6] *= -1
    with pytest.raises(ValueError, match="left-handed"):
        rod.project(flipped)


# ---- dynamics -----------------------------------------------------------------------------------


def test_straight_rod_without_preferred_curvature_stays_at_rest():
    rod = models.rod(n_points=31, epsilon=1.0, length=6.0)  # above the wall, no shear flow
    x0 = rod.initial_state()
    # round-off forces (~1e-16) over μ = 1e-6: velocities ~1e-11 μm/s against ~100 for a swimmer
    assert np.abs(rod.rates(0.0, x0)).max() < 1e-10
    np.testing.assert_allclose(
        integrate.propagate(rod, x0, 0.0, 1e-3, "rk2", 1e-5), x0, rtol=0, atol=1e-13
    )


def curvature_torsion(x, ds):
    d1 = np.gradient(x[:, :3], ds, axis=0)
    d2 = np.gradient(d1, ds, axis=0)
    d3 = np.gradient(d2, ds, axis=0)
    c = np.cross(d1, d2)
    kappa = np.linalg.norm(c, axis=1) / np.linalg.norm(d1, axis=1) ** 3
    tau = np.einsum("ij,ij->i", c, d3) / np.einsum("ij,ij->i", c, c)
    return kappa[4:-4], tau[4:-4]


def test_free_rod_relaxes_to_helix():
    kappa, tau = 1.0, 0.5
    rod = helix_rod(preferred=(kappa, 0.0, tau))
    x = integrate.propagate(rod, rod.initial_state(), 0.0, 120.0, "rk2", 0.05)
    assert np.abs(rod.rates(120.0, x)).max() < 1e-4  # at rest
    k, t = curvature_torsion(x, rod.ds)
    np.testing.assert_allclose(k, kappa, rtol=0.01)  # O(Δs²) discretization
    np.testing.assert_allclose(t, tau, rtol=0.01)
    check("physics_core", "helix_curvature", float(k.mean()))  # docs/validation.md section 3
    check("physics_core", "helix_torsion", float(t.mean()))


def test_swimmer_swims_against_its_wave():
    """sin(k s + f t) travels toward -s for f > 0: the rod swims toward +x, and for f < 0 back.

    With L = 2λ, reversing s and reflecting y maps one beat onto the other, so the two drifts are
    mirror images (x and y flip, z stays) to round-off.
    """
    drifts = []
    for sign in (1, -1):
        rod = models.rod_swimmer(n_points=61, epsilon=2.0, frequency=sign * 40 * math.pi)
        x0 = rod.initial_state()
        res = integrate.run(rod, x0, 0.0, 0.05, "rk2", 5e-5)  # one beat period
        drifts.append(res.state[:, :3].mean(0) - x0[:, :3].mean(0))
        assert np.ptp(res.state[:, 1]) == pytest.approx(2 * rod.amplitude, rel=0.1)
        assert res.max_monitor < rod.monitor_limit
    plus, minus = drifts
    check("physics_core", "swimmer_drift_x", plus[0])  # ~0.11 per beat, docs/validation.md
    assert abs(plus[2]) < 0.05 * plus[0]
    np.testing.assert_allclose(minus, plus * [-1, -1, 1], rtol=0, atol=1e-9)


def test_paper_swimmer_with_the_fine_step_keeps_its_length():
    rod = models.rod_swimmer()  # Table 2, M = 301, ε = 5 σ_f
    assert (rod.n_points, rod.ds, rod.epsilon, rod.height) == (301, pytest.approx(0.2), 1.0, 10.0)
    x0 = rod.initial_state()
    res = integrate.run(rod, x0, 0.0, 3e-4, "rk2", 1e-6)
    assert res.n_steps == 300
    assert res.max_monitor < rod.monitor_limit
    assert np.abs(res.state[:, 1]).max() > 1e-3  # the beat has begun (in the plane z = 10)


@pytest.mark.slow
def test_paper_swimmer_one_beat_period_with_the_fine_step():
    """Table 2 swimmer, M = 301, τ_f = 1e-6, one period 2π/f = 0.05 (5e4 RK2 steps, minutes)."""
    rod = models.rod_swimmer()
    x0 = rod.initial_state()
    res = integrate.run(rod, x0, 0.0, 0.05, "rk2", 1e-6)
    drift = res.state[:, :3].mean(0) - x0[:, :3].mean(0)
    assert res.max_monitor < rod.monitor_limit
    assert drift[0] > 0.05 and abs(drift[2]) < 0.05 * drift[0]
    assert np.ptp(res.state[:, 1]) == pytest.approx(2 * rod.amplitude, rel=0.15)


def test_five_rods_interact_through_the_fluid():
    five = models.rod_swimmer(n_rods=5, n_points=61)
    one = models.rod_swimmer(n_rods=1, n_points=61)
    assert np.ptp(five.initial_state()[:, 1]) == pytest.approx(20.0)  # 5 μm apart in y
    shift = np.zeros(12)
    shift[1] = 5.0
    x5 = np.concatenate([bent_state(one, seed=1) + (j - 2) * shift for j in range(5)])
    x1 = x5[2 * 61 : 3 * 61]
    f5 = five.loads(0.01, x5)[0]
    f1 = one.loads(0.01, x1)[0]
    np.testing.assert_array_equal(f5[2 * 61 : 3 * 61], f1)  # mechanics is per rod
    u5, u1 = five.rates(0.01, x5)[2 * 61 : 3 * 61], one.rates(0.01, x1)
    assert 1e-3 < np.abs(u5 - u1).max() / np.abs(u1).max() < 1  # the neighbours' flow is felt


# ---- parameters and construction -----------------------------------------------------------


def test_parameters_enter_the_rates_as_the_physics_says():
    """(That each parameter changes alone is the contract check's, test_system_contract.py.)"""
    rod = models.rod_swimmer(n_points=31)
    assert rod.params == {"epsilon": 1.0, "viscosity": 1e-6, "bending": 1.0}
    x = bent_state(rod, seed=7)
    base = rod.rates(0.01, x)
    np.testing.assert_allclose(rod.with_params(viscosity=2e-6).rates(0.01, x), base / 2, rtol=1e-13)
    f, n = rod.loads(0.01, x)
    f8, n8 = rod.with_params(bending=0.8).loads(0.01, x)
    np.testing.assert_array_equal(f8, f)  # a1 = a2 = a3 enter the moments only
    lever = n - rod.with_params(bending=1e-300).loads(0.01, x)[1]
    np.testing.assert_allclose(n8 - (n - lever), 0.8 * lever, rtol=1e-10, atol=1e-15)
    with pytest.raises(ValueError, match="unknown parameter"):
        rod.with_params(stiffness=0.2)
    with pytest.raises(ValueError, match="epsilon"):
        rod.with_params(epsilon=-1.0)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"n_points": -3}, "n_points"),
        ({"n_points": 2}, "n_points"),
        ({"n_rods": 0}, "n_rods"),
        ({"epsilon": 0.0}, "epsilon"),
        ({"viscosity": -1e-6}, "viscosity"),
        ({"bending": 0.0}, "bending"),
        ({"height": 0.0}, "height"),
        ({"n_threads": 0}, "n_threads"),
        ({"n_threads": "2"}, "n_threads"),
    ],
)
def test_bad_rod_input_raises_naming_the_argument(kwargs, name):
    with pytest.raises(ValueError, match=name):
        models.rod_swimmer(**kwargs)


def test_monitor_is_largest_relative_length_change():
    rod = models.rod_swimmer(n_rods=2, n_points=11, length=10.0)
    x = rod.initial_state()
    assert rod.monitor(x) == 0.0 and rod.monitor_limit == 0.01
    x[11:, 0] *= 1.02  # stretch the second rod by 2 %
    assert rod.monitor(x) == pytest.approx(0.02)


# ---- coarse grid (Remark 4) ---------------------------------------------------------------------


def smooth_state(n_points, length=60.0):
    """A smooth 3D curve (parametrized by s) with its Frenet-like frame (D3 the tangent)."""
    s = np.linspace(0.0, length, n_points)
    k = 2 * math.pi / 30.0
    pos = np.stack([s, np.sin(k * s), 10 + 0.5 * np.cos(0.5 * k * s)], axis=1)
    tangent = np.stack([np.ones_like(s), k * np.cos(k * s), -0.25 * k * np.sin(0.5 * k * s)], 1)
    d3 = tangent / np.linalg.norm(tangent, axis=1, keepdims=True)
    d1 = np.cross([0.0, 0.0, 1.0], d3)
    d1 /= np.linalg.norm(d1, axis=1, keepdims=True)
    d2 = np.cross(d3, d1)
    return np.concatenate([pos, d1, d2, d3], axis=1)


def test_coarsened_system_and_transfer():
    rod = models.rod_swimmer()
    coarse, transfer = rod.coarsened(6)
    assert coarse.n_points == 51 and coarse.ds == pytest.approx(1.2)
    assert coarse.epsilon == rod.epsilon and coarse.params == rod.params
    np.testing.assert_allclose(transfer.restrict(rod.initial_state()), coarse.initial_state(),
                               atol=1e-13)
    with pytest.raises(ValueError, match="factor"):
        rod.coarsened(7)
    assert pickle.loads(pickle.dumps(transfer)) == transfer


def test_restrict_prolong_reproduces_a_smooth_rod_to_spline_accuracy():
    shift = np.zeros(12)
    shift[1] = 5.0
    fine = np.concatenate([smooth_state(301), smooth_state(301) + shift])
    fourth = (2 * math.pi / 30.0) ** 4  # largest fourth derivative of the curve (y component)
    errors = []
    for factor in (3, 6):
        _, transfer = models.rod_swimmer(n_rods=2).coarsened(factor)
        coarse = transfer.restrict(fine)
        assert coarse.shape == (2 * (300 // factor + 1), 12)
        back = transfer.prolong(coarse)
        assert frame_error(back) < 1e-14
        np.testing.assert_allclose(transfer.restrict(back), coarse, atol=1e-12)
        errors.append(np.abs(back[:, :3] - fine[:, :3]).max())
        # the classical cubic-spline bound (5/384) h^4 max|f''''| with h = σ_c
        assert errors[-1] < 5 / 384 * (0.2 * factor) ** 4 * fourth
        assert np.abs(back[:, 3:] - fine[:, 3:]).max() < 1e-4
    assert math.log2(errors[1] / errors[0]) > 3.5  # at least fourth order in σ_c
    check("rod_transfer", "restrict_prolong_error", errors)


def test_rod_system_is_a_dataclass_of_scalars():
    rod = RodSystem()
    assert not any(isinstance(getattr(rod, f.name), np.ndarray) for f in dataclasses.fields(rod))
