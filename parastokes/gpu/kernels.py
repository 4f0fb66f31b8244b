"""Batched regularized-Stokeslet kernels for numba's CUDA target: B independent systems, one launch.

The pair formulas are the CPU kernels' own functions (:mod:`parastokes.mrs.compiled`:
``_free_pair``, ``_wall_pair`` and ``_rsqrt3``), which numba compiles a second time as CUDA
device functions: the GPU evaluates exactly the algebra that the CPU tests check against the numpy
oracle, with the same inverse square root (a single-precision seed and one double-precision Halley
step, :func:`parastokes.mrs.compiled._rsqrt`).

Launch layout (:func:`velocity_kernels`): a block of ``tx`` targets x ``sy`` source lanes; the grid
is (target blocks, B). Thread (i, s) sums the sources j = s, s + sy, s + 2 sy, ... for target i (a
warp is 32 targets at the same source, so each source's data is one broadcast load); the ``sy``
partial sums are then added in a fixed order in shared memory. Every target's sum therefore runs in
the same order whatever the batch, so a member's result does not depend on what it is batched with.
Splitting the sources gives ``sy`` times more threads than targets: one rod of 301 points is 2,400
threads, 40 of them 96,000, which is what it takes to keep the H200's 132 SMs busy.

A member b is skipped when ``mi[b, STATUS] != RUNNING`` (its solve has finished or failed; see
:mod:`parastokes.gpu.stepping`), so members with fewer steps stop costing anything.
"""

from __future__ import annotations

import functools

from numba import cuda

from ..mrs import compiled

__all__ = ["RUNNING", "launch_shape", "velocity_kernels"]

#: ``status`` of a member whose solve is still running (the others hold integrate.DONE, ...).
RUNNING = -1

#: Columns of the per-member float table ``mf`` (B, 6 + P): start time, step, ε, 8πμ, worst
#: monitor, monitor that ended the run, then from ``THETA`` on the P other parameters of the body
#: kind (``DeviceParts.parameters``, e.g. a rod's bending a).
T0, STEP, EPS, DENOM, WORST, MEND, THETA = range(7)
#: Columns of the per-member integer table ``mi`` (B, 3): status, steps to take, steps kept.
STATUS, NSTEPS, TAKEN = range(3)

@functools.cache
def velocity_kernels(tx: int, sy: int, per_source: bool = False) -> tuple:
    """``(full, free_u_f)`` for blocks of ``tx`` targets x ``sy`` source lanes; with
    ``per_source``, source j of member b has its own ε, ``eps[b, j]`` (a scene's bodies), else
    every source has the member's ``mf[b, EPS]`` (``eps`` is not read).

    - ``full[grid, block](x, y, f, n, mf, mi, wall, shear, eps, out)``: u and w from forces
      ``f`` and torques ``n`` at the sources ``y`` (B, N, >= 3; the first three columns are
      read), at the targets ``x`` (B, M, >= 3), free space ([1]-[4]) or above the wall z = 0
      ([1]-[8]) when ``wall``; ``out`` (B, M, >= 6) gets u in columns 0-2 and w in 3-5, divided
      by 8πμ, plus the shear flow (shear · z, 0, 0) in u and its rotation shear/2 in w_y when
      ``shear`` is not 0; ε, 8πμ and the status of member b are ``mf[b, EPS]``,
      ``mf[b, DENOM]``, ``mi[b, STATUS]``.
    - ``free_u_f[grid, block](x, y, f, mf, mi, shear, eps, out)``: u from forces in free space
      (eq. 6) plus the shear flow (shear · z, 0, 0) (docs/physics.md (15)), into columns 0-2.

    Launch with :func:`launch_shape`. Compiled on first use, once per process and ``(tx, sy)``
    (not cached on disk: numba's cache does not key closures on their constants).
    """
    from numba import float64

    wall_pair = compiled._wall_pair
    free_pair = compiled._free_pair
    rsqrt3 = compiled._rsqrt3

    @cuda.jit
    def full(x, y, f, n, mf, mi, wall, shear, eps, out):
        lane = cuda.threadIdx.x
        s = cuda.threadIdx.y
        b = cuda.blockIdx.y
        if mi[b, STATUS] != RUNNING:
            return  # the whole block leaves: no barrier is skipped by some threads only
        i = cuda.blockIdx.x * tx + lane
        m = x.shape[1]
        a0 = a1 = a2 = a3 = a4 = a5 = 0.0
        if i < m:
            px = x[b, i, 0]
            py = x[b, i, 1]
            pz = x[b, i, 2]
            e2 = mf[b, EPS] * mf[b, EPS]
            for j in range(s, y.shape[1], sy):
                if per_source:
                    e2 = eps[b, j] * eps[b, j]
                h = y[b, j, 2]
                if wall:
                    v0, v1, v2, v3, v4, v5 = wall_pair(
                        px - y[b, j, 0], py - y[b, j, 1], pz, h, e2,
                        f[b, j, 0], f[b, j, 1], f[b, j, 2], n[b, j, 0], n[b, j, 1], n[b, j, 2],
                    )
                else:
                    v0, v1, v2, v3, v4, v5 = free_pair(
                        px - y[b, j, 0], py - y[b, j, 1], pz - h, e2,
                        f[b, j, 0], f[b, j, 1], f[b, j, 2], n[b, j, 0], n[b, j, 1], n[b, j, 2],
                        False,
                    )
                a0 += v0
                a1 += v1
                a2 += v2
                a3 += v3
                a4 += v4
                a5 += v5
        part = cuda.shared.array((sy, 6, tx), float64)
        part[s, 0, lane] = a0
        part[s, 1, lane] = a1
        part[s, 2, lane] = a2
        part[s, 3, lane] = a3
        part[s, 4, lane] = a4
        part[s, 5, lane] = a5
        cuda.syncthreads()
        if i < m:
            for c in range(s, 6, sy):  # the column's threads write the six components
                total = part[0, c, lane]
                for q in range(1, sy):
                    total += part[q, c, lane]
                value = total / mf[b, DENOM]
                if c == 0 and shear != 0.0:
                    value += shear * x[b, i, 2]
                if c == 4 and shear != 0.0:
                    value += 0.5 * shear
                out[b, i, c] = value

    @cuda.jit
    def free_u_f(x, y, f, mf, mi, shear, eps, out):
        lane = cuda.threadIdx.x
        s = cuda.threadIdx.y
        b = cuda.blockIdx.y
        if mi[b, STATUS] != RUNNING:
            return
        i = cuda.blockIdx.x * tx + lane
        m = x.shape[1]
        a0 = a1 = a2 = 0.0
        if i < m:
            px = x[b, i, 0]
            py = x[b, i, 1]
            pz = x[b, i, 2]
            e2 = mf[b, EPS] * mf[b, EPS]
            e22 = 2.0 * e2
            for j in range(s, y.shape[1], sy):
                if per_source:
                    e2 = eps[b, j] * eps[b, j]
                    e22 = 2.0 * e2
                rx = px - y[b, j, 0]
                ry = py - y[b, j, 1]
                rz = pz - y[b, j, 2]
                gx = f[b, j, 0]
                gy = f[b, j, 1]
                gz = f[b, j, 2]
                r2 = rx * rx + ry * ry + rz * rz
                inv3 = rsqrt3(r2 + e2)
                h1 = (r2 + e22) * inv3
                fr = (gx * rx + gy * ry + gz * rz) * inv3
                a0 = a0 + fr * rx + h1 * gx
                a1 = a1 + fr * ry + h1 * gy
                a2 = a2 + fr * rz + h1 * gz
        part = cuda.shared.array((sy, 3, tx), float64)
        part[s, 0, lane] = a0
        part[s, 1, lane] = a1
        part[s, 2, lane] = a2
        cuda.syncthreads()
        if i < m:
            for c in range(s, 3, sy):
                total = part[0, c, lane]
                for q in range(1, sy):
                    total += part[q, c, lane]
                u = total / mf[b, DENOM]
                if c == 0:
                    u += shear * x[b, i, 2]
                out[b, i, c] = u

    return full, free_u_f


def launch_shape(batch: int, targets: int, tx: int, sy: int) -> tuple[tuple, tuple]:
    """``(grid, block)`` of the kernels of :func:`velocity_kernels` for ``batch`` members."""
    return (-(-targets // tx), batch), (tx, sy)
