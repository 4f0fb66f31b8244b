"""Points on a sphere for the validation: the Fibonacci (golden-spiral) lattice, nearly
uniform, every point with the same area 4πa²/N."""

from __future__ import annotations

import numpy as np


def fibonacci_sphere(n: int, radius: float = 1.0) -> np.ndarray:
    """``n`` points (n, 3) on the sphere of ``radius``: z_k = 1 - (2k + 1)/n, azimuth k × the
    golden angle π(3 - √5)."""
    if n < 2:
        raise ValueError(f"n: must be >= 2, got {n}")
    k = np.arange(n)
    z = 1.0 - (2 * k + 1) / n
    rho = np.sqrt(1.0 - z * z)
    phi = k * np.pi * (3.0 - np.sqrt(5.0))
    return radius * np.stack([rho * np.cos(phi), rho * np.sin(phi), z], axis=1)


def sphere_spacing(n: int, radius: float = 1.0) -> float:
    """The mean spacing h = sqrt(4πa²/n) of ``n`` evenly spread points (ε is tied to it)."""
    return float(np.sqrt(4 * np.pi * radius**2 / n))
