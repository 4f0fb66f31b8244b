"""The one place where rigid bodies call the mobility solve (docs/bodies.md, "Rigid bodies").

:func:`mobility` takes every rigid surface of one evaluation (lab-frame points, reference
point, ε, surface slip, external force and torque), the background velocity at the points and
the fluid, and returns each body's (U, Ω), the surface forces on the fluid and the residual: the
augmented system of Khatri & Cortez,

    Σ_j S_ε(x_i, x_j) f_j − U_k − Ω_k × (x_i − c_k) = u_s(x_i) − u_b(x_i)   (i on body k),
    Σ_{i on k} f_i = F_k,   Σ_{i on k} (x_i − c_k) × f_i = T_k,

with S_ε the regularized Stokeslet of docs/physics.md (1) (and the wall's images (5)).

One body in free space whose surface is fixed in its frame (``Surface.key`` set: a rigid shape)
is solved in its body frame, where the matrix does not change as it turns or moves: its LU
factorization is computed once per (shape, ε, μ) and kept (per process, a few bodies), and each
solve rotates the right-hand side in and the solution out (the free-space Stokeslet commutes with
rotations). The motion alone (what ``rates`` needs) is then six kept rows of the inverse times the
right-hand side, O(N); the forces (the flow field, a scene) one LU solve, O(N²). Otherwise the
matrix is assembled and factorized at every solve, O(N³).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg

from ... import mrs

__all__ = ["MobilitySolution", "Surface", "mobility", "skew"]


@dataclass(frozen=True)
class Surface:
    """One body's surface at one evaluation, in the lab frame: ``points`` (M, 3), reference point
    ``center``, blob width ``epsilon``, surface ``slip`` (M, 3) relative to the rigid motion,
    external ``force`` and ``torque`` on the body (about ``center``); when the surface is fixed
    in the body frame: ``rotation`` R (body -> lab), the body-frame points ``body`` X (``points``
    = center + X Rᵀ) and a hashable ``key`` that names X (the same X for every pose)."""

    points: np.ndarray
    center: np.ndarray
    epsilon: float
    slip: np.ndarray
    force: np.ndarray
    torque: np.ndarray
    rotation: np.ndarray | None = None
    body: np.ndarray | None = None
    key: Any = None


@dataclass(frozen=True)
class MobilitySolution:
    """Every body's velocity ``U`` (B, 3) and angular velocity ``Omega`` (B, 3), the surface
    forces on the fluid ``forces`` (Σ M, 3; None when not asked for) and the relative residual
    of the solve."""

    U: np.ndarray
    Omega: np.ndarray
    forces: Any
    residual: float


def skew(r: np.ndarray) -> np.ndarray:
    """[r]× of every row, (M, 3, 3): [r]× v = r × v."""
    out = np.zeros((len(r), 3, 3))
    out[:, 0, 1], out[:, 0, 2] = -r[:, 2], r[:, 1]
    out[:, 1, 0], out[:, 1, 2] = r[:, 2], -r[:, 0]
    out[:, 2, 0], out[:, 2, 1] = -r[:, 1], r[:, 0]
    return out


def stokeslet_matrix(points: np.ndarray, epsilon: np.ndarray, mu: float, wall: bool,
                     n_threads: int | None) -> np.ndarray:
    """The (3N, 3N) force -> velocity matrix at ``points``, each source with its own ε: entry
    (3i + a, 3j + b) is u_a(x_i) from a unit force e_b at x_j."""
    n = len(points)
    targets = np.broadcast_to(points, (n, n, 3))
    sources = np.ascontiguousarray(points[:, None, :])
    eps = np.ascontiguousarray(epsilon.reshape(n, 1))
    out = np.empty((3 * n, 3 * n))
    for b in range(3):
        forces = np.zeros((n, 1, 3))
        forces[:, 0, b] = 1.0
        u = mrs.velocity(targets, sources, forces, epsilon=eps, mu=np.full(n, mu), wall=wall,
                         n_threads=n_threads, check=False)
        out[:, b::3] = u.transpose(1, 2, 0).reshape(3 * n, n)
    return out


def _augmented(points: np.ndarray, centers: list[np.ndarray], counts: list[int],
               eps: np.ndarray, mu: float, wall: bool, n_threads: int | None) -> np.ndarray:
    """The matrix of the augmented system (see the module) of the bodies' ``points``."""
    n, nb = len(points), len(counts)
    size = 3 * n + 6 * nb
    a = np.zeros((size, size))
    a[: 3 * n, : 3 * n] = stokeslet_matrix(points, eps, mu, wall, n_threads)
    first = 0
    for k, (center, m) in enumerate(zip(centers, counts, strict=True)):
        rows = slice(3 * first, 3 * (first + m))
        col = 3 * n + 6 * k
        rigid = np.zeros((m, 3, 6))
        rigid[:, :, :3] = np.eye(3)
        rigid[:, :, 3:] = -skew(points[first : first + m] - center)  # U + Ω × r
        k_block = rigid.reshape(3 * m, 6)
        a[rows, col : col + 6] = -k_block
        a[col : col + 6, rows] = k_block.T
        first += m
    return a


def _relative(error: np.ndarray, rhs: np.ndarray) -> float:
    """‖error‖ / ‖rhs‖ (‖error‖ for a zero right-hand side)."""
    scale = float(np.linalg.norm(rhs))
    return float(np.linalg.norm(error)) / (scale if scale > 0.0 else 1.0)


def _rhs(slip: np.ndarray, loads: list[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    return np.concatenate([slip.ravel(), *(np.concatenate(load) for load in loads)])


#: Factorized body-frame systems by (key, ε, μ), newest last (a few per process): the LU
#: factors and their backward error (the relative residual of a solve with a random right-hand
#: side, measured once: a direct solve's residual does not depend on the right-hand side beyond
#: round-off, and measuring it at every solve would cost as much again as the solve).
_FACTORS: dict[tuple[Any, float, float], tuple[Any, np.ndarray, float]] = {}
_KEEP = 4


def _body_frame(s: Surface, mu: float) -> tuple[Any, np.ndarray, float]:
    """The LU factors of one free body's augmented system in its frame, the last six rows of its
    inverse (the motion (U, Ω) of any right-hand side, one product away) and their residual."""
    name = (s.key, float(s.epsilon), float(mu))
    found = _FACTORS.pop(name, None)
    if found is None:
        assert s.body is not None
        n = len(s.body)
        a = _augmented(np.ascontiguousarray(s.body), [np.zeros(3)], [n],
                       np.full(n, float(s.epsilon)), mu, False, None)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", scipy.linalg.LinAlgWarning)
            lu = scipy.linalg.lu_factor(a)
        if not np.all(np.diag(lu[0])):
            raise np.linalg.LinAlgError("Singular matrix")
        probe = np.random.default_rng(0).standard_normal(len(a))
        residual = _relative(a @ scipy.linalg.lu_solve(lu, probe) - probe, probe)
        last = np.zeros((len(a), 6))
        last[-6:, :] = np.eye(6)
        motion = np.ascontiguousarray(scipy.linalg.lu_solve(lu, last, trans=1).T)
        found = lu, motion, residual
        while len(_FACTORS) >= _KEEP:
            _FACTORS.pop(next(iter(_FACTORS)))
    _FACTORS[name] = found
    return found


def _solve_in_body_frame(s: Surface, mu: float, slip: np.ndarray, forces: bool
                         ) -> MobilitySolution:
    r = s.rotation
    assert r is not None
    lu, rows, residual = _body_frame(s, mu)
    rhs = _rhs(slip @ r, [(s.force @ r, s.torque @ r)])
    n = len(s.points)
    if forces:
        x = scipy.linalg.lu_solve(lu, rhs)
        f = x[: 3 * n].reshape(n, 3) @ r.T
    else:  # (U, Ω) only: six rows of the inverse, O(N) instead of O(N²)
        x = np.concatenate([np.zeros(3 * n), rows @ rhs])
        f = None
    return MobilitySolution((x[3 * n : 3 * n + 3] @ r.T)[None], (x[3 * n + 3 :] @ r.T)[None],
                            f, residual)


def mobility(surfaces: list[Surface], mu: float, wall: bool, background: np.ndarray | None,
             n_threads: int | None = None, forces: bool = True) -> MobilitySolution:
    """Solve the augmented mobility system of all ``surfaces`` at once (see the module);
    ``forces=False``: the motion only (``forces`` None where that is cheaper: one free rigid
    body, whose (U, Ω) are then six kept rows of the inverse times the right-hand side)."""
    slip = np.concatenate([s.slip for s in surfaces])
    if background is not None:
        slip = slip - background
    if len(surfaces) == 1 and not wall and surfaces[0].key is not None \
            and surfaces[0].body is not None and surfaces[0].rotation is not None:
        return _solve_in_body_frame(surfaces[0], mu, slip, forces)
    points = np.concatenate([s.points for s in surfaces])
    eps = np.concatenate([np.full(len(s.points), float(s.epsilon)) for s in surfaces])
    a = _augmented(points, [s.center for s in surfaces], [len(s.points) for s in surfaces],
                   eps, mu, wall, n_threads)
    rhs = _rhs(slip, [(s.force, s.torque) for s in surfaces])
    x = np.linalg.solve(a, rhs)
    residual = _relative(a @ x - rhs, rhs)
    n, nb = len(points), len(surfaces)
    motion = x[3 * n :].reshape(nb, 6)
    return MobilitySolution(motion[:, :3].copy(), motion[:, 3:].copy(),
                            x[: 3 * n].reshape(n, 3), residual)
