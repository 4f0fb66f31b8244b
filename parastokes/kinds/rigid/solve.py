"""The one place where rigid bodies call the mobility solve (docs/bodies.md, "Rigid bodies").

:func:`mobility` takes every rigid surface of one evaluation (lab-frame points, reference
point, ε, surface slip, external force and torque), the background velocity at the points and
the fluid, and hands them to :func:`parastokes.mobility.solve_mobility`: the augmented system of
Khatri & Cortez,

    Σ_j S_ε(x_i, x_j) f_j − U_k − Ω_k × (x_i − c_k) = u_s(x_i) − u_b(x_i)   (i on body k),
    Σ_{i on k} f_i = F_k,   Σ_{i on k} (x_i − c_k) × f_i = T_k,

with S_ε the regularized Stokeslet of docs/physics.md (1) (and the wall's images (5)); direct or
GMRES as :mod:`parastokes.mobility.choice` picks. A surface fixed in its body frame (a rigid
shape: ``Surface.key`` set) keeps one :class:`parastokes.mobility.RigidSurface` per (shape, ε) in
this process, so that a free body's body-frame factorization is made once and reused at every
pose; a surface with a moving part (a bacterium's flagellum) is a new one at every solve.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...mobility import PlacedSurface, RigidSurface, SolveInfo, solve_mobility

__all__ = ["MobilitySolution", "Surface", "mobility"]


@dataclass(frozen=True)
class Surface:
    """One body's surface at one evaluation, in the lab frame: ``points`` (M, 3), reference point
    ``center``, blob width ``epsilon``, surface ``slip`` (M, 3) relative to the rigid motion,
    external ``force`` and ``torque`` on the body (about ``center``), ``rotation`` R (body ->
    lab) and the body-frame points ``body`` X (``points`` = center + X Rᵀ); ``key``: a hashable
    name of X when the surface is fixed in its body frame (the same X at every pose), else None."""

    points: np.ndarray
    center: np.ndarray
    epsilon: float
    slip: np.ndarray
    force: np.ndarray
    torque: np.ndarray
    rotation: np.ndarray
    body: np.ndarray
    key: Any = None
    name: str = "body"


@dataclass(frozen=True)
class MobilitySolution:
    """Every body's velocity ``U`` (B, 3) and angular velocity ``Omega`` (B, 3), the surface
    forces on the fluid ``forces`` (Σ M, 3) and how the solve went (``info``: method,
    iterations, relative residual, whether a factorization was reused)."""

    U: np.ndarray
    Omega: np.ndarray
    forces: np.ndarray
    info: SolveInfo

    @property
    def residual(self) -> float:
        return float(self.info.residual)


#: Rigid surfaces (with their kept factorizations) by (key, ε), newest last; a few per process.
_SURFACES: dict[tuple[Any, float], RigidSurface] = {}
_KEEP = 4
_KEPT = threading.Lock()


def _rigid_surface(s: Surface) -> RigidSurface:
    if s.key is None:
        return RigidSurface(s.body, float(s.epsilon), name=s.name, check=False)
    name = (s.key, float(s.epsilon))
    with _KEPT:  # (threads of hosted solves share the surfaces)
        found = _SURFACES.pop(name, None)
        if found is None:
            found = RigidSurface(s.body, float(s.epsilon), name=s.name, check=False)
            while len(_SURFACES) >= _KEEP:
                _SURFACES.pop(next(iter(_SURFACES)))
        _SURFACES[name] = found
        return found


def placed(s: Surface) -> PlacedSurface:
    """``s`` as a :class:`parastokes.mobility.PlacedSurface` (its rigid surface kept when fixed
    in its body frame)."""
    return _rigid_surface(s).place(s.center, s.rotation, s.name)


def mobility(surfaces: list[Surface], mu: float, wall: bool, background: np.ndarray | None,
             n_threads: int | None = None) -> MobilitySolution:
    """Solve the augmented mobility system of all ``surfaces`` at once (see the module);
    :class:`parastokes.mobility.SolveError` when the solve fails."""
    result = solve_mobility(
        [placed(s) for s in surfaces], mu=mu, wall=wall,
        external_force=np.array([s.force for s in surfaces]),
        external_torque=np.array([s.torque for s in surfaces]),
        slip=np.concatenate([s.slip for s in surfaces]), background=background,
        n_threads=n_threads)
    return MobilitySolution(result.U, result.Omega, result.forces, result.info)
