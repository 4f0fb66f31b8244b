"""Compiled (numba) regularized Stokeslet kernels: the fast path.

Layout: structure of arrays, a leading batch axis ``b`` (B independent systems, each with its ε),
targets padded to a multiple of :data:`TILE` and processed in tiles, sources streamed one at a time
with their constants hoisted, targets innermost so that the inner loop vectorizes. One square root
and one division per distance. Work is split over ``(system, tile)`` pairs with ``prange``; each
target's sum runs over the sources in the same order whatever the number of threads, so results
are bit-identical for any thread count.

All kernels return the velocity times 8πμ; :mod:`parastokes.mrs.velocity` applies 1/(8πμ).
Formulas: ``shared/physics.md`` (1)-(8), the paper's eqs. 3-6.

Kernels:

- :func:`free_u_f`: force -> velocity in free space (eq. 6), the vesicle's hot path;
- :func:`full`: u and w from forces and torques in free space ([1]-[4]) or, with ``wall``, above
  the wall z = 0 ([1]-[8]), the rod's.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

#: Targets per tile (a multiple of 8 so that the inner loop vectorizes without remainder).
TILE = 64

# fastmath: "contract" lets LLVM fuse multiply-adds; the tests check the results agree with the
# numpy oracle to 1e-12 relative (in practice ~1e-15). No reassociation: sums keep their order.
_OPTS = dict(cache=True, error_model="numpy", fastmath={"contract"}, boundscheck=False)


@njit(inline="always", **_OPTS)
def _free_pair(rx, ry, rz, r2, e2, inv, fx, fy, fz, nx, ny, nz):
    """8π × (u, w) at r from a force f and a torque n in free space ([1]-[4])."""
    inv2 = inv * inv
    inv3 = inv2 * inv
    inv5 = inv3 * inv2
    h1 = (r2 + 2.0 * e2) * inv3
    fr = (fx * rx + fy * ry + fz * rz) * inv3
    nr = (nx * rx + ny * ry + nz * rz) * (1.5 * inv5)
    q = (r2 + 2.5 * e2) * inv5  # ½ Q · 8π
    p1 = -0.5 * (r2 - 2.0 * e2) * inv5
    ux = h1 * fx + fr * rx + (ny * rz - nz * ry) * inv3
    uy = h1 * fy + fr * ry + (nz * rx - nx * rz) * inv3
    uz = h1 * fz + fr * rz + (nx * ry - ny * rx) * inv3
    wx = q * (fy * rz - fz * ry) + p1 * nx + nr * rx
    wy = q * (fz * rx - fx * rz) + p1 * ny + nr * ry
    wz = q * (fx * ry - fy * rx) + p1 * nz + nr * rz
    return ux, uy, uz, wx, wy, wz


@njit(inline="always", **_OPTS)
def _image_pair(bx, by, b3, z, h, e2, fx, fy, fz, nx, ny, nz):
    """8π × (u, w) image parts ([5]-[8]) at R = (bx, by, b3) = x - y*, R3 = b3 = z + h.

    The coefficients of physics.md (5)-(8) are regrouped with z = R3 - h (fewer operations, the
    same terms): e.g. the f* and f coefficients of (5) combine into -(R² + 2ε² + 2hz)/R_ε³ +
    6hε²z/R_ε⁵ for the x and y components.
    """
    r2 = bx * bx + by * by + b3 * b3
    inv = 1.0 / np.sqrt(r2 + e2)
    inv2 = inv * inv
    inv3 = inv2 * inv
    inv5 = inv3 * inv2
    he5 = 6.0 * h * e2 * inv5
    kk = b3 * (2.0 * r2 + 7.0 * e2) - 5.0 * e2 * h
    p7 = kk * inv5 * inv2
    # [5] force -> velocity.
    rf = bx * fx + by * fy + b3 * fz
    rfs = rf - 2.0 * b3 * fz
    c_xy = he5 * z - (r2 + 2.0 * e2 + 2.0 * h * z) * inv3
    c_z = he5 * (z + 2.0 * h) - (r2 + 2.0 * e2 - 2.0 * h * z) * inv3
    c_r = (2.0 * h * fz - rf) * inv3 + 6.0 * h * z * rfs * inv5
    c_e3 = 2.0 * h * inv5 * (rfs * (r2 + 4.0 * e2) - 3.0 * e2 * rf)
    ux = c_xy * fx + c_r * bx
    uy = c_xy * fy + c_r * by
    uz = c_z * fz + c_r * b3 + c_e3
    # [6] force -> angular velocity, g = f2 R1 - f1 R2.
    aw = -(r2 + 2.5 * e2) * inv5 - 3.0 * h * p7
    bw = -h * (4.0 * r2 + e2) * inv5 + 6.0 * h * b3 * p7
    g = fy * bx - fx * by
    cg = 6.0 * h * inv5 * g
    wx = aw * (fy * b3 - fz * by) + bw * fy + cg * bx
    wy = aw * (fz * bx - fx * b3) - bw * fx + cg * by
    wz = cg * b3 - (aw + 6.0 * h * p7) * g
    # [7] torque -> velocity, b = n × e3 = (ny, -nx, 0).
    cb = (2.0 * h * (r2 - 2.0 * e2) + 6.0 * e2 * b3) * inv5
    crb = 6.0 * z * inv5 * (bx * ny - by * nx)
    ux += (nz * by - ny * b3) * inv3 + cb * ny + crb * bx
    uy += (nx * b3 - nz * bx) * inv3 - cb * nx + crb * by
    uz += (ny * bx - nx * by) * inv3 + crb * b3
    # [8] torque -> angular velocity.
    an = (3.5 * r2 + 2.0 * e2) * inv5 - 3.0 * b3 * p7
    nrr = nx * bx + ny * by + nz * b3
    cr = 3.0 * inv5 * (b3 * nz - 1.5 * nrr)
    wx += an * nx + cr * bx
    wy += an * ny + cr * by
    wz += an * nz + cr * b3 + 3.0 * p7 * nrr - 3.0 * inv3 * nz
    return ux, uy, uz, wx, wy, wz


@njit(parallel=True, **_OPTS)
def free_u_f(tx, ty, tz, sx, sy, sz, fx, fy, fz, eps, ux, uy, uz):
    """8π μ u from forces in free space (eq. 6). Targets (B, Mp) with Mp % TILE == 0."""
    nb, mp = tx.shape
    ns = sx.shape[1]
    ntiles = mp // TILE
    for job in prange(nb * ntiles):
        b = job // ntiles
        t0 = (job % ntiles) * TILE
        e2 = eps[b] * eps[b]
        e22 = 2.0 * e2
        ax = np.zeros(TILE)
        ay = np.zeros(TILE)
        az = np.zeros(TILE)
        px = tx[b, t0 : t0 + TILE]
        py = ty[b, t0 : t0 + TILE]
        pz = tz[b, t0 : t0 + TILE]
        for j in range(ns):
            yx, yy, yz = sx[b, j], sy[b, j], sz[b, j]
            gx, gy, gz = fx[b, j], fy[b, j], fz[b, j]
            for i in range(TILE):
                rx = px[i] - yx
                ry = py[i] - yy
                rz = pz[i] - yz
                r2 = rx * rx + ry * ry + rz * rz
                inv = 1.0 / np.sqrt(r2 + e2)
                inv3 = inv * inv * inv
                h1 = (r2 + e22) * inv3
                fr = (gx * rx + gy * ry + gz * rz) * inv3
                ax[i] += h1 * gx + fr * rx
                ay[i] += h1 * gy + fr * ry
                az[i] += h1 * gz + fr * rz
        ux[b, t0 : t0 + TILE] = ax
        uy[b, t0 : t0 + TILE] = ay
        uz[b, t0 : t0 + TILE] = az


@njit(parallel=True, **_OPTS)
def full(tx, ty, tz, sx, sy, sz, fx, fy, fz, nx, ny, nz, eps, wall, ux, uy, uz, wx, wy, wz):
    """8π μ (u, w) from forces and torques: free space ([1]-[4]), plus the images ([5]-[8]) of
    the plane wall z = 0 when ``wall`` (a loop-invariant test: LLVM unswitches the loops)."""
    nb, mp = tx.shape
    ns = sx.shape[1]
    ntiles = mp // TILE
    for job in prange(nb * ntiles):
        b = job // ntiles
        t0 = (job % ntiles) * TILE
        e2 = eps[b] * eps[b]
        a0 = np.zeros(TILE)
        a1 = np.zeros(TILE)
        a2 = np.zeros(TILE)
        a3 = np.zeros(TILE)
        a4 = np.zeros(TILE)
        a5 = np.zeros(TILE)
        px = tx[b, t0 : t0 + TILE]
        py = ty[b, t0 : t0 + TILE]
        pz = tz[b, t0 : t0 + TILE]
        for j in range(ns):
            yx, yy, h = sx[b, j], sy[b, j], sz[b, j]
            gx, gy, gz = fx[b, j], fy[b, j], fz[b, j]
            mx, my, mz = nx[b, j], ny[b, j], nz[b, j]
            for i in range(TILE):
                rx = px[i] - yx
                ry = py[i] - yy
                z = pz[i]
                rz = z - h
                r2 = rx * rx + ry * ry + rz * rz
                inv = 1.0 / np.sqrt(r2 + e2)
                v0, v1, v2, v3, v4, v5 = _free_pair(rx, ry, rz, r2, e2, inv,
                                                    gx, gy, gz, mx, my, mz)
                if wall:
                    i0, i1, i2, i3, i4, i5 = _image_pair(rx, ry, z + h, z, h, e2,
                                                         gx, gy, gz, mx, my, mz)
                    v0 += i0
                    v1 += i1
                    v2 += i2
                    v3 += i3
                    v4 += i4
                    v5 += i5
                a0[i] += v0
                a1[i] += v1
                a2[i] += v2
                a3[i] += v3
                a4[i] += v4
                a5[i] += v5
        ux[b, t0 : t0 + TILE] = a0
        uy[b, t0 : t0 + TILE] = a1
        uz[b, t0 : t0 + TILE] = a2
        wx[b, t0 : t0 + TILE] = a3
        wy[b, t0 : t0 + TILE] = a4
        wz[b, t0 : t0 + TILE] = a5
