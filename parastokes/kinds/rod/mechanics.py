"""The discrete Kirchhoff rod (paper section 5.1; docs/physics.md section 3; Lim et al. 2008).

:func:`rod_loads` computes, for any number of rods stored one after the other in a state
array ``(n_rods * M, 12)`` of rows ``[X, D1, D2, D3]``, the point forces and torques that the rods
exert on the fluid. For each half point k+½ (k = 0..M-2) of each rod it forms

- the half-point frame D_i^{k+½} = sqrt(A_k) D_i^k, A_k = Σ_i D_i^{k+1} (D_i^k)^T, as the rotation
  by half the angle of A_k about its axis (docs/physics.md (9)); the axis-angle of A_k comes from
  v = ½ Σ_i D_i^k × D_i^{k+1} = sin θ e and tr A_k = 1 + 2 cos θ, and the half rotation (cosine
  ½ sqrt(tr A_k + 1), sine ``|v|`` over twice that) is applied with Rodrigues' formula;
- the strains Ω_i (paper eq. 10; docs/physics.md (10));
- the moment N and force F (paper eq. 11; docs/physics.md (11)) with the preferred strain Ω̂
  (eq. 36);

and accumulates the point values (paper eq. 12; docs/physics.md (12)) with free ends
(F = N = 0 outside 0..M-2). Everything runs in one compiled loop; no Python loop over points.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ...bodies.frames import rodrigues

_OPTS = dict(cache=True, error_model="numpy")


@njit(inline="always", **(_OPTS | dict(fastmath={"contract"})))
def segment_loads(p, q, inv_ds, a1, a2, a3, b1, b2, b3, o1, o2, o3):
    """The moment N and force F at the half point between nodes p and q (rows [X, D1, D2, D3]),
    and the lever ½ ΔX × F (eqs. 9-11): ``(F, N, ½ ΔX × F)`` as nine numbers. ``inv_ds`` = 1/Δs,
    a_i, b_i the moduli, o_i = Ω̂_i at the half point. One segment of :func:`rod_loads`; also
    compiled as a CUDA device function by :mod:`parastokes.gpu` (hence ``math.sqrt``)."""
    # v = ½ Σ_i D_i^k × D_i^{k+1} = sin θ e, tr A_k = Σ_i D_i^k·D_i^{k+1} = 1 + 2 cos θ
    vx = 0.5 * (p[4] * q[5] - p[5] * q[4] + p[7] * q[8] - p[8] * q[7]
                + p[10] * q[11] - p[11] * q[10])
    vy = 0.5 * (p[5] * q[3] - p[3] * q[5] + p[8] * q[6] - p[6] * q[8]
                + p[11] * q[9] - p[9] * q[11])
    vz = 0.5 * (p[3] * q[4] - p[4] * q[3] + p[6] * q[7] - p[7] * q[6]
                + p[9] * q[10] - p[10] * q[9])
    tr = (p[3] * q[3] + p[4] * q[4] + p[5] * q[5] + p[6] * q[6] + p[7] * q[7]
          + p[8] * q[8] + p[9] * q[9] + p[10] * q[10] + p[11] * q[11])
    ch = 0.5 * math.sqrt(tr + 1.0)
    rc = 1.0 / (ch * (1.0 + ch))
    inv_ch = rc * (1.0 + ch)
    sp = 0.5 * inv_ch
    kq = 0.25 * inv_ch * rc
    # half-point frame H_i (docs/physics.md (9))
    h1x, h1y, h1z = rodrigues(p[3], p[4], p[5], vx, vy, vz, ch, kq, sp)
    h2x, h2y, h2z = rodrigues(p[6], p[7], p[8], vx, vy, vz, ch, kq, sp)
    h3x, h3y, h3z = rodrigues(p[9], p[10], p[11], vx, vy, vz, ch, kq, sp)
    dx0 = q[0] - p[0]
    dx1 = q[1] - p[1]
    dx2 = q[2] - p[2]
    # strains (eq. 10): Ω1 = H3·ΔD2/Δs, Ω2 = H1·ΔD3/Δs, Ω3 = H2·ΔD1/Δs; moments a_i (Ω - Ω̂)
    om1 = (h3x * (q[6] - p[6]) + h3y * (q[7] - p[7]) + h3z * (q[8] - p[8])) * inv_ds
    om2 = (h1x * (q[9] - p[9]) + h1y * (q[10] - p[10]) + h1z * (q[11] - p[11])) * inv_ds
    om3 = (h2x * (q[3] - p[3]) + h2y * (q[4] - p[4]) + h2z * (q[5] - p[5])) * inv_ds
    m1 = a1 * (om1 - o1)
    m2 = a2 * (om2 - o2)
    m3 = a3 * (om3 - o3)
    # force at the half point (eq. 11)
    c1 = b1 * (h1x * dx0 + h1y * dx1 + h1z * dx2) * inv_ds
    c2 = b2 * (h2x * dx0 + h2y * dx1 + h2z * dx2) * inv_ds
    c3 = b3 * ((h3x * dx0 + h3y * dx1 + h3z * dx2) * inv_ds - 1.0)
    fx = c1 * h1x + c2 * h2x + c3 * h3x
    fy = c1 * h1y + c2 * h2y + c3 * h3y
    fz = c1 * h1z + c2 * h2z + c3 * h3z
    nx = m1 * h1x + m2 * h2x + m3 * h3x
    ny = m1 * h1y + m2 * h2y + m3 * h3y
    nz = m1 * h1z + m2 * h2z + m3 * h3z
    # point values (eq. 12); ½ ΔX × F goes to both neighbours
    lx = 0.5 * (dx1 * fz - dx2 * fy)
    ly = 0.5 * (dx2 * fx - dx0 * fz)
    lz = 0.5 * (dx0 * fy - dx1 * fx)
    return fx, fy, fz, nx, ny, nz, lx, ly, lz


@njit(**(_OPTS | dict(fastmath={"contract"})))
def rod_loads(state, n_rods, ds, a, b, omega_hat):
    """Point forces and torques on the fluid of ``n_rods`` rods (paper eqs. 10-12).

    Parameters: ``state`` (n_rods * M, 12); ``ds`` the node spacing Δs; ``a`` = (a1, a2, a3) the
    bending/twist moduli; ``b`` = (b1, b2, b3) the shear/stretch moduli; ``omega_hat`` (M - 1, 3)
    the preferred strains at the half points s_{k+½} (the same for every rod).
    Returns ``(f, n)``, two contiguous (n_rods * M, 3) arrays.

    The half-angle rotation needs no axis normalization: with v = sin θ e and
    cos(θ/2) = ½ sqrt(tr A_k + 1), ``sin(θ/2)/|v| = 1/(2 cos(θ/2))`` and
    ``(1 - cos(θ/2))/|v|² = 1/(4 cos²(θ/2) (1 + cos(θ/2)))``, both finite at θ = 0
    (``|v| = 0`` gives H = D^k). One square root and one division per segment, no branch. A half
    turn between neighbouring frames (θ = π, no unique square root) gives non-finite loads, which
    the integrator reports as a blow-up.
    """
    n = state.shape[0]
    m = n // n_rods
    inv_ds = 1.0 / ds
    f = np.zeros((n, 3))
    tq = np.zeros((n, 3))
    for r in range(n_rods):
        for k in range(r * m, (r + 1) * m - 1):
            kk = k - r * m
            fx, fy, fz, nx, ny, nz, lx, ly, lz = segment_loads(
                state[k], state[k + 1], inv_ds, a[0], a[1], a[2], b[0], b[1], b[2],
                omega_hat[kk, 0], omega_hat[kk, 1], omega_hat[kk, 2],
            )
            f[k, 0] += fx
            f[k, 1] += fy
            f[k, 2] += fz
            f[k + 1, 0] -= fx
            f[k + 1, 1] -= fy
            f[k + 1, 2] -= fz
            tq[k, 0] += nx + lx
            tq[k, 1] += ny + ly
            tq[k, 2] += nz + lz
            tq[k + 1, 0] += lx - nx
            tq[k + 1, 1] += ly - ny
            tq[k + 1, 2] += lz - nz
    return f, tq


@njit(**_OPTS)
def rod_lengths(state, n_rods):
    """Length ``Σ_k |X_{k+1} - X_k|`` of each rod (the stability monitor of section 5.1)."""
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
def length_change(state, n_rods, length):
    """The rods' stability monitor (section 5.1): max over rods of
    ``|Σ_k |X_{k+1} - X_k| - L| / L``."""
    return np.abs(rod_lengths(state, n_rods) - length).max() / length


@njit(**_OPTS)
def wave_table(n_half, ds, wavenumber):
    """sin(k s) and cos(k s) at the ``n_half`` half points s_{k+½} = (k + ½) ds: an (n_half, 2)
    array, computed once per rod so that :func:`preferred_strain` needs no sine per point."""
    out = np.empty((n_half, 2))
    for k in range(n_half):
        arg = wavenumber * ((k + 0.5) * ds)
        out[k, 0] = np.sin(arg)
        out[k, 1] = np.cos(arg)
    return out


@njit(**_OPTS)
def preferred_strain(table, t, constant, amplitude, wavenumber, frequency):
    """Ω̂ at the half points s_{k+½} at time ``t``: ``constant + (0, -k² A sin(k s + f t), 0)``.

    With ``constant = 0`` this is the swimmer's planar travelling wave (paper eq. 36); with
    ``amplitude = 0`` a constant strain-twist (κ, 0, τ) gives a helix, and 0 a straight rod.
    ``table`` is :func:`wave_table` of the half points (sin(k s), cos(k s)); the wave is
    sin(k s) cos(f t) + cos(k s) sin(f t), one sine and one cosine per call. ``constant`` is a
    3-tuple of floats. Returns an (n_half, 3) array.
    """
    n_half = table.shape[0]
    out = np.empty((n_half, 3))
    scale = -(wavenumber**2) * amplitude
    sft = scale * np.sin(frequency * t)
    cft = scale * np.cos(frequency * t)
    for k in range(n_half):
        out[k, 0] = constant[0]
        out[k, 1] = constant[1]
        out[k, 2] = constant[2]
        if amplitude != 0.0:
            out[k, 1] += table[k, 0] * cft + table[k, 1] * sft
    return out
