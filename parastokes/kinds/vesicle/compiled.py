"""The vesicle's compiled parts for the loop of :mod:`parastokes.integrate.loop`.

The same compiled functions as :class:`.system.VesicleSystem`'s Python methods, in
the same order, so both loops give the same bits:

- rates: the spring forces (docs/physics.md (14)), the free-space kernel
  :func:`parastokes.mrs.compiled.free_u_f` (eq. 6) on the points padded as ``mrs.velocity`` pads
  them, plus the shear flow γ̇ z e_x (docs/physics.md (15));
- advance: ``x + dt * rates``; no bracket (positions commute);
- monitor: the relative change of the surface area.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numba.extending import overload

from ...bodies.geometry import mesh_area
from ...integrate import loop
from ...mrs import compiled
from .mechanics import spring_forces

if TYPE_CHECKING:  # system imports this module
    from .system import VesicleSystem

__all__ = ["VesicleData", "vesicle_data"]


class VesicleData(NamedTuple):
    """What the compiled parts of a :class:`.system.VesicleSystem` need."""

    edges: np.ndarray  # (E, 2)
    rest: np.ndarray  # (E,) rest lengths
    stiffness: float
    shear_rate: float
    triangles: np.ndarray  # (T, 3)
    area: float  # the initial sphere's
    eps: np.ndarray  # (1,)
    denom: np.ndarray  # (1,) 8πμ
    starts: np.ndarray  # the kernel's tiles; starts[-1] = the padded target count
    rate_columns: int = 3


def vesicle_data(system: VesicleSystem, threads: int) -> VesicleData:
    """The :class:`VesicleData` of ``system`` for kernels on ``threads`` threads."""
    return VesicleData(
        system.edges,
        system.rest_lengths,
        float(system.stiffness),
        float(system.shear_rate),
        system.mesh[1],
        float(system.initial_area),
        *loop.kernel_arguments(system, system.mesh[0].shape[0], threads),
    )


@overload(loop.workspace)
def _workspace(data, x):
    if loop.is_data(data, VesicleData):

        def impl(data, x):
            n = x.shape[0]
            return np.empty((3, 1, data.starts[-1])), np.empty((1, n, 3)), np.empty((1, n, 3))

        return impl


@overload(loop.rates_into)
def _rates_into(data, t, x, work, out):
    if loop.is_data(data, VesicleData):

        def impl(data, t, x, work, out):
            tp, s3, u = work
            n = x.shape[0]
            f = spring_forces(x, data.edges, data.rest, data.stiffness)
            loop.pack_points(x, tp, s3)
            compiled.free_u_f(tp, s3, f.reshape((1, n, 3)), data.eps, data.denom, data.starts, u)
            for i in range(n):
                for j in range(3):
                    out[i, j] = u[0, i, j]
                out[i, 0] += data.shear_rate * x[i, 2]

        return impl


@overload(loop.advance)
def _advance(data, x, rates, dt):
    if loop.is_data(data, VesicleData):

        def impl(data, x, rates, dt):
            out = np.empty_like(x)
            for i in range(x.shape[0]):
                for j in range(x.shape[1]):
                    out[i, j] = x[i, j] + dt * rates[i, j]
            return out

        return impl


@overload(loop.monitor)
def _monitor(data, x):
    if loop.is_data(data, VesicleData):
        return lambda data, x: abs(mesh_area(x, data.triangles) - data.area) / data.area


@overload(loop.bracket_into)
def _bracket_into(data, out, kp, kq, h):
    if loop.is_data(data, VesicleData):
        return lambda data, out, kp, kq, h: None


# ---- the parts a scene composes (parastokes.scene.compiled) -----------------------------------
@overload(loop.loads_into)
def _loads_into(data, t, x, forces, torques):
    if loop.is_data(data, VesicleData):

        def impl(data, t, x, forces, torques):
            forces[:, :] = spring_forces(x, data.edges, data.rest, data.stiffness)

        return impl


@overload(loop.body_rates_into)
def _body_rates_into(data, u, w, out):
    if loop.is_data(data, VesicleData):

        def impl(data, u, w, out):
            out[:, :] = u

        return impl
