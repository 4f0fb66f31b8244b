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
