"""The spring-network sphere in shear flow (section 5.2; physics.md section 4)."""

import dataclasses

import numpy as np
import pytest

from parastokes import integrate, models, mrs
from parastokes.bodies import geometry
from parastokes.kinds.vesicle import reference
from parastokes.kinds.vesicle.mechanics import spring_forces


def deformed(ves, seed=0, size=0.02):
    rng = np.random.default_rng(seed)
    x = ves.initial_state()
    return x * np.array([1.05, 1.0, 0.97]) + size * rng.standard_normal(x.shape)


def test_defaults_are_the_papers():
    ves = models.vesicle()
    verts, tris = ves.mesh
    assert (len(verts), len(tris), len(ves.edges)) == (642, 1280, 1920)
    l_max = geometry.edge_lengths(verts, ves.edges).max()
    assert ves.epsilon == pytest.approx(0.3 * l_max) and l_max == pytest.approx(0.165, abs=5e-4)
    assert ves.params == {"epsilon": ves.epsilon, "viscosity": 1e-3, "stiffness": 0.1}
    assert ves.shear_rate == 0.1 and ves.monitor_limit == 1e-4
    np.testing.assert_allclose(ves.rest_lengths, geometry.edge_lengths(verts, ves.edges))


def test_forces_match_reference_and_balance():
    ves = models.vesicle()
    x = deformed(ves)
    f = ves.forces(x)
    np.testing.assert_allclose(
        f, reference.spring_forces(x, ves.edges, ves.rest_lengths, 0.1), rtol=0, atol=1e-16
    )
    assert np.abs(f).max() > 1e-3
    np.testing.assert_allclose(f.sum(0), 0.0, atol=1e-15)  # no net force
    np.testing.assert_allclose(np.cross(x, f).sum(0), 0.0, atol=1e-15)  # no net torque


def test_spring_force_direction_and_size():
    """A spring stretched by δ pulls both ends toward each other with force κ δ (eq. 14)."""
    x = np.array([[0.0, 0.0, 0.0], [1.5, 0.0, 0.0]])
    f = spring_forces(x, np.array([[0, 1]]), np.array([1.0]), 0.2)
    np.testing.assert_allclose(f, [[0.1, 0, 0], [-0.1, 0, 0]], rtol=1e-15)


def test_rest_shape_feels_only_the_shear_flow():
    ves = models.vesicle()
    x = ves.initial_state()
    assert np.abs(ves.forces(x)).max() == 0.0
    np.testing.assert_allclose(ves.rates(0.0, x), np.c_[0.1 * x[:, 2], 0 * x[:, :2]], atol=1e-17)


def test_rates_equal_plain_numpy():
    ves = models.vesicle(subdivisions=2)
    x = deformed(ves)
    f = reference.spring_forces(x, ves.edges, ves.rest_lengths, ves.stiffness)
    u = mrs.reference.velocity(x, x, f, epsilon=ves.epsilon, mu=ves.viscosity)
    u[:, 0] += 0.1 * x[:, 2]
    np.testing.assert_allclose(ves.rates(0.0, x), u, rtol=0, atol=1e-13 * np.abs(u).max())
    np.testing.assert_array_equal(ves.advance(x, u, 0.01), x + 0.01 * u)
    assert ves.project(x) is x


def test_deformed_vesicle_relaxes_to_its_sphere():
    """The springs pull an ellipsoid (same volume) back to the sphere: the sign of eq. (14)."""
    ves = models.vesicle(subdivisions=2, shear_rate=0.0)
    x0 = ves.initial_state() * np.array([1.02, 1.0, 1 / 1.02])

    def out_of_round(x):
        return np.abs(np.linalg.norm(x, axis=1) - 1.0).max()

    x = integrate.propagate(ves, x0, 0.0, 0.2, "rk2", 1e-3)
    assert out_of_round(x) < 0.25 * out_of_round(x0)
    assert ves.monitor(x) < ves.monitor(x0)
    np.testing.assert_allclose(x.mean(0), 0.0, atol=1e-12)  # no net force: no drift


def fit_rigid_motion(x, u):
    """Least-squares U, Ω with u ≈ U + Ω × (x - mean x); returns U, Ω and the largest residual."""
    r = x - x.mean(0)
    n = len(x)
    a = np.zeros((n, 3, 6))
    a[:, :, :3] = np.eye(3)
    a[:, 0, 4], a[:, 0, 5] = r[:, 2], -r[:, 1]
    a[:, 1, 5], a[:, 1, 3] = r[:, 0], -r[:, 2]
    a[:, 2, 3], a[:, 2, 4] = r[:, 1], -r[:, 0]
    coef = np.linalg.lstsq(a.reshape(3 * n, 6), u.ravel(), rcond=None)[0]
    return coef[:3], coef[3:], np.abs(u.ravel() - a.reshape(3 * n, 6) @ coef).max()


@pytest.mark.parametrize("radius", [1.0, 3.0])
def test_very_stiff_vesicle_rotates_rigidly_at_half_the_shear_rate(radius):
    """A nearly rigid sphere in shear turns at γ̇/2 whatever its size; what it lets through of the
    straining part of the shear grows with its size R and its capillary number μγ̇R/κ."""
    ves = models.vesicle(subdivisions=2, stiffness=1.0, radius=radius)
    capillary = ves.viscosity * ves.shear_rate * radius / ves.stiffness  # 1e-4 R
    x = integrate.propagate(ves, ves.initial_state(), 0.0, 0.2, "rk2", 2e-4)
    velocity, omega, residual = fit_rigid_motion(x, ves.rates(0.2, x))
    gamma = ves.shear_rate
    np.testing.assert_allclose(velocity, 0.0, atol=1e-12 * radius)
    np.testing.assert_allclose(omega, [0.0, gamma / 2, 0.0], rtol=0, atol=1e-5 * gamma)
    assert residual < 2e-3 * gamma * radius * capillary / 1e-4  # the straining is resisted
    assert ves.monitor(x) < 1e-6


def test_radius_scales_positions_rest_lengths_area_and_epsilon():
    unit = models.vesicle(subdivisions=2)
    big = models.vesicle(subdivisions=2, radius=2.5)
    assert models.vesicle(subdivisions=2, radius=1.0) == unit  # the default is the unit sphere
    np.testing.assert_allclose(big.initial_state(), 2.5 * unit.initial_state(), rtol=1e-15)
    np.testing.assert_allclose(big.rest_lengths, 2.5 * unit.rest_lengths, rtol=1e-15)
    assert big.initial_area == pytest.approx(2.5**2 * unit.initial_area, rel=1e-14)
    assert big.epsilon == pytest.approx(2.5 * unit.epsilon, rel=1e-15)  # ε = 0.3 l_max
    assert np.abs(big.forces(big.initial_state())).max() == 0.0  # at rest at its own size
    moved = dataclasses.replace(big, center=(1.0, 2.0, 3.0))
    np.testing.assert_allclose(moved.initial_state() - [1, 2, 3], big.initial_state(), atol=1e-15)


def test_vesicle_twice_the_size_with_twice_the_stiffness_moves_twice_as_fast():
    """x -> R x, ℓ⁰ -> R ℓ⁰, ε -> R ε, κ -> R κ: the spring forces scale by R, the Stokeslets by
    1/R (S_{Rε}(R r) = S_ε(r)/R) and u∞ = γ̇ z by R, so the rates and the whole evolution scale
    by R (self-similar in time)."""
    unit = models.vesicle(subdivisions=2)
    big = models.vesicle(subdivisions=2, stiffness=2 * unit.stiffness, radius=2.0)
    x = deformed(unit)
    u = unit.rates(0.0, x)
    assert np.abs(unit.forces(x)).max() > 1e-3
    np.testing.assert_allclose(big.rates(0.0, 2 * x), 2 * u, rtol=0, atol=1e-13 * np.abs(u).max())
    x = unit.initial_state() * np.array([1.003, 1.0, 1 / 1.003])  # within the area monitor
    x1 = integrate.propagate(unit, x, 0.0, 0.05, "rk2", 1e-3)
    x2 = integrate.propagate(big, 2 * x, 0.0, 0.05, "rk2", 1e-3)
    assert np.abs(x1 - x).max() > 1e-3  # it moved
    np.testing.assert_allclose(x2, 2 * x1, rtol=0, atol=1e-13)


def test_area_monitor_within_paper_limit_with_the_fine_step():
    ves = models.vesicle()  # 642 points, ε = 0.3 l_max, κ = 0.1
    res = integrate.run(ves, ves.initial_state(), 0.0, 0.3, "rk2", 1e-3)
    assert res.n_steps == 300
    assert 0 < res.max_monitor < ves.monitor_limit


def test_stiffness_scales_the_spring_forces():
    """(That each parameter changes alone is the contract check's, test_system_contract.py.)"""
    ves = models.vesicle(subdivisions=1)
    x = deformed(ves)
    np.testing.assert_allclose(
        ves.with_params(stiffness=0.05).forces(x), 0.5 * ves.forces(x), rtol=1e-14
    )
    with pytest.raises(ValueError, match="unknown parameter"):
        ves.with_params(bending=1.0)
    with pytest.raises(ValueError, match="stiffness"):
        ves.with_params(stiffness=0.0)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"subdivisions": -1}, "subdivisions"),
        ({"epsilon_factor": 0.0}, "epsilon_factor"),
        ({"stiffness": -0.1}, "stiffness"),
        ({"viscosity": 0.0}, "viscosity"),
        ({"n_threads": 0}, "n_threads"),
        ({"radius": 0.0}, "radius"),
        ({"radius": float("nan")}, "radius"),
    ],
)
def test_bad_vesicle_input_raises_naming_the_argument(kwargs, name):
    with pytest.raises(ValueError, match=name):
        models.vesicle(**kwargs)
