"""The rod's device parts (:class:`parastokes.bodies.device.DeviceParts`): its loads, node advance,
RKMK brackets and monitor as CUDA device functions for the GPU's batched driver
(:mod:`parastokes.gpu.stepping`). The mechanics are the CPU's own compiled functions
(``segment_loads``, ``advance_node``), compiled a second time for CUDA, so the GPU cannot drift from
the tested physics. Imported only by a GPU solve (it imports ``numba.cuda``)."""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np
from numba import cuda

from ...bodies.device import DeviceFunctions, DeviceParts, larger, rows
from ...bodies.frames import advance_node
from .mechanics import segment_loads

__all__ = ["PARTS"]

#: Columns of the rods' constant table: 1/Δs, b1, b2, b3, Ω̂ constant (3), amplitude, wavenumber,
#: frequency, length L.
_R_INV_DS, _R_B, _R_CONST, _R_AMP, _R_K, _R_FREQ, _R_LEN = 0, 1, 4, 7, 8, 9, 10


def _tables(system: Any, cuda: Any) -> tuple:
    """(the preferred-strain table, the constants above, points per rod) on the device."""
    _, ds, _, shear, table, constant, amplitude, wavenumber, frequency = system.mechanics
    consts = np.array([1.0 / ds, *shear, *constant, amplitude, wavenumber, frequency,
                       system.length])
    return (cuda.to_device(np.ascontiguousarray(table)), cuda.to_device(consts),
            int(system.n_points))


@functools.cache
def _functions(threads: int) -> DeviceFunctions:
    from numba import float64

    jit = cuda.jit(device=True)
    rows_ = jit(rows)

    @jit
    def segment(x, b, k, t, theta, body):
        """(F, N, lever) of the rod segment (k, k + 1) of member b at time t (eqs. 9-12, 36)."""
        table, c, m = body
        kk = k % m
        scale = -(c[_R_K] ** 2) * c[_R_AMP]
        sft = scale * math.sin(c[_R_FREQ] * t)
        cft = scale * math.cos(c[_R_FREQ] * t)
        o2 = c[_R_CONST + 1]
        if c[_R_AMP] != 0.0:
            o2 += table[kk, 0] * cft + table[kk, 1] * sft
        p = cuda.local.array(12, float64)
        q = cuda.local.array(12, float64)
        rows_(x, b, k, 12, p)
        rows_(x, b, k + 1, 12, q)
        a = theta[0]
        return segment_loads(p, q, c[_R_INV_DS], a, a, a, c[_R_B], c[_R_B + 1], c[_R_B + 2],
                             c[_R_CONST], o2, c[_R_CONST + 2])

    @jit
    def loads(x, b, t, tid, theta, body, f, tq):
        """f, tq at the points of member b (eq. 12), summed as ``kinds.rod.mechanics.rod_loads``
        does."""
        m = body[2]
        for p in range(tid, x.shape[1], threads):
            kk = p % m
            fx = fy = fz = nx = ny = nz = 0.0
            if kk > 0:
                gx, gy, gz, mx, my, mz, lx, ly, lz = segment(x, b, p - 1, t, theta, body)
                fx -= gx
                fy -= gy
                fz -= gz
                nx += lx - mx
                ny += ly - my
                nz += lz - mz
            if kk < m - 1:
                gx, gy, gz, mx, my, mz, lx, ly, lz = segment(x, b, p, t, theta, body)
                fx += gx
                fy += gy
                fz += gz
                nx += mx + lx
                ny += my + ly
                nz += mz + lz
            f[b, p, 0] = fx
            f[b, p, 1] = fy
            f[b, p, 2] = fz
            tq[b, p, 0] = nx
            tq[b, p, 1] = ny
            tq[b, p, 2] = nz

    @jit
    def advance(row, comb, h, out):
        advance_node(row, comb, h, out)

    @jit
    def bracket(k, rows_table, st, b, p, h, comb):
        """Add the RKMK commutator terms of stage ``st`` (-1: the final ones) to ``comb``."""
        off = 0 if st < 0 else 1
        for r in range(rows_table.shape[0]):
            if st < 0 or rows_table[r, 0] == st:
                c = rows_table[r, off] * h
                kp = int(rows_table[r, off + 1])
                kq = int(rows_table[r, off + 2])
                comb[3] += c * (k[kp, b, p, 4] * k[kq, b, p, 5] - k[kp, b, p, 5] * k[kq, b, p, 4])
                comb[4] += c * (k[kp, b, p, 5] * k[kq, b, p, 3] - k[kp, b, p, 3] * k[kq, b, p, 5])
                comb[5] += c * (k[kp, b, p, 3] * k[kq, b, p, 4] - k[kp, b, p, 4] * k[kq, b, p, 3])

    @jit
    def monitor_part(x, b, tid, body):
        """|length - L| of rod ``tid`` (0 for the other threads); the monitor is their max / L."""
        m = body[2]
        if tid >= x.shape[1] // m:
            return 0.0
        total = 0.0
        for k in range(tid * m, (tid + 1) * m - 1):
            dx = x[b, k + 1, 0] - x[b, k, 0]
            dy = x[b, k + 1, 1] - x[b, k, 1]
            dz = x[b, k + 1, 2] - x[b, k, 2]
            total += math.sqrt(dx * dx + dy * dy + dz * dz)
        return abs(total - body[1][_R_LEN])

    @jit
    def monitor_value(joined, body):
        return joined / body[1][_R_LEN]

    return DeviceFunctions(loads, advance, monitor_part, jit(larger), monitor_value, bracket)


#: Θ on the device: ε, μ and the bending modulus a (``theta[0]``).
PARTS = DeviceParts(columns=12, rate_columns=6, parameters=("bending",), torques=True,
                    tables=_tables, functions=_functions)
