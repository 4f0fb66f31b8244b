"""The discrete Kirchhoff rod (paper section 5.1; physics.md section 3; Lim et al. 2008).

:func:`rod_loads` computes, for any number of rods stored one after the other in a state
array ``(n_rods * M, 12)`` of rows ``[X, D1, D2, D3]``, the point forces and torques that the rods
exert on the fluid. For each half point k+½ (k = 0..M-2) of each rod it forms

- the half-point frame D_i^{k+½} = sqrt(A_k) D_i^k, A_k = Σ_i D_i^{k+1} (D_i^k)^T, as the rotation
  by half the angle of A_k about its axis (physics.md (9)); the axis-angle of A_k comes from
  v = ½ Σ_i D_i^k × D_i^{k+1} = sin θ e and tr A_k = 1 + 2 cos θ, and the half rotation (cosine
  ½ sqrt(tr A_k + 1), sine |v| over twice that) is applied with Rodrigues' formula;
- the strains Ω_i (paper eq. 10; physics.md (10));
- the moment N and force F (paper eq. 11; physics.md (11)) with the preferred strain Ω̂ (eq. 36);

and accumulates the point values (paper eq. 12; physics.md (12)) with free ends
(F = N = 0 outside 0..M-2). Everything runs in one compiled loop; no Python loop over points.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .frames import rotate

_OPTS = dict(cache=True, error_model="numpy")


@njit(inline="always", **_OPTS)
def _dot3(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(**_OPTS)
def rod_loads(state, n_rods, ds, a, b, omega_hat):
    """Point forces and torques on the fluid of ``n_rods`` rods (paper eqs. 10-12).

    Parameters: ``state`` (n_rods * M, 12); ``ds`` the node spacing Δs; ``a`` = (a1, a2, a3) the
    bending/twist moduli; ``b`` = (b1, b2, b3) the shear/stretch moduli; ``omega_hat`` (M - 1, 3)
    the preferred strains at the half points s_{k+½} (the same for every rod).
    Returns ``(f, n)``, two contiguous (n_rods * M, 3) arrays.
    """
    n = state.shape[0]
    m = n // n_rods
    f = np.zeros((n, 3))
    tq = np.zeros((n, 3))
    h = np.empty((3, 3))  # rows: half-point frame H1, H2, H3
    dd = np.empty((3, 3))  # rows: D_i^{k+1} - D_i^k
    dx = np.empty(3)
    big_f = np.empty(3)
    big_n = np.empty(3)
    for r in range(n_rods):
        for k in range(r * m, (r + 1) * m - 1):
            # axis-angle of A_k: v = ½ Σ_i D_i^k × D_i^{k+1} = sin θ e, tr A_k = 1 + 2 cos θ
            vx = 0.0
            vy = 0.0
            vz = 0.0
            tr = 0.0
            for i in range(3, 12, 3):
                p0 = state[k, i]
                p1 = state[k, i + 1]
                p2 = state[k, i + 2]
                q0 = state[k + 1, i]
                q1 = state[k + 1, i + 1]
                q2 = state[k + 1, i + 2]
                vx += 0.5 * (p1 * q2 - p2 * q1)
                vy += 0.5 * (p2 * q0 - p0 * q2)
                vz += 0.5 * (p0 * q1 - p1 * q0)
                tr += p0 * q0 + p1 * q1 + p2 * q2
            vn = np.sqrt(vx * vx + vy * vy + vz * vz)
            ch = 1.0
            sh = 0.0
            if vn > 0.0:
                # cos(θ/2) = sqrt((1 + cos θ)/2) = ½ sqrt(tr + 1), sin(θ/2) = sin θ / (2 cos(θ/2)):
                # no transcendental functions (θ < π: adjacent frames are close).
                ch = 0.5 * np.sqrt(tr + 1.0)
                sh = 0.5 * vn / ch
                vx /= vn
                vy /= vn
                vz /= vn
            for i in range(3):
                c0 = 3 + 3 * i
                if vn > 0.0:
                    h[i, 0], h[i, 1], h[i, 2] = rotate(
                        state[k, c0], state[k, c0 + 1], state[k, c0 + 2], vx, vy, vz, ch, sh
                    )
                else:
                    h[i, 0] = state[k, c0]
                    h[i, 1] = state[k, c0 + 1]
                    h[i, 2] = state[k, c0 + 2]
                for j in range(3):
                    dd[i, j] = state[k + 1, c0 + j] - state[k, c0 + j]
                dx[i] = state[k + 1, i] - state[k, i]
            # strains (eq. 10): Ω1 = H3·ΔD2/Δs, Ω2 = H1·ΔD3/Δs, Ω3 = H2·ΔD1/Δs
            kk = k - r * m
            om0 = _dot3(h[2], dd[1]) / ds - omega_hat[kk, 0]
            om1 = _dot3(h[0], dd[2]) / ds - omega_hat[kk, 1]
            om2 = _dot3(h[1], dd[0]) / ds - omega_hat[kk, 2]
            # moment and force at the half point (eq. 11)
            c1 = b[0] * _dot3(h[0], dx) / ds
            c2 = b[1] * _dot3(h[1], dx) / ds
            c3 = b[2] * (_dot3(h[2], dx) / ds - 1.0)
            for j in range(3):
                big_n[j] = a[0] * om0 * h[0, j] + a[1] * om1 * h[1, j] + a[2] * om2 * h[2, j]
                big_f[j] = c1 * h[0, j] + c2 * h[1, j] + c3 * h[2, j]
            # ½ ΔX × F goes to both neighbours (eq. 12)
            lx = 0.5 * (dx[1] * big_f[2] - dx[2] * big_f[1])
            ly = 0.5 * (dx[2] * big_f[0] - dx[0] * big_f[2])
            lz = 0.5 * (dx[0] * big_f[1] - dx[1] * big_f[0])
            for j in range(3):
                f[k, j] += big_f[j]
                f[k + 1, j] -= big_f[j]
                tq[k, j] += big_n[j]
                tq[k + 1, j] -= big_n[j]
            tq[k, 0] += lx
            tq[k, 1] += ly
            tq[k, 2] += lz
            tq[k + 1, 0] += lx
            tq[k + 1, 1] += ly
            tq[k + 1, 2] += lz
    return f, tq


@njit(**_OPTS)
def rod_lengths(state, n_rods):
    """Length Σ_k |X_{k+1} - X_k| of each rod (the stability monitor of section 5.1)."""
    n = state.shape[0]
    m = n // n_rods
    out = np.zeros(n_rods)
    for r in range(n_rods):
        total = 0.0
        for k in range(r * m, (r + 1) * m - 1):
            dx = state[k + 1, 0] - state[k, 0]
            dy = state[k + 1, 1] - state[k, 1]
            dz = state[k + 1, 2] - state[k, 2]
            total += np.sqrt(dx * dx + dy * dy + dz * dz)
        out[r] = total
    return out


@njit(**_OPTS)
def preferred_strain(n_half, ds, t, constant, amplitude, wavenumber, frequency):
    """Ω̂ at the ``n_half`` half points s_{k+½} = (k + ½) ds and time ``t``:
    ``constant + (0, -k² A sin(k s + f t), 0)``.

    With ``constant = 0`` this is the swimmer's planar travelling wave (paper eq. 36); with
    ``amplitude = 0`` a constant strain-twist (κ, 0, τ) gives a helix, and 0 a straight rod.
    ``constant`` is a 3-tuple of floats. Returns an (n_half, 3) array.
    """
    out = np.empty((n_half, 3))
    for k in range(n_half):
        out[k, 0] = constant[0]
        out[k, 1] = constant[1]
        out[k, 2] = constant[2]
        if amplitude != 0.0:
            s = (k + 0.5) * ds
            out[k, 1] -= wavenumber**2 * amplitude * np.sin(wavenumber * s + frequency * t)
    return out
