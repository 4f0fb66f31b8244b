"""A scene's device parts, composed of its bodies' own (:class:`parastokes.scene.Scene` on the
GPU), as :mod:`parastokes.scene.compiled` composes their compiled parts for the CPU's loop.

``Scene`` registers :func:`scene_parts` for its type; a scene runs batched on the GPU when the
exact type of every body has device parts, and otherwise :func:`scene_parts` raises
:class:`parastokes.gpu.stepping.NoDevicePartsError` naming the body that has none. The same steps
as :meth:`Scene.rates` and the other Python methods:

- the velocity kernel over all points at once, each source with its body's ε
  (:attr:`DeviceParts.epsilon` = ``scene.source_epsilon``), plus the background shear
  u∞ = (γ̇ z, 0, 0) and w∞ = (0, γ̇/2, 0); each body's rates are the first ``rate columns`` of
  (u, w) at its rows;
- loads, advance and brackets: each body's own on its rows (its state columns; the padding
  columns of the state stay zero); the members' Θ are the bodies' parameters as ``"name.param"``;
- monitor: the largest of the bodies' monitors over their limits, NaN when one is not finite,
  infinite when a point is on or below the wall.

The composed functions are compiled once per mix of body kinds and layout (closures over each
body's rows and parameters, chained body by body).
"""

from __future__ import annotations

import functools
import math
from typing import Any

from numba import cuda

from ..bodies.device import DeviceFunctions, DeviceParts, itself, larger
from .stepping import NoDevicePartsError, block_monitor, device_parts

__all__ = ["scene_parts"]


def scene_parts(scene: Any) -> DeviceParts:
    """The device parts of ``scene``; NoDevicePartsError naming a body without any."""
    parts = []
    for name, body in zip(scene.names, scene.bodies, strict=True):
        try:
            parts.append(device_parts(body))
        except NoDevicePartsError as error:
            raise NoDevicePartsError(f"scene body {name!r}: {error}") from None
    names = tuple(f"{name}.{p}" for name, part in zip(scene.names, parts, strict=True)
                  for p in part.parameters)
    layout = tuple((first, rows, cols, rate_cols, float(body.monitor_limit))
                   for (first, rows, cols), rate_cols, body
                   in zip(scene.shapes, scene.rate_columns, scene.bodies, strict=True))
    return _composed(tuple(parts), layout, names, bool(scene.wall))


def _tables(scene: Any, cuda: Any, parts: tuple[DeviceParts, ...]) -> tuple:
    return tuple(part.tables(body, cuda) for part, body in zip(parts, scene.bodies, strict=True))


def _source_epsilon(scene: Any) -> Any:
    return scene.source_epsilon()


@functools.cache
def _composed(parts: tuple[DeviceParts, ...], layout: tuple, names: tuple[str, ...],
              wall: bool) -> DeviceParts:
    return DeviceParts(
        columns=max(cols for _, _, cols, _, _ in layout),
        rate_columns=max(rate_cols for _, _, _, rate_cols, _ in layout),
        parameters=names,
        torques=any(part.torques for part in parts),
        tables=functools.partial(_tables, parts=parts),
        functions=functools.partial(_functions, parts, layout, wall),
        epsilon=_source_epsilon,
    )


@functools.cache
def _functions(parts: tuple[DeviceParts, ...], layout: tuple, wall: bool, threads: int
               ) -> DeviceFunctions:
    jit = cuda.jit(device=True)
    own = [part.functions(threads) for part in parts]
    width = max(cols for _, _, cols, _, _ in layout)
    offsets, start = [], 0
    for part in parts:
        offsets.append((start, len(part.parameters)))
        start += len(part.parameters)

    def loads_from(i: int) -> Any:
        if i == len(parts):

            @jit
            def none(x, b, t, tid, theta, body, f, tq):
                pass

            return none
        head, rest = own[i].loads, loads_from(i + 1)
        first, rows = layout[i][0], layout[i][1]
        o, n = offsets[i]

        @jit
        def loads(x, b, t, tid, theta, body, f, tq):
            last = first + rows
            head(x[:, first:last], b, t, tid, theta[o : o + n], body[i], f[:, first:last],
                 tq[:, first:last])
            rest(x, b, t, tid, theta, body, f, tq)

        return loads

    def advance_from(i: int) -> Any:
        if i == len(parts):

            @jit
            def none(p, row, comb, h, out):
                pass

            return none
        head, rest = own[i].advance, advance_from(i + 1)
        first, rows, cols = layout[i][0], layout[i][1], layout[i][2]

        @jit
        def advance_at(p, row, comb, h, out):
            if first <= p < first + rows:
                head(row, comb, h, out)
                for q in range(cols, width):
                    out[q] = 0.0
            else:
                rest(p, row, comb, h, out)

        return advance_at

    def bracket_from(i: int) -> Any:
        while i < len(parts) and own[i].bracket is None:
            i += 1
        if i == len(parts):

            @jit
            def none(k, rows_table, st, b, p, h, comb):
                pass

            return none
        head, rest = own[i].bracket, bracket_from(i + 1)
        first, rows = layout[i][0], layout[i][1]

        @jit
        def bracket(k, rows_table, st, b, p, h, comb):
            if first <= p < first + rows:
                head(k, rows_table, st, b, p, h, comb)
            else:
                rest(k, rows_table, st, b, p, h, comb)

        return bracket

    def monitors_from(i: int) -> Any:
        if i == len(parts):

            @jit
            def none(x, b, tid, body, red, worst, finite):
                return worst, finite

            return none
        head = own[i].monitor or block_monitor(threads, own[i].monitor_part,
                                               own[i].monitor_join, own[i].monitor_value)
        rest = monitors_from(i + 1)
        first, rows, limit = layout[i][0], layout[i][1], layout[i][4]

        @jit
        def monitors(x, b, tid, body, red, worst, finite):
            value = head(x[:, first : first + rows], b, tid, body[i], red) / limit
            return rest(x, b, tid, body, red, max(worst, value),
                        finite and math.isfinite(value))

        return monitors

    @jit
    def below_wall(x, b, tid, body):
        """Infinite when one of this thread's points is on or below z = 0, else 0."""
        for p in range(tid, x.shape[1], threads):
            if not x[b, p, 2] > 0.0:
                return math.inf
        return 0.0

    crossed = block_monitor(threads, below_wall, jit(larger), jit(itself))
    bodies = monitors_from(0)

    @jit
    def monitor(x, b, tid, body, red):
        worst, finite = bodies(x, b, tid, body, red, -math.inf, True)
        if wall and crossed(x, b, tid, body, red) > 0.0:  # (wall: the same for every thread)
            return math.inf
        return worst if finite else math.nan

    return DeviceFunctions(loads_from(0), bracket=bracket_from(0), advance_at=advance_from(0),
                           monitor=monitor)
