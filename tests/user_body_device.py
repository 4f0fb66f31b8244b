"""The GPU device parts of ``user_body.SedimentingCloud``, written outside parastokes as
docs/extending.md ("Running on the GPU") teaches; ``user_body`` registers them for its class.
``numba.cuda`` is imported only when a GPU solve asks for the parts."""

from __future__ import annotations

import functools
import math

import numpy as np

from parastokes.bodies.device import DeviceFunctions, DeviceParts, itself, larger, move_point


def gyration(x: np.ndarray) -> float:
    return float(np.sqrt(((x - x.mean(axis=0)) ** 2).sum(axis=1).mean()))


def tables(system, cuda) -> tuple:
    """(weight, radius of gyration of the initial state) on the device."""
    return (cuda.to_device(np.array([system.weight, gyration(system.initial_state())])),)


@functools.cache
def functions(threads: int) -> DeviceFunctions:
    from numba import cuda

    jit = cuda.jit(device=True)

    @jit
    def loads(x, b, t, tid, theta, body, f, tq):
        for p in range(tid, x.shape[1], threads):
            f[b, p, 0] = 0.0
            f[b, p, 1] = 0.0
            f[b, p, 2] = -body[0][0]

    @jit
    def monitor_part(x, b, tid, body):
        """Thread 0 computes the whole monitor (a small cloud); the others give 0."""
        if tid != 0:
            return 0.0
        n = x.shape[1]
        cx = cy = cz = 0.0
        for p in range(n):
            cx += x[b, p, 0]
            cy += x[b, p, 1]
            cz += x[b, p, 2]
        cx, cy, cz = cx / n, cy / n, cz / n
        total = 0.0
        for p in range(n):
            total += (x[b, p, 0] - cx) ** 2 + (x[b, p, 1] - cy) ** 2 + (x[b, p, 2] - cz) ** 2
        return abs(math.sqrt(total / n) / body[0][1] - 1.0)

    # the point's advance X + h u, the larger part and the value itself: parts many kinds share
    return DeviceFunctions(loads, jit(move_point), monitor_part, jit(larger), jit(itself))


PARTS = DeviceParts(columns=3, rate_columns=3, parameters=(), torques=False, tables=tables,
                    functions=functions)
