"""The chain's compiled parts for the loop of :mod:`parastokes.integrate.loop`, alone and in a
scene (:mod:`parastokes.scene.compiled`).

The same compiled functions as :class:`parastokes.kinds.chain.ChainSystem`'s Python methods, in
the same order, so the loops give the same bits:

- loads: :func:`.mechanics.chain_forces` plus the external load on every bead;
- rates: the loads, the fluid's velocity as :class:`parastokes.fluid.MRS` computes it
  (:func:`parastokes.fluid.compiled.velocity_into`: free-space Stokeslets, or with the wall's
  images), plus the shear flow γ̇ z e_x (docs/physics.md (15));
- advance: ``x + dt * rates``; no bracket (positions commute);
- monitor: :func:`.mechanics.bond_strain`.

Registered for :class:`~parastokes.kinds.chain.ChainSystem` with the :class:`parastokes.fluid.MRS`
fluid by :func:`parastokes.integrate.loop.register_parts` (the end of
:mod:`parastokes.kinds.chain`).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numba.extending import overload

from ...bodies.geometry import crossed_wall
from ...fluid.compiled import fluid_workspace, velocity_into
from ...integrate import loop
from .mechanics import bond_strain, chain_forces

if TYPE_CHECKING:  # the package imports this module
    from . import ChainSystem

__all__ = ["ChainData", "chain_data"]


class ChainData(NamedTuple):
    """What the compiled parts of a chain need."""

    bond: float
    stiffness: float
    bending: float
    load: np.ndarray  # (3,) the external force on every bead
    shear_rate: float
    wall: bool
    eps: np.ndarray  # (1,)
    denom: np.ndarray  # (1,) 8πμ
    starts: np.ndarray  # the kernel's tiles; starts[-1] = the padded target count
    rate_columns: int = 3
    phi: bool = False  # the kernel's torque-blob flag, as mrs.velocity passes it


def chain_data(system: ChainSystem, threads: int) -> ChainData:
    """The :class:`ChainData` of ``system`` for kernels on ``threads`` threads."""
    return ChainData(
        float(system.bond),
        float(system.stiffness),
        float(system.bending),
        np.asarray(system.load, dtype=float),
        float(system.shear_rate),
        bool(system.wall),
        *loop.kernel_arguments(system, system.n_beads, threads),
    )


@overload(loop.workspace)
def _workspace(data, x):
    if loop.is_data(data, ChainData):
        return lambda data, x: fluid_workspace(x.shape[0], data.starts[-1])


@overload(loop.loads_into)
def _loads_into(data, t, x, forces, torques):
    if loop.is_data(data, ChainData):

        def impl(data, t, x, forces, torques):
            f = chain_forces(x, data.bond, data.stiffness, data.bending)
            for i in range(f.shape[0]):
                for j in range(3):
                    forces[i, j] = f[i, j] + data.load[j]

        return impl


@overload(loop.rates_into)
def _rates_into(data, t, x, work, out):
    if loop.is_data(data, ChainData):

        def impl(data, t, x, work, out):
            loop.loads_into(data, t, x, work[2][0], work[3][0])
            velocity_into(x, work, data.eps, data.denom, data.starts, data.wall, False, data.phi)
            u = work[4][0]
            for i in range(x.shape[0]):
                out[i, 0] = u[i, 0] + data.shear_rate * x[i, 2]
                out[i, 1] = u[i, 1]
                out[i, 2] = u[i, 2]

        return impl


@overload(loop.body_rates_into)
def _body_rates_into(data, u, w, out):
    if loop.is_data(data, ChainData):

        def impl(data, u, w, out):
            out[:, :] = u

        return impl


@overload(loop.advance)
def _advance(data, x, rates, dt):
    if loop.is_data(data, ChainData):
        return lambda data, x, rates, dt: x + dt * rates


@overload(loop.monitor)
def _monitor(data, x):
    if loop.is_data(data, ChainData):
        def impl(data, x):
            if crossed_wall(x, data.wall):
                return math.inf
            return bond_strain(x, data.bond)

        return impl


@overload(loop.bracket_into)
def _bracket_into(data, out, kp, kq, h):
    if loop.is_data(data, ChainData):
        return lambda data, out, kp, kq, h: None
