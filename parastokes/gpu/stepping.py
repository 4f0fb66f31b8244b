"""Batched Runge-Kutta solves on the GPU: B members of one system kind advance together.

A member is one call of a :class:`parastokes.integrate.Propagator`: its own start state, start
time, step h and step count, and its own parameters Θ (ε, μ and the body's others, e.g. the rods'
bending a, the vesicle's spring constant κ); all members share the scheme and the rest of the
system (points, rods, mesh, wave, wall). This module is the generic driver: what is specific to a
body kind are its device parts (:class:`parastokes.bodies.device.DeviceParts`: loads, advance,
brackets, monitor), found by the exact type of the system (``registry.loops.register_device``)
in the kind's own folder, so no module of this package names a body kind. The states stay on the
device for the whole solve; the host only launches kernels and copies the final states back.

Every step of an s-stage scheme is 2s launches, each over all members at once:

- the velocity kernel of :mod:`.kernels` (one per stage): ``k_i`` from the loads;
- a body kernel, one block per member, threads over its points: for stage i >= 1, the stage state
  ``advance(x, Σ_j a_ij k_j + brackets, h)`` and its loads; after the last stage, the new state
  ``advance(x, Σ_j b_j k_j + brackets, h)``, the finiteness check and the monitor (a reduction in
  the block), the decision (keep, or stop the member: non-finite state, monitor beyond the blow-up
  limit), and the loads of the next step's first stage.

This is :func:`parastokes.integrate.loop._run` spread over kernels: the same tableau (RKMK
brackets included), the same per-step checks and outcomes, and the bodies' own device functions
(the rod's and the vesicle's are their CPU's compiled functions compiled a second time for the
GPU). A member that stops is frozen (``mi[b, STATUS]`` leaves ``RUNNING``) and every kernel
skips it, so members with fewer steps cost nothing once done.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import cuda

from ..bodies.device import DeviceParts, rows
from ..core import plugins
from ..core.contracts import System
from ..integrate import BEYOND, DONE, NON_FINITE, Scheme
from ..integrate.loop import tableau_arrays
from ..mrs.velocity import EIGHT_PI
from ..registry import loops as registry
from . import device
from .kernels import (
    DENOM,
    EPS,
    MEND,
    NSTEPS,
    RUNNING,
    STATUS,
    STEP,
    T0,
    TAKEN,
    THETA,
    WORST,
    launch_shape,
    velocity_kernels,
)

__all__ = ["Launch", "Member", "NoDevicePartsError", "device_parts", "solve"]


class NoDevicePartsError(TypeError):
    """A system whose exact type has registered no device parts (docs/extending.md)."""


@dataclass(frozen=True)
class Launch:
    """Thread-block shapes: the velocity kernels' ``tx`` targets x ``sy`` source lanes, and the
    body kernels' ``threads`` per member (a power of two). The defaults suit an H100/H200;
    :meth:`default` picks small blocks on the simulator, which runs every thread in Python."""

    tx: int = 32
    sy: int = 8
    threads: int = 128

    def __post_init__(self) -> None:
        for name in ("tx", "sy", "threads"):
            value = getattr(self, name)
            if not isinstance(value, int) or value < 1:
                raise ValueError(f"{name}: must be a positive integer, got {value!r}")
        if self.threads & (self.threads - 1):
            raise ValueError(f"threads: must be a power of two (a tree reduction), got "
                             f"{self.threads}")

    @classmethod
    def default(cls) -> Launch:
        return cls(4, 2, 4) if device.simulated() else cls()


@dataclass(frozen=True)
class Member:
    """One solve of a batch: ``n`` steps of size ``h`` from ``(t0, x)`` (``x`` already projected)
    with the parameters of ``system`` (a variant of the batch's system: only Θ may differ)."""

    system: Any
    x: np.ndarray
    t0: float
    h: float
    n: int


def block_monitor(threads: int, part: Any, join: Any, value: Any) -> Any:
    """``monitor(x, b, tid, body, red)``: member b's monitor (every thread of the block gets it), a
    fixed-order tree reduction by ``join`` of the threads' values of ``part`` (e.g. max of the
    rods' length changes; sum of the vesicle's areas), then ``value`` of the result; ``red`` is
    the block's shared array of ``threads`` numbers."""

    @cuda.jit(device=True)
    def monitor(x, b, tid, body, red):
        red[tid] = part(x, b, tid, body)
        cuda.syncthreads()
        width = threads // 2
        while width > 0:
            if tid < width:
                red[tid] = join(red[tid], red[tid + width])
            cuda.syncthreads()
            width //= 2
        joined = red[0]
        cuda.syncthreads()
        return value(joined, body)

    return monitor


@functools.cache
def _body_kernels(parts: DeviceParts, threads: int) -> tuple:
    """``(begin, stage, finish)`` kernels of the body kind of ``parts`` for blocks of ``threads``
    threads (one block per member)."""
    from numba import float64, int64

    jit = cuda.jit(device=True)
    cols, rcols = parts.columns, parts.rate_columns
    rows_ = jit(rows)
    body_functions = parts.functions(threads)
    loads = body_functions.loads
    if body_functions.advance_at is not None:
        advance_at = body_functions.advance_at
    else:
        advance = body_functions.advance

        @jit
        def advance_at(p, row, comb, h, out):
            advance(row, comb, h, out)

    monitor = body_functions.monitor or block_monitor(
        threads, body_functions.monitor_part, body_functions.monitor_join,
        body_functions.monitor_value)
    if body_functions.bracket is not None:
        bracket = body_functions.bracket
    else:

        @jit
        def bracket(k, rows_table, st, b, p, h, comb):
            pass

    # ---- generic parts ------------------------------------------------------------------------
    @jit
    def combine(k, coefs, b, p, comb):
        """Σ_j coefs[j] k_j at point p, zero coefficients skipped, terms added in order (as
        ``integrate._combine``)."""
        first = True
        for j in range(coefs.shape[0]):
            c = coefs[j]
            if c != 0.0:
                for q in range(rcols):
                    comb[q] = c * k[j, b, p, q] if first else comb[q] + c * k[j, b, p, q]
                first = False

    @jit
    def advance_points(x, k, coefs, brackets, st, b, tid, h, out):
        """out[b, p] = advance(x[b, p], Σ_j coefs[j] k_j + brackets, h) for this thread's points;
        returns False when one of them is not finite."""
        comb = cuda.local.array(rcols, float64)
        row = cuda.local.array(cols, float64)
        new = cuda.local.array(cols, float64)
        finite = True
        for p in range(tid, x.shape[1], threads):
            combine(k, coefs, b, p, comb)
            bracket(k, brackets, st, b, p, h, comb)
            rows_(x, b, p, cols, row)
            advance_at(p, row, comb, h, new)
            for q in range(cols):
                out[b, p, q] = new[q]
                if not math.isfinite(new[q]):
                    finite = False
        return finite

    # ---- kernels ------------------------------------------------------------------------------
    @cuda.jit
    def begin(x, mf, mi, body, f, tq):
        """Loads of the first stage of the first step, and the initial monitor (the worst so
        far)."""
        b = cuda.blockIdx.x
        tid = cuda.threadIdx.x
        if mi[b, STATUS] != RUNNING:
            return
        red = cuda.shared.array(threads, float64)
        value = monitor(x, b, tid, body, red)
        if tid == 0:
            mf[b, WORST] = value
        loads(x, b, mf[b, T0], tid, mf[b, THETA:], body, f, tq)

    @cuda.jit
    def stage(st, step, x, k, a, c, brackets, mf, mi, body, xs, f, tq):
        """Stage ``st`` >= 1 of step ``step``: its state into ``xs``, and its loads."""
        b = cuda.blockIdx.x
        tid = cuda.threadIdx.x
        if mi[b, STATUS] != RUNNING:
            return
        h = mf[b, STEP]
        advance_points(x, k, a[st], brackets, st, b, tid, h, xs)
        cuda.syncthreads()
        t = mf[b, T0] + step * h
        loads(xs, b, t + c[st] * h, tid, mf[b, THETA:], body, f, tq)

    @cuda.jit
    def finish(step, x, k, weights, brackets, limit, mf, mi, body, xs, f, tq):
        """End of step ``step``: new state, checks, decision, next step's first loads."""
        b = cuda.blockIdx.x
        tid = cuda.threadIdx.x
        if mi[b, STATUS] != RUNNING:
            return
        flags = cuda.shared.array(2, int64)  # [any non-finite, keep the new state]
        red = cuda.shared.array(threads, float64)
        if tid == 0:
            flags[0] = 0
        cuda.syncthreads()
        h = mf[b, STEP]
        if not advance_points(x, k, weights, brackets, -1, b, tid, h, xs):
            flags[0] = 1
        cuda.syncthreads()
        value = monitor(xs, b, tid, body, red)
        if tid == 0:
            flags[1] = 0
            if flags[0]:
                mi[b, STATUS] = NON_FINITE
                mi[b, TAKEN] = step
                mf[b, MEND] = math.nan
            elif not value <= limit:
                mi[b, STATUS] = BEYOND
                mi[b, TAKEN] = step
                mf[b, MEND] = value
            else:
                flags[1] = 1
                mf[b, WORST] = max(mf[b, WORST], value)
                mi[b, TAKEN] = step + 1
                if step + 1 >= mi[b, NSTEPS]:
                    mi[b, STATUS] = DONE
                    mf[b, MEND] = mf[b, WORST]
        cuda.syncthreads()
        if flags[1]:
            for p in range(tid, x.shape[1], threads):
                for q in range(cols):
                    x[b, p, q] = xs[b, p, q]
            cuda.syncthreads()
            if step + 1 < mi[b, NSTEPS]:
                loads(x, b, mf[b, T0] + (step + 1) * h, tid, mf[b, THETA:], body, f, tq)

    return begin, stage, finish


@functools.cache
def _load_parts(target: str) -> Any:
    parts = plugins.import_target(target, target, NoDevicePartsError)
    if not (isinstance(parts, DeviceParts) or callable(parts)):
        raise NoDevicePartsError(f"{target} is neither a parastokes.bodies.device.DeviceParts "
                                 "nor a function of the system that returns one")
    return parts


def device_parts(system: System) -> DeviceParts:
    """The device parts registered for the exact type of ``system``; NoDevicePartsError naming
    the type otherwise (another class, or a subclass, whose physics may differ)."""
    target = registry.device_target(system)
    if target is None:
        raise NoDevicePartsError(
            f"{type(system).__name__} has no device parts: register them with "
            "parastokes.registry.loops.register_device (docs/extending.md, 'Running on the "
            "GPU'), or run it on a CPU executor"
        )
    parts = _load_parts(target)
    return parts if isinstance(parts, DeviceParts) else parts(system)


def gpu_system(system: System) -> Any:
    """``system`` itself when the GPU path reproduces it (its exact type has device parts, and a
    scene's bodies all have theirs), or None (another class, or a subclass, whose physics may
    differ; a rigid body; a scene with a body without device parts: hosted,
    :mod:`parastokes.gpu.hosted`)."""
    if registry.device_target(system) is None:
        return None
    try:
        device_parts(system)
    except NoDevicePartsError:
        return None
    return system


#: Steps launched between two looks at the members' status (to stop once all have finished).
POLL_STEPS = 256


def solve(
    scheme: Scheme,
    members: list[Member],
    limit: float,
    launch: Launch | None = None,
) -> list[tuple[np.ndarray, float, int, int, float]]:
    """Run all ``members`` (one system kind, the same points) together on the GPU.

    Returns, per member, what ``system.run_steps`` returns: ``(last state kept, worst monitor,
    steps kept, outcome, monitor that ended the run)``, outcome one of ``integrate.DONE``,
    ``NON_FINITE``, ``BEYOND``; ``limit`` is the blow-up limit of the monitor.
    """
    cuda = device.require()
    launch = launch or Launch.default()
    if min(mb.n for mb in members) < 1:
        raise ValueError("members: every member must take at least one step")
    first = members[0].system
    parts = device_parts(first)
    cols, rcols, names = parts.columns, parts.rate_columns, parts.parameters
    own = {"epsilon"} if parts.epsilon is None else {
        k for k in first.params if k.rpartition(".")[2] == "epsilon"}  # ε per source: a scene's
    extra = sorted(set(first.params) - {"viscosity", *own, *names})
    if extra:
        raise ValueError(f"{type(first).__name__}: its device parts hold no member values of "
                         f"the parameter(s) {extra} (DeviceParts.parameters: {list(names)})")
    nb = len(members)
    x = np.stack([np.asarray(mb.x, dtype=float) for mb in members])
    if x.shape[2] != cols:
        raise ValueError(f"x: expected {cols} columns per point, got {x.shape[2]}")
    npts = x.shape[1]
    mf = np.zeros((nb, THETA + max(len(names), 1)))
    mi = np.zeros((nb, 3), dtype=np.int64)
    for b, mb in enumerate(members):
        s = mb.system
        epsilon = s.epsilon if parts.epsilon is None else 0.0  # (then one per source, below)
        mf[b, [T0, STEP, EPS, DENOM]] = (mb.t0, mb.h, epsilon, EIGHT_PI * s.viscosity)
        params = s.params
        mf[b, THETA:THETA + len(names)] = [params[name] for name in names]
        mi[b] = (RUNNING, mb.n, 0)
    if parts.epsilon is None:
        eps = np.zeros((1, 1))  # not read
    else:
        eps = np.stack([np.asarray(parts.epsilon(mb.system), dtype=float) for mb in members])
    c, a, weights, stage_brackets, final_brackets = tableau_arrays(scheme)
    stages = weights.size

    d_x = cuda.to_device(x)
    d_xs = cuda.to_device(x)
    wall = bool(getattr(first, "wall", False))
    shear = float(getattr(first, "shear_rate", 0.0))
    use_full = parts.torques or wall  # u (and w) from forces and torques, wall images
    d_k = cuda.device_array((stages, nb, npts, max(rcols, 6) if use_full else rcols))
    k_views = [d_k[st] for st in range(stages)]
    d_f = cuda.device_array((nb, npts, 3))
    d_tq = cuda.to_device(np.zeros((nb, npts, 3)))  # (a body without torques leaves its rows 0)
    d_eps = cuda.to_device(eps)
    d_mf = cuda.to_device(mf)
    d_mi = cuda.to_device(mi)
    d_a, d_c, d_w = cuda.to_device(a), cuda.to_device(c), cuda.to_device(weights)
    d_sb = cuda.to_device(stage_brackets.reshape(-1, 4) if stage_brackets.size else
                          np.zeros((0, 4)))
    d_fb = cuda.to_device(final_brackets.reshape(-1, 3) if final_brackets.size else
                          np.zeros((0, 3)))
    body = parts.tables(first, cuda)
    begin, stage, finish = _body_kernels(parts, launch.threads)
    full, free_u_f = velocity_kernels(launch.tx, launch.sy, parts.epsilon is not None)
    grid, block = launch_shape(nb, npts, launch.tx, launch.sy)

    # launch configurations made once (each is reused for every step)
    begin, stage, finish = (kernel[nb, launch.threads] for kernel in (begin, stage, finish))
    full, free_u_f = full[grid, block], free_u_f[grid, block]

    def velocity(positions, out):
        if use_full:
            full(positions, positions, d_f, d_tq, d_mf, d_mi, wall, shear, d_eps, out)
        else:
            free_u_f(positions, positions, d_f, d_mf, d_mi, shear, d_eps, out)

    begin(d_x, d_mf, d_mi, body, d_f, d_tq)
    limit = float(limit)
    for step in range(int(mi[:, NSTEPS].max())):
        velocity(d_x, k_views[0])
        for st in range(1, stages):
            stage(st, step, d_x, d_k, d_a, d_c, d_sb, d_mf, d_mi, body, d_xs, d_f, d_tq)
            velocity(d_xs, k_views[st])
        finish(step, d_x, d_k, d_w, d_fb, limit, d_mf, d_mi, body, d_xs, d_f, d_tq)
        if (step + 1) % POLL_STEPS == 0 and not (d_mi.copy_to_host()[:, STATUS] == RUNNING).any():
            break
    x = d_x.copy_to_host()
    mf = d_mf.copy_to_host()
    mi = d_mi.copy_to_host()
    return [(x[b], float(mf[b, WORST]), int(mi[b, TAKEN]), int(mi[b, STATUS]), float(mf[b, MEND]))
            for b in range(nb)]
