"""Two equal spheres settling together, used by the validation of several bodies: along their
line of centers, the exact series of Stimson & Jeffery (1926), Proc. R. Soc. Lond. A 111, 110;
along or across it, the far-field expansions of the two-sphere mobility functions.

Spheres of radius a, centers 2d apart, cosh α = d/a, moving with equal velocity U along the line
of centers: each feels the drag 6πμaU λ with

    λ = (4/3) sinh α Σ_{n≥1} n(n+1)/((2n-1)(2n+3)) ×
        [1 - (4 sinh²((n+½)α) - (2n+1)² sinh²α) / (2 sinh((2n+1)α) + (2n+1) sinh 2α)].

λ -> 1 far apart (as 1/(1 + 3a/(4d))) and -> 0.645 at contact.
"""

from __future__ import annotations

import math


def stimson_jeffery(d_over_a: float, rtol: float = 1e-15) -> float:
    """λ = drag / (6πμaU) of each of two spheres settling along their line of centers, with
    centers ``2 d`` apart (d/a = ``d_over_a`` > 1)."""
    if not d_over_a > 1.0:
        raise ValueError(f"d_over_a: the spheres must not overlap (d/a > 1), got {d_over_a}")
    a = math.acosh(d_over_a)
    total = 0.0
    for n in range(1, 100_000):
        k = 2 * n + 1
        num = 2 * math.sinh(k * a) + k * math.sinh(2 * a)
        den = 4 * math.sinh((n + 0.5) * a) ** 2 - k**2 * math.sinh(a) ** 2
        term = n * (n + 1) / ((2 * n - 1) * (2 * n + 3)) * (1 - den / num)
        total += term
        if abs(term) < rtol * abs(total):
            break
    return 4.0 / 3.0 * math.sinh(a) * total


def pair_mobility(s: float) -> tuple[float, float]:
    """The speed of each of two equal spheres under equal forces over one sphere's, along and
    across their line of centers (``s`` = center distance over radius, > 2): the two-sphere
    mobility functions of Batchelor (1976), J. Fluid Mech. 74, 1, summed to their O(s⁻⁶)
    terms (Jeffrey & Onishi 1984, J. Fluid Mech. 139, 261, give the higher ones),

        along:  A11 + A12 = 1 + 3/(2s) - 1/s³ - 15/(4s⁴),
        across: B11 + B12 = 1 + 3/(4s) + 1/(2s³) - 17/(16s⁶),

    whose error is O(s⁻⁶) along (O(s⁻⁷) across). The pairwise part, 3/(2s) - 1/s³ and
    3/(4s) + 1/(2s³), is the Rotne–Prager tensor's; the rest is the reflections between the
    two. Along the line, 1/λ of :func:`stimson_jeffery` at d/a = s/2 is the exact value."""
    if not s > 2.0:
        raise ValueError(f"s: the spheres must not overlap (s = r/a > 2), got {s}")
    return (1 + 1.5 / s - 1 / s**3 - 3.75 / s**4,
            1 + 0.75 / s + 0.5 / s**3 - 17 / (16 * s**6))
