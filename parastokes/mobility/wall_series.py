"""Exact and asymptotic wall corrections for a sphere of radius a whose center is at height h
above a no-slip plane wall, used by the validation (docs/validation.md, "Rigid bodies").

Each returns the drag (or torque) divided by its free-space value 6πμaU (or 8πμa³Ω).

- :func:`brenner_perpendicular`: translation toward the wall, the exact series of Brenner (1961),
  H. Brenner, Chem. Eng. Sci. 16, 242, eq. (2.19), in bipolar coordinates, cosh α = h/a.
- :func:`jeffery_rotation_normal`: rotation about the wall normal, the exact series of Jeffery
  (1915), G. B. Jeffery, Proc. London Math. Soc. 14, 327: sinh³α Σ csch³(nα).
- :func:`faxen_parallel`: translation along the wall, Faxén's far-field series to (a/h)⁵ (as
  quoted by Goldman, Cox & Brenner 1967 and Faucheux & Libchaber, PRE 49, 5158, 1994).
- :func:`gcb_parallel_translation`, :func:`gcb_parallel_rotation`: the near-wall (lubrication)
  asymptotes of Goldman, Cox & Brenner (1967), Chem. Eng. Sci. 22, 637, eqs. (2.65) and (3.13),
  for a gap δ = h - a ≪ a: 8/15 ln(a/δ) + 0.9588 (force, translation) and
  2/5 ln(a/δ) + 0.3817 (torque, rotation about an axis parallel to the wall).
"""

from __future__ import annotations

import math


def _alpha(h_over_a: float) -> float:
    if not h_over_a > 1.0:
        raise ValueError(f"h_over_a: the sphere must lie above the wall (h/a > 1), got {h_over_a}")
    return math.acosh(h_over_a)


def brenner_perpendicular(h_over_a: float, rtol: float = 1e-15) -> float:
    """Brenner's λ = F / (6πμaU) for a sphere moving normal to the wall:

    λ = (4/3) sinh α Σ_{n≥1} n(n+1)/((2n-1)(2n+3)) ×
        [(2 sinh((2n+1)α) + (2n+1) sinh 2α) / (4 sinh²((n+½)α) - (2n+1)² sinh²α) - 1],

    summed until a term falls below ``rtol`` of the sum (the terms decay like e^{-2nα})."""
    a = _alpha(h_over_a)
    total = 0.0
    for n in range(1, 100_000):
        k = 2 * n + 1
        num = 2 * math.sinh(k * a) + k * math.sinh(2 * a)
        den = 4 * math.sinh((n + 0.5) * a) ** 2 - k**2 * math.sinh(a) ** 2
        term = n * (n + 1) / ((2 * n - 1) * (2 * n + 3)) * (num / den - 1)
        total += term
        if abs(term) < rtol * abs(total):
            break
    return 4.0 / 3.0 * math.sinh(a) * total


def jeffery_rotation_normal(h_over_a: float, rtol: float = 1e-15) -> float:
    """Jeffery's T / (8πμa³Ω) for a sphere rotating about the wall normal: sinh³α Σ csch³(nα)."""
    a = _alpha(h_over_a)
    total = 0.0
    for n in range(1, 100_000):
        term = math.sinh(a) ** 3 / math.sinh(n * a) ** 3
        total += term
        if term < rtol * total:
            break
    return total


def faxen_parallel(h_over_a: float) -> float:
    """Faxén's F / (6πμaU) for translation parallel to the wall, q = a/h:
    1 / (1 - 9q/16 + q³/8 - 45q⁴/256 - q⁵/16); accurate far from the wall (h ≳ 2a)."""
    q = 1.0 / h_over_a
    return 1.0 / (1 - 9 * q / 16 + q**3 / 8 - 45 * q**4 / 256 - q**5 / 16)


def gcb_parallel_translation(gap_over_a: float) -> float:
    """Goldman, Cox & Brenner's near-wall F / (6πμaU), translation parallel to the wall:
    -8/15 ln(δ/a) + 0.9588 (eq. 2.65), for δ/a ≪ 1."""
    return -8.0 / 15.0 * math.log(gap_over_a) + 0.9588


def gcb_parallel_rotation(gap_over_a: float) -> float:
    """Goldman, Cox & Brenner's near-wall T / (8πμa³Ω), rotation about an axis parallel to the
    wall: -2/5 ln(δ/a) + 0.3817 (eq. 3.13), for δ/a ≪ 1."""
    return -2.0 / 5.0 * math.log(gap_over_a) + 0.3817
