"""Plain-numpy oracles of the rod's compiled functions (readable, slow; used by the tests).

Each function restates a formula of the paper / docs/physics.md with whole-array operations and a
different route (scipy's ``Rotation`` for the half-point frames and the Rodrigues update), so that
agreement with the compiled code (:mod:`.mechanics`, :func:`parastokes.bodies.frames.advance_rod`)
is evidence for both.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation


def _frame_matrices(state: np.ndarray) -> np.ndarray:
    """(n, 3, 3) matrices with columns D1, D2, D3."""
    return state[:, 3:12].reshape(-1, 3, 3).transpose(0, 2, 1)


def rod_loads(
    state: np.ndarray,
    n_rods: int,
    ds: float,
    a: np.ndarray,
    b: np.ndarray,
    omega_hat: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Point forces and torques on the fluid (eqs. 10-12), rod by rod."""
    m = state.shape[0] // n_rods
    f_all, n_all = [], []
    for x in state.reshape(n_rods, m, 12):
        r = _frame_matrices(x)
        a_k = r[1:] @ r[:-1].transpose(0, 2, 1)  # A_k = Σ_i D_i^{k+1} (D_i^k)^T, eq. (9)
        half = Rotation.from_rotvec(0.5 * Rotation.from_matrix(a_k).as_rotvec())
        h = half.as_matrix() @ r[:-1]  # columns: half-point frame
        h1, h2, h3 = h[:, :, 0], h[:, :, 1], h[:, :, 2]
        d = x[:, 3:12].reshape(-1, 3, 3)
        dd = np.diff(d, axis=0) / ds  # rows ΔD1, ΔD2, ΔD3 over Δs
        omega = np.stack(
            [
                np.einsum("kj,kj->k", h3, dd[:, 1]),
                np.einsum("kj,kj->k", h1, dd[:, 2]),
                np.einsum("kj,kj->k", h2, dd[:, 0]),
            ],
            axis=1,
        )  # eq. (10)
        coef_n = a * (omega - omega_hat)
        big_n = coef_n[:, :1] * h1 + coef_n[:, 1:2] * h2 + coef_n[:, 2:] * h3
        dx = np.diff(x[:, :3], axis=0)
        t = np.einsum("kij,ki->kj", h, dx) / ds - np.array([0.0, 0.0, 1.0])
        coef_f = b * t
        big_f = coef_f[:, :1] * h1 + coef_f[:, 1:2] * h2 + coef_f[:, 2:] * h3  # eq. (11)
        zero = np.zeros((1, 3))
        f_pad = np.concatenate([zero, big_f, zero])
        n_pad = np.concatenate([zero, big_n, zero])
        lever = 0.5 * np.cross(dx, big_f)
        l_pad = np.concatenate([zero, lever, zero])
        f_all.append(f_pad[1:] - f_pad[:-1])  # eq. (12)
        n_all.append(n_pad[1:] - n_pad[:-1] + l_pad[1:] + l_pad[:-1])
    return np.concatenate(f_all), np.concatenate(n_all)


def advance_rod(state: np.ndarray, rates: np.ndarray, dt: float) -> np.ndarray:
    """X + dt u; each frame rotated by the rotation vector dt·w (eq. 13)."""
    out = state.copy()
    out[:, :3] += dt * rates[:, :3]
    rot = Rotation.from_rotvec(dt * rates[:, 3:])
    for i in range(3):
        out[:, 3 + 3 * i : 6 + 3 * i] = rot.apply(state[:, 3 + 3 * i : 6 + 3 * i])
    return out

