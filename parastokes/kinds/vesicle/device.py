"""The vesicle's device parts (:class:`parastokes.bodies.device.DeviceParts`): its spring forces,
point advance and area monitor as CUDA device functions for the GPU's batched driver
(:mod:`parastokes.gpu.stepping`), built on the CPU's own compiled ``spring_pull`` and
``triangle_area2``. Imported only by a GPU solve (it imports ``numba.cuda``)."""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
from numba import cuda

from ...bodies.device import DeviceFunctions, DeviceParts, move_point, rows
from ...bodies.geometry import triangle_area2
from .mechanics import spring_pull

__all__ = ["PARTS"]

#: Columns of the vesicle's constant table: initial area, shear rate.
_V_AREA, _V_SHEAR = 0, 1


def _tables(system: Any, cuda: Any) -> tuple:
    """Per vertex its springs in edge order (offsets, incident edges), the edges, rest lengths,
    triangles and (initial area, shear rate), on the device."""
    edges = np.ascontiguousarray(system.edges, dtype=np.int64)
    n = system.mesh[0].shape[0]
    ends = np.concatenate([edges[:, 0], edges[:, 1]])
    ids = np.concatenate([np.arange(len(edges))] * 2)
    order = np.lexsort((ids, ends))  # per vertex, its springs in edge order
    offsets = np.searchsorted(ends[order], np.arange(n + 1))
    return (
        cuda.to_device(offsets.astype(np.int64)),
        cuda.to_device(ids[order].astype(np.int64)),
        cuda.to_device(edges),
        cuda.to_device(np.ascontiguousarray(system.rest_lengths, dtype=float)),
        cuda.to_device(np.ascontiguousarray(system.mesh[1], dtype=np.int64)),
        cuda.to_device(np.array([system.initial_area, system.shear_rate])),
    )


@functools.cache
def _functions(threads: int) -> DeviceFunctions:
    from numba import float64

    jit = cuda.jit(device=True)
    rows_ = jit(rows)

    @jit
    def loads(x, b, t, tid, theta, body, f, tq):
        """Spring forces at the vertices of member b (docs/physics.md (14)), each vertex summing its
        springs in edge order, as ``kinds.vesicle.mechanics.spring_forces`` does."""
        offsets, incident, edges, rest = body[0], body[1], body[2], body[3]
        two = cuda.local.array((2, 3), float64)
        for p in range(tid, x.shape[1], threads):
            fx = fy = fz = 0.0
            for slot in range(offsets[p], offsets[p + 1]):
                e = incident[slot]
                rows_(x, b, edges[e, 0], 3, two[0])
                rows_(x, b, edges[e, 1], 3, two[1])
                px, py, pz = spring_pull(two, 0, 1, rest[e], theta[0])
                if edges[e, 0] == p:
                    fx += px
                    fy += py
                    fz += pz
                else:
                    fx -= px
                    fy -= py
                    fz -= pz
            f[b, p, 0] = fx
            f[b, p, 1] = fy
            f[b, p, 2] = fz

    @jit
    def monitor_part(x, b, tid, body):
        """Twice the area of this thread's triangles; the monitor is |Σ/2 - A0| / A0."""
        triangles = body[4]
        three = cuda.local.array((3, 3), float64)
        total = 0.0
        for tri in range(tid, triangles.shape[0], threads):
            for v in range(3):
                rows_(x, b, triangles[tri, v], 3, three[v])
            total += triangle_area2(three, 0, 1, 2)
        return total

    @jit
    def monitor_join(first, second):
        return first + second

    @jit
    def monitor_value(joined, body):
        area = body[5][_V_AREA]
        return abs(0.5 * joined - area) / area

    return DeviceFunctions(loads, jit(move_point), monitor_part, monitor_join, monitor_value)


#: Θ on the device: ε, μ and the spring constant κ (``theta[0]``).
PARTS = DeviceParts(columns=3, rate_columns=3, parameters=("stiffness",), torques=False,
                    tables=_tables, functions=_functions)
