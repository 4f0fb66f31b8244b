"""The resistance problem: given each body's rigid motion (U, Ω), the surface forces, and each
body's total force and torque (on the fluid).

Surface velocity u(x_i) = U + Ω × (x_i - c) + slip_i must equal the fluid velocity there,
(M f)_i + background_i, with M the regularized Stokeslet matrix (eq. 6; wall images (5)), so
M f = K Y + slip - background. The force and torque on the fluid, Kᵀ f, are minus the
hydrodynamic force and torque on the body.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .choice import solve
from .errors import SolveInfo
from .rigid import PlacedSurface, RigidSurface
from .system import SurfaceSet


@dataclass(frozen=True)
class ResistanceResult:
    """``forces`` (N, 3): point forces on the fluid, bodies in order; ``force``, ``torque``
    (B, 3): their totals per body (torque about each body's center); ``info``: how it went."""

    forces: np.ndarray
    force: np.ndarray
    torque: np.ndarray
    info: SolveInfo


def solve_resistance(
    surfaces: Sequence[PlacedSurface] | PlacedSurface,
    U=None,
    Omega=None,
    *,
    mu: float,
    wall: bool = False,
    slip=None,
    background=None,
    slip_frame: str = "lab",
    method: str = "auto",
    tol: float = 1e-10,
    precondition: str = "free",
    n_threads: int | None = None,
) -> ResistanceResult:
    """Point forces making every surface point move with its body's rigid motion.

    Parameters
    ----------
    surfaces : PlacedSurface or a sequence of them (:meth:`RigidSurface.place`)
    U, Omega : (B, 3) or (3,) arrays (one (3,) vector: all bodies), default 0
        Each body's translational velocity and angular velocity (about its center).
    mu, wall : viscosity; plane wall at z = 0.
    slip : (N, 3) array, optional
        Surface velocity relative to the rigid motion (a swimmer's surface motion).
    background : (N, 3) array, optional
        Velocity at the surface points induced by other forces (explicit bodies, a shear flow).
    slip_frame : "lab" or "body"
        The frame ``slip`` is given in: ``"body"``, each body's rows in its own frame (turned by
        its rotation). A single body in free space then solves a slip fixed in its frame (a
        squirmer's) once and reuses the result (no background) at every placement.
    method : "auto", "dense" or "gmres"
        Solver (:mod:`parastokes.mobility.choice`); ``tol``: GMRES relative residual.
    precondition : "free" or "wall"
        GMRES's block of each body (:mod:`parastokes.mobility.precondition`).
    n_threads : threads of the compiled kernels in GMRES's products.

    Raises
    ------
    parastokes.mobility.SolveError
        When the solve fails.
    ValueError
        For bad input (before any solve).
    """
    sset = SurfaceSet(surfaces, mu, wall, n_threads)
    y = np.concatenate([sset.body_vectors("U", U), sset.body_vectors("Omega", Omega)], axis=1)
    slip_lab, slip_body = sset.slip_vectors(slip, slip_frame)
    bg = sset.point_vectors("background", background)
    g_body = slip_body if not np.any(bg) else None
    f, _, info = solve(sset, slip_lab - bg, None, method, tol, precondition, y, g_body)
    totals = sset.reduce(f)
    return ResistanceResult(f.reshape(-1, 3), totals[:, :3], totals[:, 3:], info)


def resistance_matrix(
    surface: RigidSurface, center=(0.0, 0.0, 0.0), rotation=None, *, mu: float, wall: bool = False
) -> np.ndarray:
    """The 6x6 resistance matrix Kᵀ M⁻¹ K of one body: (F, T) on the fluid = R (U, Ω) (torque
    about ``center``). Free space: the reused body-frame one, rotated; with the wall: assembled
    and factorized at this placement."""
    from .direct import factor_for
    from .threads import blas_threads

    sset = SurfaceSet([surface.place(center, rotation)], mu, wall)
    with blas_threads(sset.n_threads):
        factor, _ = factor_for(sset)
    return np.array(factor.resistance)
