"""The collective physics of many rigid spheres (validation/many_bodies.py; docs/validation.md,
"Many bodies"): a sedimenting cloud against Nitsche & Batchelor's (6/5) N a/R, a row of spheres
and a pair against the Rotne–Prager tensor and the two-sphere mobility functions."""

from __future__ import annotations

import numpy as np
import pytest

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


@pytest.mark.parametrize(("spacing", "tolerance"), [(4.0, 1e-3), (6.0, 2e-4)])
def test_a_row_of_spheres_falls_as_rotne_prager_says(spacing, tolerance):
    """Nine spheres of 42 points in a horizontal row, falling across it: each within 0.1 %
    (spacing 4a; 0.02 % at 6a) of the Rotne–Prager sum with the sphere's a_eff (measured 0.05 %
    and 0.01 %); the middle falls fastest, the row is symmetric; a pair agrees with the
    two-sphere mobility functions to 5e-4."""
    r = mb.row(42, 9, spacing)
    speeds, reference = np.array(r["speeds"]), np.array(r["rotne_prager"])
    np.testing.assert_allclose(speeds, reference, rtol=tolerance)
    assert np.argmax(speeds) == 4 and speeds[0] == min(speeds)
    np.testing.assert_allclose(speeds, speeds[::-1], rtol=1e-4)  # Fibonacci points: not exact
    pair = mb.row(42, 2, spacing)
    assert pair["speeds"][0] == pytest.approx(pair["pair"], abs=5e-4)


@pytest.mark.parametrize("seed", [1, 2])
def test_a_dilute_cloud_settles_faster_by_six_fifths_n_a_over_r(seed):
    """100 spheres of 42 points at random in a sphere of radius 12a (volume fraction 0.058):
    the mean speed over one sphere's, 11.4, is 1 + (6/5)(n - 1) a/R to 3 % in its collective
    part (0.996 and 0.990 measured), and below the Rotne–Prager sum of the same configuration
    by 1-4 % (2.0 % measured: the reflections between the spheres, which the pairwise sum
    leaves out, make the cloud a drop slightly more viscous than the fluid)."""
    c = mb.cloud(42, 100, 12.0, seed)
    assert (c["mean"] - 1) / (c["theory"] - 1) == pytest.approx(1.0, abs=0.03)
    assert 0.96 < c["mean"] / c["rotne_prager"] < 0.99


@pytest.mark.slow
@pytest.mark.parametrize(("points", "seed"), [(42, 1), (42, 2), (162, 1)])
def test_a_larger_cloud_settles_faster_by_six_fifths_n_a_over_r(points, seed):
    """250 spheres in a sphere of radius 16a (volume fraction 0.061), and with 162 points per
    sphere: the collective part within 3 % of Nitsche & Batchelor's."""
    c = mb.cloud(points, 250, 16.0, seed)
    assert (c["mean"] - 1) / (c["theory"] - 1) == pytest.approx(1.0, abs=0.03)
    assert 0.96 < c["mean"] / c["rotne_prager"] < 0.99


@pytest.mark.slow
@pytest.mark.parametrize("spacing", [3.0, 4.0])
def test_a_row_of_finer_spheres_falls_as_rotne_prager_says(spacing):
    """The row with 162 points per sphere: within 0.4 % at spacing 3a (reflections, O(a/r)⁴),
    0.1 % at 4a."""
    r = mb.row(162, 9, spacing)
    np.testing.assert_allclose(r["speeds"], r["rotne_prager"], rtol=4e-3 if spacing < 4 else 1e-3)
