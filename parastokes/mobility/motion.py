"""The mobility problem: the augmented system of Khatri & Cortez (unknown surface forces and
each body's (U, Ω)).

For bodies b with surface points x_i, centers c_b, external force F_b and torque T_b on the body
(gravity, a magnetic torque, a tether), find the point forces f (on the fluid) and (U_b, Ω_b):

    M f - K Y = slip - background      (each point moves rigidly, plus its slip)
    Kᵀ f     = (F_ext, T_ext)          (force and torque balance)

Sign: f is the force the body exerts on the fluid, so without inertia the body passes its
external load on to the fluid: Σ f = F_ext and Σ (x - c) × f = T_ext (a sphere sinking under
F_ext = -m g e_z pushes the fluid down, Σ f = -m g e_z, and moves at U = F_ext / (6πμa)). A
force-free swimmer has F_ext = T_ext = 0.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .choice import solve
from .errors import SolveInfo
from .rigid import PlacedSurface
from .system import SurfaceSet


@dataclass(frozen=True)
class MobilityResult:
    """``U``, ``Omega`` (B, 3): each body's velocity and angular velocity; ``forces`` (N, 3):
    point forces on the fluid, bodies in order; ``info``: how it went."""

    U: np.ndarray
    Omega: np.ndarray
    forces: np.ndarray
    info: SolveInfo


def solve_mobility(
    surfaces: Sequence[PlacedSurface] | PlacedSurface,
    *,
    mu: float,
    wall: bool = False,
    external_force=None,
    external_torque=None,
    slip=None,
    background=None,
    slip_frame: str = "lab",
    method: str = "auto",
    tol: float = 1e-10,
    precondition: str = "free",
    n_threads: int | None = None,
) -> MobilityResult:
    """Each body's rigid motion and the surface forces under external loads (see the module).

    ``external_force``, ``external_torque``: (B, 3) or (3,) (all bodies), default 0, on the
    body, torque about its center; ``slip``, ``background``, ``slip_frame``: (N, 3) as in
    :func:`parastokes.mobility.solve_resistance`; ``method``, ``tol``, ``precondition``,
    ``n_threads``: the solver as there.

    Raises :class:`parastokes.mobility.SolveError` when the solve fails, ``ValueError`` for bad
    input (before any solve).
    """
    sset = SurfaceSet(surfaces, mu, wall, n_threads)
    ft = np.concatenate(
        [
            sset.body_vectors("external_force", external_force),
            sset.body_vectors("external_torque", external_torque),
        ],
        axis=1,
    )
    slip_lab, slip_body = sset.slip_vectors(slip, slip_frame)
    bg = sset.point_vectors("background", background)
    g_body = slip_body if not np.any(bg) else None
    f, y, info = solve(sset, slip_lab - bg, ft, method, tol, precondition, g_body=g_body)
    return MobilityResult(y[:, :3].copy(), y[:, 3:].copy(), f.reshape(-1, 3), info)
