"""A scene's compiled parts for the loop of :mod:`parastokes.integrate.loop`, composed from its
bodies' own.

A :class:`parastokes.scene.Scene` is stepped in compiled code when every body's exact type has
registered compiled parts (:func:`parastokes.integrate.loop.register_parts`); its data
:class:`SceneData` holds every body's data with its rows, and each part runs its bodies' parts in
turn (``numba.literal_unroll`` over the heterogeneous tuple of bodies: one compiled loop per mix
of body types). The same steps as :meth:`Scene.rates` and the other Python methods, so both loops
give the same bits:

- rates: every body's loads (``loads_into``) into one array of all points, one kernel call over
  all of them with each source's own ε (:func:`parastokes.fluid.compiled.velocity_into`), the
  background shear u∞ = (γ̇ z, 0, 0) and w∞ = (0, γ̇/2, 0), then every body's rates from the
  velocities at its rows (``body_rates_into``), zero in the columns past a body's own;
- advance, bracket: every body's on its rows and columns, the padding columns zero;
- monitor: the largest of the bodies' monitors over their limits (NaN if one is not finite).

:mod:`parastokes.scene` imports this module (to register the loop for ``Scene``), so ``scene``
below is annotated ``Any``: this module does not import the scene back.
"""

from __future__ import annotations

import functools
import math
from typing import Any, NamedTuple

import numpy as np
from numba import literal_unroll
from numba.extending import overload

from ..bodies.geometry import crossed_wall
from ..fluid.compiled import fluid_workspace, velocity_into
from ..integrate import loop
from ..mrs import compiled
from ..mrs.velocity import EIGHT_PI
from ..registry import loops as registry
from ..registry.loops import RunSteps

__all__ = ["SceneData", "scene_data", "scene_loop"]


class SceneData(NamedTuple):
    """What the compiled parts of a scene need."""

    bodies: tuple  # per body (first row, rows, state columns, rate columns, monitor limit, data)
    eps: np.ndarray  # (1, N): every point's ε (its body's)
    denom: np.ndarray  # (1,) 8πμ
    starts: np.ndarray  # the kernel's tiles; starts[-1] = the padded target count
    wall: bool
    angular: bool  # some body's rates include angular velocities
    shear_rate: float
    rate_columns: int
    phi: bool = False  # the kernel's torque-blob flag, as mrs.velocity passes it


def _body_data(body: Any, threads: int) -> tuple:
    """The compiled data of one body of a scene (TypeError for a body without one)."""
    make_data = registry.compiled_data(body)
    if make_data is None:
        raise TypeError(f"{type(body).__name__} has no compiled parts to join a scene's loop")
    return make_data(body, threads)


def scene_data(scene: Any, threads: int) -> SceneData:
    """The :class:`SceneData` of ``scene`` for kernels on ``threads`` threads."""
    bodies = tuple(
        (first, rows, cols, rate_cols, float(body.monitor_limit), _body_data(body, threads))
        for body, (first, rows, cols), rate_cols in zip(
            scene.bodies, scene.shapes, scene.rate_columns, strict=True)
    )
    n = bodies[-1][0] + bodies[-1][1]
    return SceneData(
        bodies,
        scene.source_epsilon().reshape(1, n),
        np.full(1, EIGHT_PI * scene.viscosity),
        compiled.tile_starts(compiled.padded_size(n), threads),
        bool(scene.wall),
        any(body.angular for body in scene.bodies),
        float(scene.shear_rate),
        max(scene.rate_columns),
    )


def scene_loop(scene: Any) -> RunSteps | None:
    """The compiled loop of ``scene`` (registered for :class:`parastokes.scene.Scene`), or None
    when a body's exact type has no compiled parts: the scene then runs the Python loop."""
    if any(registry.compiled_data(body) is None for body in scene.bodies):
        return None
    return functools.partial(loop.run_steps, scene, scene_data)


@overload(loop.workspace)
def _workspace(data, x):
    if loop.is_data(data, SceneData):
        return lambda data, x: fluid_workspace(x.shape[0], data.starts[-1])


@overload(loop.rates_into)
def _rates_into(data, t, x, work, out):
    if loop.is_data(data, SceneData):

        def impl(data, t, x, work, out):
            f, tq, u, w = work[2][0], work[3][0], work[4][0], work[5][0]
            for body in literal_unroll(data.bodies):
                first, rows, cols, _, _, part = body
                last = first + rows
                loop.loads_into(part, t, x[first:last, :cols], f[first:last], tq[first:last])
            velocity_into(x, work, data.eps, data.denom, data.starts, data.wall, data.angular,
                          data.phi)
            if not data.angular:
                w[:, :] = 0.0  # not asked of the fluid: zero, as Scene.rates has it
            for i in range(x.shape[0]):
                u[i, 0] += data.shear_rate * x[i, 2]
                w[i, 1] += 0.5 * data.shear_rate
            for body in literal_unroll(data.bodies):
                first, rows, _, rate_cols, _, part = body
                last = first + rows
                loop.body_rates_into(part, u[first:last], w[first:last],
                                     out[first:last, :rate_cols])
                out[first:last, rate_cols:] = 0.0

        return impl


@overload(loop.advance)
def _advance(data, x, rates, dt):
    if loop.is_data(data, SceneData):

        def impl(data, x, rates, dt):
            out = np.zeros_like(x)
            for body in literal_unroll(data.bodies):
                first, rows, cols, rate_cols, _, part = body
                last = first + rows
                out[first:last, :cols] = loop.advance(part, x[first:last, :cols],
                                                      rates[first:last, :rate_cols], dt)
            return out

        return impl


@overload(loop.monitor)
def _monitor(data, x):
    if loop.is_data(data, SceneData):

        def impl(data, x):
            if crossed_wall(x, data.wall):
                return math.inf
            worst = -math.inf
            finite = True
            for body in literal_unroll(data.bodies):
                first, rows, cols, _, limit, part = body
                value = loop.monitor(part, x[first : first + rows, :cols]) / limit
                finite = finite and math.isfinite(value)
                worst = max(worst, value)
            return worst if finite else math.nan

        return impl


@overload(loop.bracket_into)
def _bracket_into(data, out, kp, kq, h):
    if loop.is_data(data, SceneData):

        def impl(data, out, kp, kq, h):
            for body in literal_unroll(data.bodies):
                first, rows, _, rate_cols, _, part = body
                last = first + rows
                loop.bracket_into(part, out[first:last, :rate_cols], kp[first:last, :rate_cols],
                                  kq[first:last, :rate_cols], h)

        return impl
