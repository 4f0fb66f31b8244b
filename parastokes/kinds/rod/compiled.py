"""The rod system's compiled parts for the loop of :mod:`parastokes.integrate.loop`.

The same compiled functions as :class:`.system.RodSystem`'s Python methods, in the
same order, so both loops give the same bits:

- rates: the preferred strain (eq. 36), the rod loads (eqs. 10-12), and ``u``, ``w`` from the
  kernel :func:`parastokes.mrs.compiled.full` on the points padded as ``mrs.velocity`` pads them;
- advance: ``advance_rod`` (eq. 13); bracket: ``[0, w_p × w_q]`` per node (RKMK4);
- monitor: the largest relative length change over the rods.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numba.extending import overload

from ...bodies.frames import advance_rod
from ...bodies.geometry import crossed_wall
from ...integrate import loop
from ...mrs import compiled
from .mechanics import length_change, preferred_strain, rod_loads

if TYPE_CHECKING:  # system imports this module
    from .system import RodSystem

__all__ = ["RodData", "rod_data"]


class RodData(NamedTuple):
    """What the compiled parts of a :class:`.system.RodSystem` need."""

    mechanics: tuple  # RodSystem.mechanics (n_rods first)
    eps: np.ndarray  # (1,)
    denom: np.ndarray  # (1,) 8πμ
    starts: np.ndarray  # the kernel's tiles; starts[-1] = the padded target count
    wall: bool
    length: float
    rate_columns: int = 6
    phi: bool = False  # the kernel's torque-blob flag, as RodSystem.rates passes it (a typed
    # bool, not a literal False: the same compiled kernel as mrs.velocity's, not a second one)


def rod_data(system: RodSystem, threads: int) -> RodData:
    """The :class:`RodData` of ``system`` for kernels on ``threads`` threads."""
    return RodData(
        system.mechanics,
        *loop.kernel_arguments(system, system.n_rods * system.n_points, threads),
        bool(system.wall),
        float(system.length),
    )


@overload(loop.workspace)
def _workspace(data, x):
    if loop.is_data(data, RodData):

        def impl(data, x):
            n = x.shape[0]
            return (np.empty((3, 1, data.starts[-1])), np.empty((1, n, 3)), np.empty((1, n, 3)),
                    np.empty((1, n, 3)))

        return impl


@overload(loop.rates_into)
def _rates_into(data, t, x, work, out):
    if loop.is_data(data, RodData):

        def impl(data, t, x, work, out):
            n_rods, ds, a, b, table, constant, amplitude, wavenumber, frequency = data.mechanics
            tp, s3, u, w = work
            n = x.shape[0]
            omega_hat = preferred_strain(table, t, constant, amplitude, wavenumber, frequency)
            f, tq = rod_loads(x, n_rods, ds, a, b, omega_hat)
            loop.pack_points(x, tp, s3)
            compiled.full(tp, s3, f.reshape((1, n, 3)), tq.reshape((1, n, 3)), data.eps,
                          data.wall, data.phi, data.denom, data.starts, u, w)
            for i in range(n):
                for j in range(3):
                    out[i, j] = u[0, i, j]
                    out[i, 3 + j] = w[0, i, j]

        return impl


@overload(loop.advance)
def _advance(data, x, rates, dt):
    if loop.is_data(data, RodData):
        return lambda data, x, rates, dt: advance_rod(x, rates, dt)


@overload(loop.monitor)
def _monitor(data, x):
    if loop.is_data(data, RodData):
        def impl(data, x):
            if crossed_wall(x, data.wall):
                return math.inf
            return length_change(x, data.mechanics[0], data.length)

        return impl


@overload(loop.bracket_into)
def _bracket_into(data, out, kp, kq, h):
    if loop.is_data(data, RodData):

        def impl(data, out, kp, kq, h):
            for i in range(out.shape[0]):
                out[i, 3] += h * (kp[i, 4] * kq[i, 5] - kp[i, 5] * kq[i, 4])
                out[i, 4] += h * (kp[i, 5] * kq[i, 3] - kp[i, 3] * kq[i, 5])
                out[i, 5] += h * (kp[i, 3] * kq[i, 4] - kp[i, 4] * kq[i, 3])

        return impl


# ---- the parts a scene composes (parastokes.scene.compiled) -----------------------------------
@overload(loop.loads_into)
def _loads_into(data, t, x, forces, torques):
    if loop.is_data(data, RodData):

        def impl(data, t, x, forces, torques):
            n_rods, ds, a, b, table, constant, amplitude, wavenumber, frequency = data.mechanics
            omega_hat = preferred_strain(table, t, constant, amplitude, wavenumber, frequency)
            f, tq = rod_loads(x, n_rods, ds, a, b, omega_hat)
            forces[:, :] = f
            torques[:, :] = tq

        return impl


@overload(loop.body_rates_into)
def _body_rates_into(data, u, w, out):
    if loop.is_data(data, RodData):

        def impl(data, u, w, out):
            out[:, :3] = u
            out[:, 3:6] = w

        return impl
