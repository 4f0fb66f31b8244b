"""The one place where rigid bodies call the mobility solve (docs/bodies.md, "Rigid bodies").

:func:`mobility` takes every rigid surface of one evaluation (lab-frame points, reference
point, ε, surface slip, external force and torque), the background velocity at the points and
the fluid, and returns each body's (U, Ω), the surface forces on the fluid and the residual: the
augmented system of Khatri & Cortez,

    Σ_j S_ε(x_i, x_j) f_j − U_k − Ω_k × (x_i − c_k) = u_s(x_i) − u_b(x_i)   (i on body k),
    Σ_{i on k} f_i = F_k,   Σ_{i on k} (x_i − c_k) × f_i = T_k,

with S_ε the regularized Stokeslet of docs/physics.md (1) (and the wall's images (5)).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ... import mrs

__all__ = ["Surface", "MobilitySolution", "mobility", "skew"]


@dataclass(frozen=True)
class Surface:
    """One body's surface at one evaluation, in the lab frame: ``points`` (M, 3), reference point
    ``center``, blob width ``epsilon``, surface ``slip`` (M, 3) relative to the rigid motion,
    external ``force`` and ``torque`` on the body (about ``center``)."""

    points: np.ndarray
    center: np.ndarray
    epsilon: float
    slip: np.ndarray
    force: np.ndarray
    torque: np.ndarray


@dataclass(frozen=True)
class MobilitySolution:
    """Every body's velocity ``U`` (B, 3) and angular velocity ``Omega`` (B, 3), the surface
    forces on the fluid ``forces`` (Σ M, 3) and the relative residual of the solve."""

    U: np.ndarray
    Omega: np.ndarray
    forces: np.ndarray
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


def mobility(surfaces: list[Surface], mu: float, wall: bool, background: np.ndarray | None,
             n_threads: int | None = None) -> MobilitySolution:
    """Solve the augmented mobility system of all ``surfaces`` at once (see the module)."""
    points = np.concatenate([s.points for s in surfaces])
    eps = np.concatenate([np.full(len(s.points), float(s.epsilon)) for s in surfaces])
    n, nb = len(points), len(surfaces)
    size = 3 * n + 6 * nb
    a = np.zeros((size, size))
    a[: 3 * n, : 3 * n] = stokeslet_matrix(points, eps, mu, wall, n_threads)
    rhs = np.zeros(size)
    slip = np.concatenate([s.slip for s in surfaces])
    if background is not None:
        slip = slip - background
    rhs[: 3 * n] = slip.ravel()
    first = 0
    for k, s in enumerate(surfaces):
        m = len(s.points)
        rows = slice(3 * first, 3 * (first + m))
        col = 3 * n + 6 * k
        rigid = np.zeros((m, 3, 6))
        rigid[:, :, :3] = np.eye(3)
        rigid[:, :, 3:] = -skew(s.points - s.center)  # U + Ω × r
        k_block = rigid.reshape(3 * m, 6)
        a[rows, col : col + 6] = -k_block
        a[col : col + 6, rows] = k_block.T
        rhs[col : col + 3] = s.force
        rhs[col + 3 : col + 6] = s.torque
        first += m
    x = np.linalg.solve(a, rhs)
    residual = float(np.linalg.norm(a @ x - rhs) / max(np.linalg.norm(rhs), 1e-300))
    motion = x[3 * n :].reshape(nb, 6)
    return MobilitySolution(motion[:, :3].copy(), motion[:, 3:].copy(),
                            x[: 3 * n].reshape(n, 3), residual)
