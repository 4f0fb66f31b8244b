"""Public factories of the paper's model problems (fixed names, design.md), defaults = the paper's.

- :func:`rod_swimmer`: rod-like swimmers above a wall (section 5.1, Table 2, eq. 36).
- :func:`rod`: a general Kirchhoff rod (constant preferred strain, e.g. (κ, 0, τ) for a helix or 0
  for a straight rod at rest; free space or above the wall).
- :func:`vesicle`: the elastic sphere in shear flow (section 5.2).
"""

from __future__ import annotations

import math

from .bodies import geometry
from .system import RodSystem, VesicleSystem

__all__ = ["rod", "rod_swimmer", "vesicle"]

#: Table 2 of the paper (units μm, s, g).
TABLE2 = {
    "length": 60.0,
    "amplitude": 1.0,
    "frequency": 40.0 * math.pi,
    "wavelength": 30.0,
    "bending": 1.0,
    "shear": (0.6, 0.6, 0.6),
    "height": 10.0,
    "viscosity": 1e-6,
}


def rod(
    n_rods: int = 1,
    n_points: int = 301,
    epsilon: float = 1.0,
    *,
    length: float = TABLE2["length"],
    preferred: tuple[float, float, float] = (0.0, 0.0, 0.0),
    amplitude: float = 0.0,
    wavelength: float = TABLE2["wavelength"],
    frequency: float = 0.0,
    bending: float = TABLE2["bending"],
    shear: tuple[float, float, float] = TABLE2["shear"],
    viscosity: float = TABLE2["viscosity"],
    wall: bool = True,
    height: float = TABLE2["height"],
    spacing: float = 5.0,
    n_threads: int | None = None,
) -> RodSystem:
    """Kirchhoff rods, initially straight along x: X(s) = (s, y_j, height), D3 = e_x, D1 = e_y,
    D2 = e_z, with preferred strain ``preferred + (0, -k² A sin(k s + f t), 0)``, k = 2π/λ.

    ``epsilon`` is absolute (μm); ``bending`` = a1 = a2 = a3; ``shear`` = (b1, b2, b3); rods are
    ``spacing`` apart in y. ``wall=False`` puts the rods in free space.
    """
    return RodSystem(
        n_rods=n_rods,
        n_points=n_points,
        length=float(length),
        epsilon=epsilon,
        viscosity=viscosity,
        bending=bending,
        shear=tuple(float(b) for b in shear),
        preferred=tuple(float(p) for p in preferred),
        amplitude=float(amplitude),
        wavelength=wavelength,
        frequency=float(frequency),
        wall=wall,
        height=float(height),
        spacing=spacing,
        n_threads=n_threads,
    )


def rod_swimmer(
    n_rods: int = 1,
    n_points: int = 301,
    epsilon: float = 1.0,
    *,
    amplitude: float = TABLE2["amplitude"],
    frequency: float = TABLE2["frequency"],
    wavelength: float = TABLE2["wavelength"],
    **kwargs,
) -> RodSystem:
    """The paper's swimmer (section 5.1): Table 2 values, M = 301 (Δs = σ_f = 0.2), ε = 5 σ_f,
    above the wall z = 0 at height 10, preferred strain Ω̂ = (0, -k² A sin(k s + f t), 0) (eq. 36).

    ``frequency`` may be negative (the authors' own code uses sin(k s - f t)). ``n_rods`` rods lie
    side by side in y, 5 μm apart (section 5.1.4 uses five). Other keywords go to :func:`rod`.
    """
    return rod(
        n_rods,
        n_points,
        epsilon,
        amplitude=amplitude,
        frequency=frequency,
        wavelength=wavelength,
        **kwargs,
    )


def vesicle(
    subdivisions: int = 3,
    epsilon_factor: float = 0.3,
    stiffness: float = 0.1,
    viscosity: float = 1e-3,
    shear_rate: float = 0.1,
    *,
    n_threads: int | None = None,
) -> VesicleSystem:
    """The elastic unit sphere of section 5.2: icosphere (642 points at level 3), Hookean edge
    springs of stiffness κ = ``stiffness``, free-space Stokeslets with ε = ``epsilon_factor`` ·
    l_max (l_max the longest edge, ≈ 0.165), shear flow u∞ = (γ̇ z, 0, 0)."""
    if not (isinstance(epsilon_factor, int | float) and epsilon_factor > 0):
        raise ValueError(f"epsilon_factor: must be > 0, got {epsilon_factor!r}")
    verts, tris = geometry.icosphere(subdivisions)
    l_max = float(geometry.edge_lengths(verts, geometry.mesh_edges(tris)).max())
    return VesicleSystem(
        subdivisions=subdivisions,
        epsilon=epsilon_factor * l_max,
        viscosity=viscosity,
        stiffness=stiffness,
        shear_rate=shear_rate,
        n_threads=n_threads,
    )
