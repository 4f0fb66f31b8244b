"""Orthonormal frames: Rodrigues rotations and re-orthonormalization (docs/physics.md (9), (13)).

A rod state has one row per node, ``[X(3), D1(3), D2(3), D3(3)]`` (docs/contracts.md). Everything
here is compiled with numba and loops over rows inside the compiled code.

- :func:`rodrigues`, :func:`rotate`: Rodrigues' formula, the exact rotation of a vector by an angle
  about an axis (unit, for :func:`rotate`).
- :func:`advance_rod`: the rod's ``advance`` (eq. 13): X + dt u, frames rotated by ``|w| dt``
  about w.
- :func:`orthonormalize`: the nearest rotation (polar factor) of every node's frame matrix, used by
  ``project`` after Parareal's linear combinations of states and after grid transfers.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_OPTS = dict(cache=True, error_model="numpy")

#: Largest Frobenius change accepted as converged by :func:`orthonormalize`.
_POLAR_TOL = 1e-15
_POLAR_MAX_ITER = 50


@njit(inline="always", **_OPTS)
def rodrigues(vx, vy, vz, ax, ay, az, c, k, s):
    """Rodrigues' formula with the axis a as given: c v + k (a·v) a + s a × v.

    For a unit axis a rotation by an angle of cosine c and sine s has k = 1 - c
    (:func:`rotate`); for an axis of length L, k = (1 - c)/L² and s = sin/L (the rod's half-point
    frames, which use the unnormalized axis).
    """
    ad = k * (ax * vx + ay * vy + az * vz)
    return (
        c * vx + ad * ax + s * (ay * vz - az * vy),
        c * vy + ad * ay + s * (az * vx - ax * vz),
        c * vz + ad * az + s * (ax * vy - ay * vx),
    )


@njit(inline="always", **_OPTS)
def rotate(vx, vy, vz, ex, ey, ez, c, s):
    """Rotate v about the unit axis e by the angle with cosine c and sine s (Rodrigues, eq. 13).

    v <- c v + (1 - c)(e·v) e + s e × v.
    """
    return rodrigues(vx, vy, vz, ex, ey, ez, c, 1.0 - c, s)


@njit(inline="always", **_OPTS)
def advance_node(x, u, dt, out):
    """One node of :func:`advance_rod`: ``out`` = ``x`` (a row [X, D1, D2, D3]) advanced by the
    rates ``u`` (a row [u, w]). Also compiled as a CUDA device function by :mod:`parastokes.gpu`
    (hence ``math``)."""
    for j in range(3):
        out[j] = x[j] + dt * u[j]
    wx = u[3]
    wy = u[4]
    wz = u[5]
    wn = math.sqrt(wx * wx + wy * wy + wz * wz)
    if wn == 0.0 or dt == 0.0:
        for j in range(3, 12):
            out[j] = x[j]
        return
    theta = wn * dt
    c = math.cos(theta)
    s = math.sin(theta)
    ex = wx / wn
    ey = wy / wn
    ez = wz / wn
    for i in range(3, 12, 3):
        out[i], out[i + 1], out[i + 2] = rotate(x[i], x[i + 1], x[i + 2], ex, ey, ez, c, s)


@njit(**_OPTS)
def advance_rod(state, rates, dt):
    """New state: X + dt u and every frame vector rotated by the angle ``|w| dt`` about w (eq. 13).

    ``state`` is (n, 12) ``[X, D1, D2, D3]``, ``rates`` (n, 6) ``[u, w]``; ``|w| = 0`` leaves the
    frame.
    """
    out = np.empty_like(state)
    for k in range(state.shape[0]):
        advance_node(state[k], rates[k], dt, out[k])
    return out


@njit(**_OPTS)
def orthonormalize(state):
    """Replace every frame (D1, D2, D3) by the nearest rotation matrix (its polar factor).

    Newton's iteration Y <- (Y + Y^-T)/2 on the matrix with columns D1, D2, D3, where
    Y^-T = [D2 × D3, D3 × D1, D1 × D2] / det Y; it converges quadratically for any nonsingular
    frame. Treating D1, D2, D3 alike, it is the natural repair after the linear combinations of
    Parareal and extrapolation (design.md). Positions are copied unchanged.
    Raises ValueError for a singular or left-handed frame (det <= 0).
    """
    n = state.shape[0]
    out = state.copy()
    y = np.empty((3, 3))
    cof = np.empty((3, 3))
    for k in range(n):
        for i in range(3):
            for j in range(3):
                y[i, j] = state[k, 3 + 3 * i + j]  # row i of y = D_{i+1}
        for _ in range(_POLAR_MAX_ITER):
            # cofactor rows: D2 × D3, D3 × D1, D1 × D2
            for i in range(3):
                a = (i + 1) % 3
                b = (i + 2) % 3
                cof[i, 0] = y[a, 1] * y[b, 2] - y[a, 2] * y[b, 1]
                cof[i, 1] = y[a, 2] * y[b, 0] - y[a, 0] * y[b, 2]
                cof[i, 2] = y[a, 0] * y[b, 1] - y[a, 1] * y[b, 0]
            det = y[0, 0] * cof[0, 0] + y[0, 1] * cof[0, 1] + y[0, 2] * cof[0, 2]
            if not det > 0.0:
                raise ValueError("state: a frame is singular or left-handed (det <= 0)")
            change = 0.0
            for i in range(3):
                for j in range(3):
                    new = 0.5 * (y[i, j] + cof[i, j] / det)
                    change += (new - y[i, j]) ** 2
                    y[i, j] = new
            if change < _POLAR_TOL * _POLAR_TOL:
                break
        for i in range(3):
            for j in range(3):
                out[k, 3 + 3 * i + j] = y[i, j]
    return out


def orthonormality_error(state: np.ndarray) -> float:
    """max over nodes of ``|D^T D - I|`` (entrywise), with D the 3x3 frame matrix of a node."""
    d = np.asarray(state)[:, 3:12].reshape(-1, 3, 3)
    gram = np.einsum("kij,klj->kil", d, d)
    return float(np.abs(gram - np.eye(3)).max())
