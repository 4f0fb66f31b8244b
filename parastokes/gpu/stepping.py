"""Batched Runge-Kutta solves on the GPU: B members of one system kind advance together.

A member is one call of a :class:`parastokes.integrate.Propagator`: its own start state, start
time, step h and step count, and its own parameters Θ (ε, μ and the body's modulus: the rods'
bending a, the vesicle's spring constant κ); all members share the scheme and the rest of the
system (points, rods, mesh, wave, wall). The states stay on the device for the whole solve; the
host only launches kernels and copies the final states back.

Every step of an s-stage scheme is 2s launches, each over all members at once:

- the velocity kernel of :mod:`.kernels` (one per stage): ``k_i`` from the loads;
- a body kernel, one block per member, threads over its points: for stage i >= 1, the stage state
  ``advance(x, Σ_j a_ij k_j + brackets, h)`` and its loads; after the last stage, the new state
  ``advance(x, Σ_j b_j k_j + brackets, h)``, the finiteness check and the monitor (a reduction in
  the block), the decision (keep, or stop the member: non-finite state, monitor beyond the blow-up
  limit), and the loads of the next step's first stage.

This is :func:`parastokes.stepping.loop._run` spread over kernels: the same tableau (RKMK
brackets included), the same per-step checks and outcomes, and the bodies' own compiled functions
(``segment_loads``, ``advance_node``, ``spring_pull``, ``triangle_area2``, compiled a second time
for the GPU). A member that stops is frozen (``mi[b, STATUS]`` leaves ``RUNNING``) and every kernel
skips it, so members with fewer steps cost nothing once done.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numba import cuda

from ..bodies.frames import advance_node
from ..bodies.geometry import triangle_area2
from ..contracts import System
from ..integrate import BEYOND, DONE, NON_FINITE, Scheme
from ..kinds.rod.mechanics import segment_loads
from ..kinds.vesicle.mechanics import spring_pull
from ..mrs.velocity import EIGHT_PI
from ..stepping.loop import tableau_arrays
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

if TYPE_CHECKING:  # the kinds are imported when a solve needs them
    from ..kinds.rod.system import RodSystem
    from ..kinds.vesicle.system import VesicleSystem

__all__ = ["Launch", "Member", "solve"]

#: Columns of the rods' constant table: 1/Δs, b1, b2, b3, Ω̂ constant (3), amplitude, wavenumber,
#: frequency, length L.
_R_INV_DS, _R_B, _R_CONST, _R_AMP, _R_K, _R_FREQ, _R_LEN = 0, 1, 4, 7, 8, 9, 10
#: Columns of the vesicle's constant table: initial area, shear rate.
_V_AREA, _V_SHEAR = 0, 1


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

    system: RodSystem | VesicleSystem
    x: np.ndarray
    t0: float
    h: float
    n: int


def _rows(x, b, p, cols, out):
    for q in range(cols):
        out[q] = x[b, p, q]


@functools.cache
def _body_kernels(kind: str, threads: int) -> tuple:
    """``(begin, stage, finish)`` kernels of the body ``kind`` ("rod" or "vesicle") for blocks of
    ``threads`` threads (one block per member)."""
    from numba import float64, int64

    jit = cuda.jit(device=True)
    rod = kind == "rod"
    cols, rcols = (12, 6) if rod else (3, 3)
    rows = jit(_rows)

    # ---- the body's parts ---------------------------------------------------------------------
    @jit
    def segment(x, b, k, t, theta, body):
        """(F, N, lever) of the rod segment (k, k + 1) of member b at time t (eqs. 9-12, 36)."""
        table, c, m = body
        kk = k % m
        scale = -(c[_R_K] ** 2) * c[_R_AMP]
        sft = scale * math.sin(c[_R_FREQ] * t)
        cft = scale * math.cos(c[_R_FREQ] * t)
        o2 = c[_R_CONST + 1]
        if c[_R_AMP] != 0.0:
            o2 += table[kk, 0] * cft + table[kk, 1] * sft
        p = cuda.local.array(12, float64)
        q = cuda.local.array(12, float64)
        rows(x, b, k, 12, p)
        rows(x, b, k + 1, 12, q)
        return segment_loads(p, q, c[_R_INV_DS], theta, theta, theta, c[_R_B], c[_R_B + 1],
                             c[_R_B + 2], c[_R_CONST], o2, c[_R_CONST + 2])

    @jit
    def rod_loads(x, b, t, tid, theta, body, f, tq):
        """f, tq at the points of member b (eq. 12), summed as ``kinds.rod.mechanics.rod_loads``
        does."""
        m = body[2]
        for p in range(tid, x.shape[1], threads):
            kk = p % m
            fx = fy = fz = nx = ny = nz = 0.0
            if kk > 0:
                gx, gy, gz, mx, my, mz, lx, ly, lz = segment(x, b, p - 1, t, theta, body)
                fx -= gx
                fy -= gy
                fz -= gz
                nx += lx - mx
                ny += ly - my
                nz += lz - mz
            if kk < m - 1:
                gx, gy, gz, mx, my, mz, lx, ly, lz = segment(x, b, p, t, theta, body)
                fx += gx
                fy += gy
                fz += gz
                nx += mx + lx
                ny += my + ly
                nz += mz + lz
            f[b, p, 0] = fx
            f[b, p, 1] = fy
            f[b, p, 2] = fz
            tq[b, p, 0] = nx
            tq[b, p, 1] = ny
            tq[b, p, 2] = nz

    @jit
    def vesicle_loads(x, b, t, tid, theta, body, f, tq):
        """Spring forces at the vertices of member b (docs/physics.md (14)), each vertex summing its
        springs in edge order, as ``kinds.vesicle.mechanics.spring_forces`` does."""
        offsets, incident, edges, rest = body[0], body[1], body[2], body[3]
        two = cuda.local.array((2, 3), float64)
        for p in range(tid, x.shape[1], threads):
            fx = fy = fz = 0.0
            for slot in range(offsets[p], offsets[p + 1]):
                e = incident[slot]
                rows(x, b, edges[e, 0], 3, two[0])
                rows(x, b, edges[e, 1], 3, two[1])
                px, py, pz = spring_pull(two, 0, 1, rest[e], theta)
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
    def rod_advance(row, comb, h, out):
        advance_node(row, comb, h, out)

    @jit
    def vesicle_advance(row, comb, h, out):
        for q in range(3):
            out[q] = row[q] + h * comb[q]

    @jit
    def rod_bracket(k, rows_, st, b, p, h, comb):
        """Add the RKMK commutator terms of stage ``st`` (-1: the final ones) to ``comb``."""
        off = 0 if st < 0 else 1
        for r in range(rows_.shape[0]):
            if st < 0 or rows_[r, 0] == st:
                c = rows_[r, off] * h
                kp = int(rows_[r, off + 1])
                kq = int(rows_[r, off + 2])
                comb[3] += c * (k[kp, b, p, 4] * k[kq, b, p, 5] - k[kp, b, p, 5] * k[kq, b, p, 4])
                comb[4] += c * (k[kp, b, p, 5] * k[kq, b, p, 3] - k[kp, b, p, 3] * k[kq, b, p, 5])
                comb[5] += c * (k[kp, b, p, 3] * k[kq, b, p, 4] - k[kp, b, p, 4] * k[kq, b, p, 3])

    @jit
    def no_bracket(k, rows_, st, b, p, h, comb):
        pass

    @jit
    def rod_monitor_part(x, b, tid, body):
        """|length - L| of rod ``tid`` (0 for the other threads); the monitor is their max / L."""
        m = body[2]
        if tid >= x.shape[1] // m:
            return 0.0
        total = 0.0
        for k in range(tid * m, (tid + 1) * m - 1):
            dx = x[b, k + 1, 0] - x[b, k, 0]
            dy = x[b, k + 1, 1] - x[b, k, 1]
            dz = x[b, k + 1, 2] - x[b, k, 2]
            total += math.sqrt(dx * dx + dy * dy + dz * dz)
        return abs(total - body[1][_R_LEN])

    @jit
    def vesicle_monitor_part(x, b, tid, body):
        """Twice the area of this thread's triangles; the monitor is |Σ/2 - A0| / A0."""
        triangles = body[4]
        three = cuda.local.array((3, 3), float64)
        total = 0.0
        for tri in range(tid, triangles.shape[0], threads):
            for v in range(3):
                rows(x, b, triangles[tri, v], 3, three[v])
            total += triangle_area2(three, 0, 1, 2)
        return total

    @jit
    def rod_monitor_value(joined, body):
        return joined / body[1][_R_LEN]

    @jit
    def vesicle_monitor_value(joined, body):
        area = body[5][_V_AREA]
        return abs(0.5 * joined - area) / area

    loads = rod_loads if rod else vesicle_loads
    advance = rod_advance if rod else vesicle_advance
    bracket = rod_bracket if rod else no_bracket
    monitor_part = rod_monitor_part if rod else vesicle_monitor_part
    monitor_value = rod_monitor_value if rod else vesicle_monitor_value

    # ---- generic parts ------------------------------------------------------------------------
    @jit
    def monitor(x, b, tid, body, red):
        """The member's monitor (every thread of the block gets it): a fixed-order tree reduction
        of the threads' parts (max of the rods' length changes; sum of the vesicle's areas)."""
        red[tid] = monitor_part(x, b, tid, body)
        cuda.syncthreads()
        width = threads // 2
        while width > 0:
            if tid < width:
                red[tid] = max(red[tid], red[tid + width]) if rod else red[tid] + red[tid + width]
            cuda.syncthreads()
            width //= 2
        value = red[0]
        cuda.syncthreads()
        return monitor_value(value, body)

    @jit
    def combine(k, coefs, b, p, comb):
        """Σ_j coefs[j] k_j at point p, zero coefficients skipped, terms added in order (as
        ``stepping.loop._combine``)."""
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
            rows(x, b, p, cols, row)
            advance(row, comb, h, new)
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
        loads(x, b, mf[b, T0], tid, mf[b, THETA], body, f, tq)

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
        loads(xs, b, t + c[st] * h, tid, mf[b, THETA], body, f, tq)

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
                loads(x, b, mf[b, T0] + (step + 1) * h, tid, mf[b, THETA], body, f, tq)

    return begin, stage, finish


def _rod_body(system: RodSystem | VesicleSystem, cuda: Any) -> tuple:
    from ..models import RodSystem

    assert isinstance(system, RodSystem)  # KINDS["RodSystem"]
    _, ds, _, shear, table, constant, amplitude, wavenumber, frequency = system.mechanics
    consts = np.array([1.0 / ds, *shear, *constant, amplitude, wavenumber, frequency,
                       system.length])
    return (cuda.to_device(np.ascontiguousarray(table)), cuda.to_device(consts),
            int(system.n_points))


def _vesicle_body(system: RodSystem | VesicleSystem, cuda: Any) -> tuple:
    from ..models import VesicleSystem

    assert isinstance(system, VesicleSystem)  # KINDS["VesicleSystem"]
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


#: Θ of each system kind: (the parameter held in ``mf[:, THETA]``, the kind's kernels, its
#: constant tables, its state and rate columns).
KINDS: dict[str, tuple[str, str, Callable[[RodSystem | VesicleSystem, Any], tuple], int, int]] = {
    "RodSystem": ("bending", "rod", _rod_body, 12, 6),
    "VesicleSystem": ("stiffness", "vesicle", _vesicle_body, 3, 3),
}


def gpu_system(system: System) -> RodSystem | VesicleSystem | None:
    """``system`` itself when the GPU path reproduces it (exactly a ``RodSystem`` or a
    ``VesicleSystem``), or None (another class, or a subclass, whose physics may differ)."""
    from ..models import RodSystem, VesicleSystem

    if type(system) is RodSystem or type(system) is VesicleSystem:
        return system
    return None


def kind_of(system: System) -> str | None:
    """The batched kind of ``system`` ("RodSystem", "VesicleSystem"), or None when the GPU path
    does not reproduce it (another class, or a subclass, whose physics may differ)."""
    return None if gpu_system(system) is None else type(system).__name__


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
    kind = kind_of(first)
    if kind is None:
        raise ValueError(f"no GPU path for {type(first).__name__}")
    theta_name, body_kind, make_body, cols, rcols = KINDS[kind]
    nb = len(members)
    x = np.stack([np.asarray(mb.x, dtype=float) for mb in members])
    if x.shape[2] != cols:
        raise ValueError(f"x: expected {cols} columns per point, got {x.shape[2]}")
    npts = x.shape[1]
    mf = np.zeros((nb, 7))
    mi = np.zeros((nb, 3), dtype=np.int64)
    for b, mb in enumerate(members):
        s = mb.system
        mf[b, [T0, STEP, EPS, DENOM, THETA]] = (mb.t0, mb.h, s.epsilon, EIGHT_PI * s.viscosity,
                                                getattr(s, theta_name))
        mi[b] = (RUNNING, mb.n, 0)
    c, a, weights, stage_brackets, final_brackets = tableau_arrays(scheme)
    stages = weights.size

    d_x = cuda.to_device(x)
    d_xs = cuda.to_device(x)
    d_k = cuda.device_array((stages, nb, npts, rcols))
    k_views = [d_k[st] for st in range(stages)]
    d_f = cuda.device_array((nb, npts, 3))
    d_tq = cuda.device_array((nb, npts, 3))
    d_mf = cuda.to_device(mf)
    d_mi = cuda.to_device(mi)
    d_a, d_c, d_w = cuda.to_device(a), cuda.to_device(c), cuda.to_device(weights)
    d_sb = cuda.to_device(stage_brackets.reshape(-1, 4) if stage_brackets.size else
                          np.zeros((0, 4)))
    d_fb = cuda.to_device(final_brackets.reshape(-1, 3) if final_brackets.size else
                          np.zeros((0, 3)))
    body = make_body(first, cuda)
    begin, stage, finish = _body_kernels(body_kind, launch.threads)
    full, free_u_f = velocity_kernels(launch.tx, launch.sy)
    grid, block = launch_shape(nb, npts, launch.tx, launch.sy)
    wall = bool(getattr(first, "wall", False))
    shear = float(getattr(first, "shear_rate", 0.0))

    # launch configurations made once (each is reused for every step)
    begin, stage, finish = (kernel[nb, launch.threads] for kernel in (begin, stage, finish))
    full, free_u_f = full[grid, block], free_u_f[grid, block]

    def velocity(positions, out):
        if body_kind == "rod":
            full(positions, positions, d_f, d_tq, d_mf, d_mi, wall, out)
        else:
            free_u_f(positions, positions, d_f, d_mf, d_mi, shear, out)

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
