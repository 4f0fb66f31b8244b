"""The collective physics of many rigid spheres (validation/many_bodies.py; docs/validation.md,
"Many bodies"): a sedimenting cloud against Nitsche & Batchelor's (6/5) N a/R, a row of spheres
and a pair against the Rotne–Prager tensor and the two-sphere mobility functions."""

from __future__ import annotations

import numpy as np
import pytest
from documented import check

from parastokes.mobility.two_spheres import pair_mobility, stimson_jeffery
from validation import many_bodies as mb


def test_the_pair_series_agrees_with_stimson_and_jeffery_along_the_line():
    """The expansion of the two-sphere mobility functions against the exact series, its error
    falling as O(s⁻⁶); across the line it starts as the Rotne–Prager tensor."""
    errors = [abs(pair_mobility(2 * d)[0] - 1 / stimson_jeffery(d)) for d in (2.3524, 3.7622)]
    assert errors[0] < 1e-3 and errors[1] < 5e-5
    assert errors[0] / errors[1] > (3.7622 / 2.3524) ** 5
    s = 40.0
    assert pair_mobility(s)[1] - 1 == pytest.approx(0.75 / s, rel=1e-3)
    with pytest.raises(ValueError, match="must not overlap"):
        pair_mobility(2.0)


#: the clouds of the table (docs/numbers.toml [many_cloud]): (points, spheres, R, seed)
CLOUDS = [(n, count, radius, seed) for n, count, radius, seeds in mb.CLOUDS for seed in seeds]
#: the rows of the table ([many_row]): (points, spacing)
ROWS = [(n, spacing) for n, _, spacings in mb.ROWS for spacing in spacings]
#: largest relative difference from the Rotne–Prager sum, by spacing: O(a/r)⁴ reflections
ROW_TOLERANCE = {3.0: 4e-3, 4.0: 1e-3, 6.0: 2e-4}


def check_cloud(index: int) -> dict:
    n, count, radius, seed = CLOUDS[index]
    c = mb.cloud(n, count, radius, seed)
    for key in ("mean", "rotne_prager", "theory", "iterations", "fraction"):
        check("many_cloud", key, c[key], index)
    check("many_cloud", "collective", (c["mean"] - 1) / (c["theory"] - 1), index)
    return c


def check_row(index: int) -> None:
    """Nine spheres in a horizontal row falling across it: each within the spacing's tolerance
    of the Rotne–Prager sum with the sphere's a_eff; the middle falls fastest, the row is
    symmetric; a pair agrees with the two-sphere mobility functions to 5e-4."""
    n, spacing = ROWS[index]
    r = mb.row(n, 9, spacing)
    speeds, reference = np.array(r["speeds"]), np.array(r["rotne_prager"])
    np.testing.assert_allclose(speeds, reference, rtol=ROW_TOLERANCE[spacing])
    assert np.argmax(speeds) == 4 and min(speeds[0], speeds[-1]) == min(speeds)
    np.testing.assert_allclose(speeds, speeds[::-1], rtol=1e-4)  # Fibonacci points: not exact
    pair = mb.row(n, 2, spacing)
    assert pair["speeds"][0] == pytest.approx(pair["pair"], abs=5e-4)
    for key, value in (("end", speeds[0]), ("middle", speeds[4]), ("rp_end", reference[0]),
                       ("rp_middle", reference[4]),
                       ("difference", np.max(np.abs(speeds / reference - 1))),
                       ("pair", pair["speeds"][0]), ("series", pair["pair"])):
        check("many_row", key, float(value), index)


@pytest.mark.parametrize("index", [0, 1, 2], ids=["3a", "4a", "6a"])
def test_a_row_of_spheres_falls_as_rotne_prager_says(index):
    """Spheres of 42 points (0.31 %, 0.049 % and 0.005 % from Rotne–Prager at 3a, 4a, 6a)."""
    check_row(index)


@pytest.mark.slow
@pytest.mark.parametrize("index", [3, 4, 5], ids=["3a", "4a", "6a"])
def test_a_row_of_finer_spheres_falls_as_rotne_prager_says(index):
    """Spheres of 162 points: the same differences (reflections, not the discretization)."""
    check_row(index)


@pytest.mark.parametrize("index", range(6), ids=[f"n{c[1]}-seed{c[3]}" for c in CLOUDS[:6]])
def test_a_dilute_cloud_settles_faster_by_six_fifths_n_a_over_r(index):
    """30 and 100 spheres of 42 points at random in spheres of radius 8a and 12a (volume
    fraction 0.058): the mean speed over one sphere's (5.5, 11.4) is 1 + (6/5)(n - 1) a/R in
    its collective part to 5 % for 30 spheres (3.1 % at worst) and 3 % for 100 (1.3 %), and
    below the Rotne–Prager sum of the same configuration by 1-4 % (2.0 % in every cloud: the
    reflections between the spheres, which the pairwise sum leaves out, make the cloud a drop
    slightly more viscous than the fluid)."""
    c = check_cloud(index)
    tolerance = 0.05 if c["count"] < 100 else 0.03
    assert (c["mean"] - 1) / (c["theory"] - 1) == pytest.approx(1.0, abs=tolerance)
    assert 0.96 < c["mean"] / c["rotne_prager"] < 0.99


@pytest.mark.slow
@pytest.mark.parametrize("index", [6, 7, 8], ids=["42-seed1", "42-seed2", "162-seed1"])
def test_a_larger_cloud_settles_faster_by_six_fifths_n_a_over_r(index):
    """250 spheres in a sphere of radius 16a (volume fraction 0.061), and with 162 points per
    sphere: the collective part within 3 % of Nitsche & Batchelor's (0.6 % at worst)."""
    c = check_cloud(index)
    assert (c["mean"] - 1) / (c["theory"] - 1) == pytest.approx(1.0, abs=0.03)
    assert 0.96 < c["mean"] / c["rotne_prager"] < 0.99


def test_the_drop_flow_is_hadamard_and_rybczynskis_inside_flow():
    """The inside flow of a drop of viscosity ratio 1 (validation/many_bodies.py,
    ``drop_flow``): divergence-free, tangent to the drop's surface, mean zero over the ball,
    -1/4 (falling ahead) at the centre and +1/4 (lagging) at the equator's edge, its horizontal
    part inwards above the centre."""
    radius, h = 3.0, 1e-4
    rng = np.random.default_rng(0)
    points = rng.uniform(-radius, radius, (20000, 3))
    points = points[np.linalg.norm(points, axis=1) < radius]
    flow = mb.drop_flow(points, radius)
    assert np.abs(flow.mean(axis=0)).max() < 3e-3  # Monte Carlo: about 1.5e-3 per component
    divergence = sum(mb.drop_flow(points[:50] + h * e, radius)[:, k]
                     - mb.drop_flow(points[:50] - h * e, radius)[:, k]
                     for k, e in enumerate(np.eye(3))) / (2 * h)
    np.testing.assert_allclose(divergence, 0.0, atol=1e-9)
    surface = points / np.linalg.norm(points, axis=1)[:, None] * radius
    np.testing.assert_allclose(np.sum(surface * mb.drop_flow(surface, radius), axis=1), 0.0,
                               atol=1e-12)
    centre, edge = mb.drop_flow(np.array([[0.0, 0.0, 0.0], [radius, 0.0, 0.0]]), radius)
    np.testing.assert_allclose(centre, [0.0, 0.0, -0.25])
    np.testing.assert_allclose(edge, [0.0, 0.0, 0.25])
    assert mb.drop_flow(np.array([[1.0, 0.0, 1.0]]), radius)[0, 0] < 0 < mb.drop_flow(
        np.array([[1.0, 0.0, -1.0]]), radius)[0, 0]


def test_the_circulation_regression_finds_a_drop_and_its_sign():
    """Velocities made of the drop's flow (plus the fall, plus noise) give a slope of 1 and a
    correlation of 1 (0.9 with noise); the reversed flow a slope of -1."""
    rng = np.random.default_rng(1)
    centers = rng.uniform(-5, 5, (400, 3))
    centers = centers[np.linalg.norm(centers, axis=1) < 5] + [1.0, -2.0, 3.0]
    offsets = centers - centers.mean(axis=0)
    radius = np.sqrt(5 / 3 * np.mean(np.sum(offsets**2, axis=1)))
    collective = 6.0
    inside = collective * mb.drop_flow(offsets, radius)
    fall = np.array([0.0, 0.0, -1.0 - collective])
    found = mb.circulation(centers, fall + inside)
    assert found["drop_radius"] == pytest.approx(radius)
    assert found["collective"] == pytest.approx(collective - (inside[:, 2].mean()))
    for key in ("slope_z", "correlation_z", "slope_h", "correlation_h"):
        assert found[key] == pytest.approx(1.0, abs=0.02), key
    assert mb.circulation(centers, fall - inside)["slope_z"] == pytest.approx(-1.0, abs=0.02)
    noisy = mb.circulation(centers, fall + inside + 0.2 * rng.standard_normal(inside.shape))
    assert 0.8 < noisy["correlation_z"] < 0.99 and noisy["slope_z"] == pytest.approx(1, abs=0.1)


#: the clouds of the circulation table ([many_circulation]): (points, spheres, R, seed)
CIRCULATIONS = [(n, count, radius, seed) for n, count, radius, seeds in mb.CIRCULATIONS
                for seed in seeds]


def check_circulation(index: int) -> dict:
    """A cloud's spheres circulate as the inside of a Hadamard–Rybczynski drop of viscosity
    ratio 1: each sphere's velocity less the mean against the drop's flow, slope 1 less the
    reflections' 10 % (0.86-1.05 over the table) and correlation above 0.93; the slope of ours
    0.86-0.93 of the Rotne–Prager sum's of the same configuration (0.87-0.91 in the table)."""
    c = mb.cloud_circulation(*CIRCULATIONS[index])
    for key in ("radius", "drop_radius", "collective", "slope_z", "correlation_z", "slope_h",
                "correlation_h", "rp_slope_z", "rp_slope_h"):
        check("many_circulation", key, c[key], index)
    least = {30: 0.93, 100: 0.96, 250: 0.985}[c["count"]]
    for part in ("z", "h"):
        assert 0.85 < c[f"slope_{part}"] < 1.1
        assert c[f"correlation_{part}"] > least
        assert 0.86 < c[f"slope_{part}"] / c[f"rp_slope_{part}"] < 0.93
    return c


@pytest.mark.parametrize("index", range(6), ids=[f"n{c[1]}-seed{c[3]}" for c in CIRCULATIONS[:6]])
def test_a_cloud_circulates_as_a_hadamard_rybczynski_drop(index):
    """30 and 100 spheres (one solve each): correlation above 0.93 and 0.96 (0.94 and 0.965 at
    worst)."""
    check_circulation(index)


@pytest.mark.slow
@pytest.mark.parametrize("index", [6, 7, 8], ids=["seed1", "seed2", "seed3"])
def test_a_larger_cloud_circulates_as_a_hadamard_rybczynski_drop(index):
    """250 spheres: correlation above 0.985 (0.990 at worst)."""
    check_circulation(index)


def test_the_repulsion_pushes_close_spheres_apart_and_no_others():
    """Two spheres within the range push each other apart equally (4 weights at contact, a
    quarter of it half-way); beyond the range nothing."""
    gap = 0.5 * mb.REPULSION_RANGE
    forces = mb.repulsion(np.array([[0.0, 0.0, 0.0], [2.0 + gap, 0.0, 0.0],
                                    [0.0, 0.0, 2.0 + 1.01 * mb.REPULSION_RANGE]]))
    np.testing.assert_allclose(forces, [[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    assert mb.repulsion(np.array([[0.0, 0.0, 0.0], [0.0, 2.0, 0.0]]))[1, 1] == 4.0


def test_a_falling_cloud_circulates_over_a_finite_time():
    """30 spheres (R = 8a, seed 1) falling for 1 a/U₀ (0.7 R; ten RK2 steps): relative to the
    centroid, every sphere near the axis (ρ < 0.4 R_d) overtakes it (moves down) and those near
    the equator's edge (ρ > 0.6 R_d, |z| < 0.4 R_d) lag on average; the displacements over the
    time follow the drop's flow as the velocities do (slope 1.006, correlation 0.971
    vertically; 0.962, 0.959 horizontally)."""
    start = mb.cloud_centers(30, 8.0, 1)
    end = mb.fall(start, [0.0, 1.0], 0.1)[1]
    found = mb.circulation(start, end - start)
    offsets = (start - start.mean(axis=0)) / found["drop_radius"]
    moved = (end - start)[:, 2] - (end - start)[:, 2].mean()
    rho, z = np.hypot(offsets[:, 0], offsets[:, 1]), offsets[:, 2]
    axis, edge = rho < 0.4, (rho > 0.6) & (np.abs(z) < 0.4)
    assert axis.sum() >= 5 and edge.sum() >= 5
    assert moved[axis].max() < 0 < moved[edge].mean()
    for part in ("z", "h"):
        assert 0.85 < found[f"slope_{part}"] < 1.1
        assert found[f"correlation_{part}"] > 0.93


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_falling_cloud_loses_spheres_behind_it(seed):
    """30 spheres (R = 8a) falling for 25 a/U₀ (17 R; 40 s each): a few have left the cloud (1,
    3 and 3 of 30 for seeds 1-3), every one of them behind it (above, in the tail), none ahead
    or beside; the cloud's lowest sphere is still inside it (the front does not leak). The
    100-sphere run of docs/validation.md (``--tail``) shows the same over 28 R."""
    found = mb.tail(30, 8.0, seed, until=25.0, every=25.0)
    end = found["records"][-1]
    assert 1 <= end["left"] <= 4
    assert end["above"] == end["left"] and end["below"] == end["beside"] == 0
    assert end["highest"] > mb.TAIL_REACH
    assert end["fallen"] > 15
