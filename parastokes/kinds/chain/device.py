"""The chain's device parts (:class:`parastokes.bodies.device.DeviceParts`): its bead forces,
point advance and bond-strain monitor as CUDA device functions for the GPU's batched driver
(:mod:`parastokes.gpu.stepping`). Each bead sums the same terms in the same order as
:func:`.mechanics.chain_forces` (springs of its two bonds, then the bending of the angles at the
beads before it, at it and after it, then the external load), so the forces are the CPU's.
Imported only by a GPU solve (it imports ``numba.cuda``)."""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np
from numba import cuda

from ...bodies.device import DeviceFunctions, DeviceParts, itself, move_point

__all__ = ["PARTS"]


def _tables(system: Any, cuda: Any) -> tuple:
    """(bond b, load (3), wall as 0/1) on the device."""
    load = np.asarray(system.load, dtype=float)
    return (cuda.to_device(np.array([system.bond, *load, float(system.wall)])),)


@functools.cache
def _functions(threads: int) -> DeviceFunctions:
    jit = cuda.jit(device=True)

    @jit
    def bond_vector(x, b, i):
        """t_i = X_{i+1} - X_i of member b and its length."""
        tx = x[b, i + 1, 0] - x[b, i, 0]
        ty = x[b, i + 1, 1] - x[b, i, 1]
        tz = x[b, i + 1, 2] - x[b, i, 2]
        return tx, ty, tz, math.sqrt(tx ** 2 + ty ** 2 + tz ** 2)

    @jit
    def spring(x, b, i, stiffness, bond, j):
        """Component j of c t_i, c = k (|t_i| - b) / |t_i| (the spring of bond i)."""
        tx, ty, tz, length = bond_vector(x, b, i)
        c = stiffness * (length - bond) / length
        t = tx if j == 0 else (ty if j == 1 else tz)
        return c * t

    @jit
    def angle(x, b, i, j):
        """Component j of (∂cos/∂t_a, ∂cos/∂t_b) at the interior bead i (bonds a = i-1, b = i)."""
        ax, ay, az, la = bond_vector(x, b, i - 1)
        bx, by, bz, lb = bond_vector(x, b, i)
        cos = (ax * bx + ay * by + az * bz) / (la * lb)
        ta = ax if j == 0 else (ay if j == 1 else az)
        tb = bx if j == 0 else (by if j == 1 else bz)
        ua = ta / la
        ub = tb / lb
        return (ub - cos * ua) / la, (ua - cos * ub) / lb

    @jit
    def loads(x, b, t, tid, theta, body, f, tq):
        """F_i = -∂E/∂X_i + load at the beads of member b (``kinds.chain`` docstring)."""
        c = body[0]
        bond = c[0]
        stiffness = theta[0]
        w = theta[1] / bond
        n = x.shape[1]
        for p in range(tid, n, threads):
            for j in range(3):
                value = 0.0
                if p >= 1:
                    value -= spring(x, b, p - 1, stiffness, bond, j)
                if p <= n - 2:
                    value += spring(x, b, p, stiffness, bond, j)
                if 1 <= p - 1 <= n - 2:
                    da, db = angle(x, b, p - 1, j)
                    value += w * db
                if 1 <= p <= n - 2:
                    da, db = angle(x, b, p, j)
                    value += w * (da - db)
                if p + 1 <= n - 2:
                    da, db = angle(x, b, p + 1, j)
                    value -= w * da
                f[b, p, j] = value + c[1 + j]

    @jit
    def monitor_part(x, b, tid, body):
        """The largest |t_i|/b - 1 of this thread's bonds; infinite when one of its beads is on or
        below the wall (as ``bodies.geometry.crossed_wall``)."""
        c = body[0]
        n = x.shape[1]
        worst = 0.0
        for i in range(tid, n, threads):
            if c[4] != 0.0 and not x[b, i, 2] > 0.0:
                return math.inf
            if i < n - 1:
                _, _, _, length = bond_vector(x, b, i)
                strain = abs(length / c[0] - 1.0)
                if not strain <= worst:  # NaN propagates
                    worst = strain
        return worst

    @jit
    def monitor_join(first, second):
        return second if second > first or second != second else first  # NaN propagates

    return DeviceFunctions(loads, jit(move_point), monitor_part, monitor_join, jit(itself))


#: Θ on the device: ε, μ, the spring constant k (``theta[0]``) and the bending modulus κ
#: (``theta[1]``).
PARTS = DeviceParts(columns=3, rate_columns=3, parameters=("stiffness", "bending"), torques=False,
                    tables=_tables, functions=_functions)
