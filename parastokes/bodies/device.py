"""What a body kind supplies to be solved batched on the GPU (:mod:`parastokes.gpu`): its device
parts, as the compiled parts of :mod:`parastokes.integrate.loop` are its parts of the CPU's loop.

The GPU's batched Runge-Kutta driver (:mod:`parastokes.gpu.stepping`) advances B members of one
system structure together (each its own start state, time, step, step count and Θ) and knows no
body: per stage it runs the velocity kernel over all members (eq. 6 with the body's loads; forces
only in free space, or forces and torques and the wall images, docs/physics.md (1)-(8)), adds the
background shear u∞ = (γ̇ z, 0, 0) of a system's ``shear_rate`` (docs/physics.md (15)), and calls
the body's device functions for the rest: its loads, the advance of a point by the combined rates,
the RKMK brackets of frames, and the monitor. A kind gives these as a :class:`DeviceParts` value in
a module of its own folder (``kinds/<kind>/device.py``), registered for its exact system type by
``registry.loops.register_device(cls, "package.module:PARTS")`` when its system module is
imported; the module is imported only when a GPU solve needs it (it imports ``numba.cuda``).

Device functions are plain Python compiled by ``numba.cuda.jit(device=True)`` in the kind's
``functions(threads)``; member ``b``'s state is ``x[b]`` (points x columns), and a body function
runs on the ``threads`` threads of member b's block, thread ``tid`` taking the points ``tid, tid +
threads, ...``. The arguments (see docs/extending.md, "Running on the GPU"):

- ``loads(x, b, t, tid, theta, body, f, tq)``: the forces ``f[b, p, :3]`` (and torques ``tq[b, p,
  :3]`` with ``torques``) at this thread's points p at time t; ``theta`` holds the member's values
  of :attr:`DeviceParts.parameters` in that order, ``body`` the tables of ``tables``;
- ``advance(row, comb, h, out)``: one point: ``out`` = advance(``row``, ``comb``, h), ``comb`` its
  combined rates Σ_j a_j k_j (``rate_columns`` numbers);
- ``bracket(k, rows, st, b, p, h, comb)`` (None: no frames): add the RKMK commutator terms of stage
  ``st`` (-1: the final ones) to ``comb``;
- ``monitor_part(x, b, tid, body)``, ``monitor_join(a, b)``, ``monitor_value(joined, body)``: the
  member's monitor is ``monitor_value`` of the tree reduction by ``monitor_join`` (max, +) of the
  threads' parts.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NamedTuple

__all__ = ["DeviceFunctions", "DeviceParts", "itself", "larger", "move_point", "rows"]


class DeviceFunctions(NamedTuple):
    """The device functions of a kind for blocks of a given number of threads (module docstring).

    A composite of bodies (a scene, :mod:`parastokes.gpu.scene`) gives instead of ``advance``
    ``advance_at(p, row, comb, h, out)`` (the advance of point p, whichever body it belongs to),
    and instead of the monitor's three parts the whole block's ``monitor(x, b, tid, body, red)``
    (``red``: the block's shared array of ``threads`` numbers)."""

    loads: Callable[..., Any]
    advance: Callable[..., Any] | None = None
    monitor_part: Callable[..., Any] | None = None
    monitor_join: Callable[..., Any] | None = None
    monitor_value: Callable[..., Any] | None = None
    bracket: Callable[..., Any] | None = None
    advance_at: Callable[..., Any] | None = None
    monitor: Callable[..., Any] | None = None


@dataclass(frozen=True)
class DeviceParts:
    """A body kind's device parts (module docstring).

    - ``columns``, ``rate_columns``: state and rate columns per point;
    - ``parameters``: the names of Θ held per member besides ``epsilon`` and ``viscosity`` (every
      name of ``system.params`` must be one of these three kinds);
    - ``torques``: whether the loads include torques (the full velocity kernel, u and w);
    - ``tables(system, cuda)``: the constant device arrays of a batch's structure, a tuple (the
      ``body`` argument of the device functions);
    - ``functions(threads)``: the :class:`DeviceFunctions` for blocks of ``threads`` threads
      (compiled for CUDA; cache them per ``threads``);
    - ``epsilon(system)`` (None: the system's ``epsilon``): the ε of every point as a source, (N,),
      when the sources have their own (a scene's bodies).
    """

    columns: int
    rate_columns: int
    parameters: tuple[str, ...]
    torques: bool
    tables: Callable[[Any, Any], tuple]
    functions: Callable[[int], DeviceFunctions]
    epsilon: Callable[[Any], Any] | None = None


def rows(x, b, p, cols, out):
    """``out[:cols]`` = point ``p`` of member ``b`` of the batched state ``x`` (a device function
    once compiled by the caller)."""
    for q in range(cols):
        out[q] = x[b, p, q]


# Parts many kinds share (plain Python: each kind compiles them with cuda.jit(device=True)).


def move_point(row, comb, h, out):
    """``advance`` of a point moved by the fluid: X + h u (3 columns)."""
    for q in range(3):
        out[q] = row[q] + h * comb[q]


def larger(first, second):
    """``monitor_join`` by the larger of two parts."""
    return max(first, second)


def itself(joined, body):
    """``monitor_value`` when the joined parts are the monitor."""
    return joined
