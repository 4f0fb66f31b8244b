"""Compiled (numba) regularized Stokeslet kernels: the fast path.

Layout: a leading batch axis ``b`` (B independent systems, each with its ε), the targets as a
structure of arrays, padded to a multiple of :data:`LANES` and processed in tiles of up to
:data:`TILE`, sources streamed one at a time with their constants hoisted, targets innermost so
that the inner loop vectorizes, with 512-bit vectors where the CPU has them
(:func:`_kernel_attributes`). One inverse square root per distance, computed without the (slow,
unpipelined) double-precision divider: a single-precision estimate refined to double round-off
(:func:`_rsqrt`). Work is split over ``(system, tile)`` pairs with ``prange``; each target's sum
runs over the sources in the same order whatever the number of threads, so results are
bit-identical for any thread count.

The sources, forces and torques are read as they come, (B, N, 3) (one source at a time: no
vector loads), and u and w are written as (B, M, 3), already divided by 8πμ: the caller packs only
the targets. Formulas: the physics notes (docs/kernels.md) (1)-(8), the paper's eqs. 3-6.

ε is one per system, ``eps`` (B,), or one per source, ``eps`` (B, N) (a scene of bodies with
their own ε, :mod:`parastokes.scene`): the same kernels, compiled once for each; per source, ε²
is formed once per source (outside the targets' loop), so a (B, N) ``eps`` with equal entries
gives the same bits as the (B,) one.

Kernels:

- :func:`free_u_f`: force -> velocity in free space (eq. 6), the vesicle's hot path;
- :func:`full`: u and w from forces and torques in free space ([1]-[4]) or, with ``wall``, above
  the wall z = 0 ([1]-[8] folded into one set of coefficients, :func:`_wall_pair`), the rod's.

Why each choice, with the figures: ``docs/kernels.md`` and ``docs/benchmarks.md``.
"""

from __future__ import annotations

import functools
import math
import platform

import numpy as np
from numba import njit, prange, types
from numba.extending import intrinsic, overload

#: Most targets per tile. Tiles are whole vectors of :data:`LANES` targets (:func:`tile_starts`).
TILE = 64
#: Doubles per vector at the widest width used (512 bits): targets are padded to a multiple of it.
LANES = 8

# fastmath: "contract" lets LLVM fuse multiply-adds; the tests check the results agree with the
# numpy oracle to 1e-12 relative (in practice ~1e-15). No reassociation: sums keep their order.
_OPTS = dict(cache=True, error_model="numpy", fastmath={"contract"}, boundscheck=False)

#: LLVM function attributes set on the kernels' loop bodies by :func:`_kernel_attributes`: 512-bit
#: vectors, and how ``_rsqrt_seed``'s single-precision 1/sqrt may be computed. On x86-64, the
#: hardware estimate (``rsqrtps``, 12 bits) with exactly one Newton step (~22 bits), pinned rather
#: than left to LLVM's default; elsewhere no estimate (an IEEE float32 sqrt and division), since
#: other estimates (AArch64's 8-bit ``frsqrte``) would need more steps. Either way the seed has
#: >= 22 bits, which the Halley step of :func:`_rsqrt` needs to reach double round-off.
KERNEL_ATTRIBUTES = (
    '"prefer-vector-width"="512"',
    '"reciprocal-estimates"="vec-sqrtf:1,sqrtf:1"'
    if platform.machine().lower() in ("x86_64", "amd64")
    else '"reciprocal-estimates"="!vec-sqrtf,!sqrtf"',
)


@intrinsic
def _kernel_attributes(typingctx):
    """Set :data:`KERNEL_ATTRIBUTES` on the calling function (no code is emitted).

    LLVM's tuning for the Intel AVX-512 cores prefers 256-bit vectors by default (numba follows
    it). The per-function attribute ``prefer-vector-width`` overrides that for this function
    only: nothing else compiled in the process changes (unlike numba's process-wide
    ``CPU_FEATURES``). Where the CPU has no 512-bit vectors it has no effect. Called at the top of
    each ``prange`` body, whose loops numba outlines into their own function.
    """

    def codegen(context, builder, signature, args):
        # llvmlite's FunctionAttributes only accepts a fixed list of keyword attributes; a
        # string attribute "key"="value" is written through the underlying set. Should a future
        # llvmlite refuse it, LLVM's defaults apply: 256-bit vectors, and a seed that is still
        # accurate enough (x86-64: one Newton step by default; AArch64: no estimate by default).
        try:
            for attribute in KERNEL_ATTRIBUTES:
                set.add(builder.function.attributes, attribute)
        except (TypeError, AttributeError):
            pass
        return context.get_dummy_value()

    return types.none(), codegen


@njit(cache=True, error_model="numpy", fastmath=True)
def _rsqrt_seed(d):
    """1/sqrt(d) to ~22 bits, computed in single precision.

    ``fastmath`` here (and only here) lets LLVM use the hardware estimate ``rsqrtps`` plus one
    single-precision Newton step (pinned by :data:`KERNEL_ATTRIBUTES`). Needs d within float32's
    normal range: guaranteed by :func:`parastokes.mrs.velocity` (ε and coordinates bounded, see
    ``SCALE_LIMIT`` there).
    """
    return np.float64(np.float32(1.0) / math.sqrt(np.float32(d)))


@njit(inline="always", **_OPTS)
def _rsqrt(d):
    """1/sqrt(d) in double precision without the divider: the single-precision seed x (relative
    error e0 ~ 3e-7) and one third-order (Halley) correction x(1 + e/2 + 3e²/8), e = 1 - d x²,
    whose truncation error (5/16) e³ ~ 1e-19 is below double-precision round-off."""
    x = _rsqrt_seed(d)
    e = 1.0 - d * x * x
    return x + x * e * (0.5 + 0.375 * e)


@njit(inline="always", **_OPTS)
def _rsqrt3(d):
    """d^(-3/2) to double round-off, for kernels that need only 1/r_ε³: from the seed x of
    :func:`_rsqrt`, x³ (1 + 3e/2 + 15e²/8) with e = 1 - d x² (the series of (1 - e)^(-3/2);
    truncation error (35/16) e³ ~ 1e-18), one operation fewer than cubing :func:`_rsqrt`."""
    x = _rsqrt_seed(d)
    x2 = x * x
    e = 1.0 - d * x2
    x3 = x2 * x
    return x3 + x3 * (e * (1.5 + 1.875 * e))


@njit(inline="always", **_OPTS)
def _free_pair(rx, ry, rz, e2, fx, fy, fz, nx, ny, nz, phi):
    """8π × (u, w) at r from a force f and a torque n in free space ([1]-[4]); with ``phi``, the
    torque parts of variant Φ instead (the blob φ_ε for them too: u = ½ Q n × r,
    w = ¼ [D1 n + D2 (n·r) r], docs/physics.md section 1)."""
    r2 = rx * rx + ry * ry + rz * rz
    inv = _rsqrt(r2 + e2)
    inv2 = inv * inv
    inv3 = inv2 * inv
    inv5 = inv3 * inv2
    h1 = (r2 + 2.0 * e2) * inv3
    fr = (fx * rx + fy * ry + fz * rz) * inv3
    q = (r2 + 2.5 * e2) * inv5  # ½ Q · 8π
    if phi:
        inv7 = inv5 * inv2
        cn = q
        p1 = 0.25 * (e2 * (10.0 * e2 - 7.0 * r2) - 2.0 * r2 * r2) * inv7  # ¼ D1 · 8π
        nr = (nx * rx + ny * ry + nz * rz) * (0.25 * (21.0 * e2 + 6.0 * r2) * inv7)
    else:
        cn = inv3
        p1 = -0.5 * (r2 - 2.0 * e2) * inv5
        nr = (nx * rx + ny * ry + nz * rz) * (1.5 * inv5)
    ux = h1 * fx + fr * rx + (ny * rz - nz * ry) * cn
    uy = h1 * fy + fr * ry + (nz * rx - nx * rz) * cn
    uz = h1 * fz + fr * rz + (nx * ry - ny * rx) * cn
    wx = q * (fy * rz - fz * ry) + p1 * nx + nr * rx
    wy = q * (fz * rx - fx * rz) + p1 * ny + nr * ry
    wz = q * (fx * ry - fy * rx) + p1 * nz + nr * rz
    return ux, uy, uz, wx, wy, wz


@njit(inline="always", **_OPTS)
def _wall_pair(rx, ry, z, h, e2, fx, fy, fz, nx, ny, nz):
    """8π × (u, w) at the target (x, y-offsets rx, ry; height z) from a force f and a torque n at
    height h above the wall: the free parts [1]-[4] plus the images [5]-[8], summed.

    The image point's offset is R = r + 2h e3 (so |R|² = r² + 4hz, R3 = z + h), which folds every
    image term onto the free terms' vectors: with f × R = f × r + 2h f × e3, f*·R = f·r - 2 fz z,
    g(f) = R·(f × e3) = -(f × r)_3 and R·(n × e3) = -(n × r)_3,

        u = A1 f + A2 r + A3 (n × r) + A4 (n × e3) + A5 e3,
        w = B1 (f × r) + B2 (f × e3) + B3 n + B4 r + B5 e3,

    so each pair costs one contraction per output component instead of one per formula. The
    scalar coefficients are those of docs/physics.md (1)-(8) regrouped and simplified with
    1/R_ε³ = (|R|² + ε²)/R_ε⁵ and R3 - h = z, which collapses several of them: A4 = 6ε² z/R_ε⁵,
    A5 = 2h (Q6 - 6ε² z fz/R_ε⁵), B2 = 6h (z K/R_ε⁷ - 1/R_ε³), and the f × r part of B5 becomes
    6hz (2|R|² + 7ε²)/R_ε⁷ (derivation in docs/kernels.md). 140 vector operations per pair in
    the compiled loop, against 189 for "free part plus image part". The tests compare every
    part (forces only, torques only, both) with :mod:`parastokes.mrs.reference`.
    """
    rz = z - h
    r2 = rx * rx + ry * ry + rz * rz
    hz4 = 4.0 * h * z
    q2 = r2 + hz4  # |R|²
    q3 = z + h  # R3
    inv = _rsqrt(r2 + e2)
    d2 = inv * inv
    d3 = d2 * inv
    d5 = d3 * d2
    jnv = _rsqrt(q2 + e2)
    j2 = jnv * jnv
    j3 = j2 * jnv
    j5 = j3 * j2
    j7 = j5 * j2
    h2 = 2.0 * h
    fr = fx * rx + fy * ry + fz * rz
    nr = nx * rx + ny * ry + nz * rz
    cfx = fy * rz - fz * ry  # f × r
    cfy = fz * rx - fx * rz
    cfz = fx * ry - fy * rx
    cnx = ny * rz - nz * ry  # n × r
    cny = nz * rx - nx * rz
    cnz = nx * ry - ny * rx
    fs = fr - 2.0 * fz * z  # f*·R
    nq = nr + h2 * nz  # n·R
    m7 = (2.0 * q2 + 7.0 * e2) * j7
    p7 = q3 * m7 - 5.0 * e2 * h * j7  # K / R_ε⁷ of (6) and (8)
    p7q = q3 * p7
    t6 = 6.0 * z * j5
    # Velocity: (1) + (3) + (5) + (7).
    a1 = (r2 + 2.0 * e2) * d3 + 6.0 * e2 * h * z * j5 - (q2 + 2.0 * e2 + h2 * z) * j3
    a3 = d3 - j3
    q6 = t6 * (h * fs - cnz)  # 6z/R_ε⁵ (h f*·R + R·(n × e3))
    a2 = fr * a3 + q6
    a4 = e2 * t6
    a5 = h2 * (q6 - e2 * fz * t6)
    # Angular velocity: (2) + (4) + (6) + (8).
    aw = -(q2 + 2.5 * e2) * j5 - 3.0 * h * p7
    b1 = (r2 + 2.5 * e2) * d5 + aw
    b2 = 6.0 * h * (z * p7 - j3)
    b3 = (3.5 * q2 + 2.0 * e2) * j5 - 3.0 * p7q - 0.5 * (r2 - 2.0 * e2) * d5
    cr = 3.0 * j5 * (q3 * nz - 1.5 * nq)
    b4 = 1.5 * nr * d5 + cr - 6.0 * h * j5 * cfz
    b5 = h2 * cr + 3.0 * p7 * nq + 6.0 * h * z * m7 * cfz - 3.0 * j3 * nz
    ux = a1 * fx + a2 * rx + a3 * cnx + a4 * ny
    uy = a1 * fy + a2 * ry + a3 * cny - a4 * nx
    uz = a1 * fz + a2 * rz + a3 * cnz + a5
    wx = b1 * cfx + b2 * fy + b3 * nx + b4 * rx
    wy = b1 * cfy - b2 * fx + b3 * ny + b4 * ry
    wz = b1 * cfz + b3 * nz + b4 * rz + b5
    return ux, uy, uz, wx, wy, wz


def padded_size(n: int) -> int:
    """``n`` targets rounded up to a whole number of vectors (:data:`LANES`)."""
    return -(-n // LANES) * LANES


@functools.lru_cache(maxsize=256)
def tile_starts(padded: int, parts: int) -> np.ndarray:
    """Tile boundaries ``starts`` (tile k is targets ``starts[k]:starts[k+1]``) for ``padded``
    targets (a multiple of :data:`LANES`) shared by ``parts`` threads.

    The targets are cut into ``parts`` contiguous chunks as equal as whole vectors allow, and
    every chunk into the same number of tiles of at most :data:`TILE` targets, again as equal as
    possible. numba hands each thread an equal contiguous share of the (system, tile) jobs, so each
    thread then gets the same number of targets, ±8: with fixed tiles of 64, the rod's 301 targets
    (5 tiles) split 192 + 112 over 2 threads, which capped 2 threads at 1.58x. No result depends on
    the tiling: each target sums over the sources in the same order in whichever tile it is (so
    the results stay bit-identical for any thread count). Cached; the array is read-only.
    """
    groups = padded // LANES
    per_chunk = -(-(-(-groups // parts) * LANES) // TILE)  # tiles per chunk, the same in all
    bounds = {padded}
    for p in range(parts):
        lo, hi = groups * p // parts, groups * (p + 1) // parts
        bounds.update((lo + (hi - lo) * q // per_chunk) * LANES for q in range(per_chunk))
    starts = np.array(sorted(bounds), dtype=np.int64)  # merged repeats: chunks of < 1 vector
    starts.flags.writeable = False
    return starts


def _system_e2(eps, b):
    """ε² of system ``b`` when ``eps`` is one per system (B,); 0 (unused) when per source."""


def _source_e2(eps, b, j, e2):
    """ε² of source ``j`` of system ``b``: the system's ``e2``, or ``eps[b, j]²`` per source."""


@overload(_system_e2, inline="always")
def _system_e2_impl(eps, b):
    if eps.ndim == 1:
        return lambda eps, b: eps[b] * eps[b]
    return lambda eps, b: 0.0


@overload(_source_e2, inline="always")
def _source_e2_impl(eps, b, j, e2):
    if eps.ndim == 1:
        return lambda eps, b, j, e2: e2
    return lambda eps, b, j, e2: eps[b, j] * eps[b, j]


@njit(inline="always", **_OPTS)
def _tile(job, starts, t, eps):
    """The ``job``-th (system, tile) pair: system b, first target t0, number of targets nt, the
    tile's target coordinates (from the (3, B, Mp) targets ``t``) and the system's ε² (0 when ε
    is per source: :func:`_source_e2` gives it)."""
    ntiles = starts.size - 1
    b = job // ntiles
    t0 = starts[job % ntiles]
    nt = starts[job % ntiles + 1] - t0
    return (b, t0, nt, t[0, b, t0 : t0 + nt], t[1, b, t0 : t0 + nt], t[2, b, t0 : t0 + nt],
            _system_e2(eps, b))


@njit(inline="always", **_OPTS)
def _store(out, b, t0, nt, denom, ax, ay, az):
    """out[b, t0 + i] = (ax, ay, az)[i] / denom for the tile's targets that are not padding."""
    for i in range(min(nt, out.shape[1] - t0)):
        out[b, t0 + i, 0] = ax[i] / denom
        out[b, t0 + i, 1] = ay[i] / denom
        out[b, t0 + i, 2] = az[i] / denom


@njit(parallel=True, **_OPTS)
def free_u_f(t, s, f, eps, denom, starts, u):
    """u from forces in free space (eq. 6): u = (8π μ u) / denom with denom = 8π μ per system.

    ``t`` (3, B, Mp): the targets' x, y, z, padded to Mp (a multiple of LANES) by repeating the
    last target; ``s``, ``f`` (B, N, 3) sources and forces; ``eps`` (B,) or per source (B, N);
    ``denom`` (B,); ``starts``
    the tiles of every system (:func:`tile_starts`); ``u`` (B, M, 3), M <= Mp, is written (the
    padded targets' values are dropped).
    """
    ns = s.shape[1]
    for job in prange(t.shape[1] * (starts.size - 1)):
        _kernel_attributes()
        b, t0, nt, px, py, pz, e2b = _tile(job, starts, t, eps)
        ax = np.zeros(nt)
        ay = np.zeros(nt)
        az = np.zeros(nt)
        for j in range(ns):
            e2 = _source_e2(eps, b, j, e2b)
            e22 = 2.0 * e2
            yx, yy, yz = s[b, j, 0], s[b, j, 1], s[b, j, 2]
            gx, gy, gz = f[b, j, 0], f[b, j, 1], f[b, j, 2]
            for i in range(nt):
                rx = px[i] - yx
                ry = py[i] - yy
                rz = pz[i] - yz
                r2 = rx * rx + ry * ry + rz * rz
                inv3 = _rsqrt3(r2 + e2)
                h1 = (r2 + e22) * inv3
                fr = (gx * rx + gy * ry + gz * rz) * inv3
                ax[i] = ax[i] + fr * rx + h1 * gx  # two fused multiply-adds
                ay[i] = ay[i] + fr * ry + h1 * gy
                az[i] = az[i] + fr * rz + h1 * gz
        _store(u, b, t0, nt, denom[b], ax, ay, az)


@njit(parallel=True, **_OPTS)
def full(t, s, f, n, eps, wall, phi, denom, starts, u, w):
    """u and w from forces and torques: free space ([1]-[4]), plus the images ([5]-[8]) of the
    plane wall z = 0 when ``wall``; in free space, ``phi`` selects the torque parts of variant Φ
    (not defined with the wall). Both flags are loop-invariant tests: LLVM unswitches the loops.
    Arguments as in :func:`free_u_f`, with torques ``n`` (B, N, 3) and the angular velocity ``w``
    (B, M, 3)."""
    ns = s.shape[1]
    for job in prange(t.shape[1] * (starts.size - 1)):
        _kernel_attributes()
        b, t0, nt, px, py, pz, e2b = _tile(job, starts, t, eps)
        a0 = np.zeros(nt)
        a1 = np.zeros(nt)
        a2 = np.zeros(nt)
        a3 = np.zeros(nt)
        a4 = np.zeros(nt)
        a5 = np.zeros(nt)
        for j in range(ns):
            e2 = _source_e2(eps, b, j, e2b)
            yx, yy, h = s[b, j, 0], s[b, j, 1], s[b, j, 2]
            gx, gy, gz = f[b, j, 0], f[b, j, 1], f[b, j, 2]
            mx, my, mz = n[b, j, 0], n[b, j, 1], n[b, j, 2]
            for i in range(nt):
                rx = px[i] - yx
                ry = py[i] - yy
                if wall:
                    v0, v1, v2, v3, v4, v5 = _wall_pair(rx, ry, pz[i], h, e2,
                                                        gx, gy, gz, mx, my, mz)
                else:
                    v0, v1, v2, v3, v4, v5 = _free_pair(rx, ry, pz[i] - h, e2,
                                                        gx, gy, gz, mx, my, mz, phi)
                a0[i] += v0
                a1[i] += v1
                a2[i] += v2
                a3[i] += v3
                a4[i] += v4
                a5[i] += v5
        _store(u, b, t0, nt, denom[b], a0, a1, a2)
        _store(w, b, t0, nt, denom[b], a3, a4, a5)
