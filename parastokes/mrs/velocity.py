"""The public entry :func:`velocity`: validation, batching, and dispatch to the compiled kernels."""

from __future__ import annotations

import contextlib
import math
import threading
from collections.abc import Callable, Iterator

import numba
import numpy as np

from . import compiled

EIGHT_PI = 8.0 * math.pi

#: Largest magnitude allowed for ε, 1/ε and the coordinates: the kernels seed 1/sqrt(r² + ε²) in
#: single precision (:func:`parastokes.mrs.compiled._rsqrt`), so r² + ε² must stay inside
#: float32's normal range (about 1e-38 to 3e38). Any physical unit system is far inside.
SCALE_LIMIT = 1e18


def _real(name: str, value) -> np.ndarray:
    """``value`` as float64; ValueError for what is not real numbers (complex, text, objects)."""
    arr = np.asarray(value)
    if arr.dtype.kind not in "biuf":
        raise ValueError(f"{name}: must be real numbers, got an array of dtype {arr.dtype}")
    return arr.astype(np.float64, copy=False)


def _points(name: str, value, batch: int | None = None) -> np.ndarray:
    arr = _real(name, value)
    if arr.ndim not in (2, 3) or arr.shape[-1] != 3:
        raise ValueError(f"{name}: expected shape (N, 3) or (B, N, 3), got {arr.shape}")
    if arr.shape[-2] == 0:
        raise ValueError(f"{name}: no points (shape {arr.shape})")
    if batch is not None and (arr.ndim == 3) != (batch > 0):
        raise ValueError(
            f"{name}: all point arrays must be batched or all unbatched, got {arr.shape}"
        )
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: contains non-finite values")
    return arr


def _positive(name: str, value, batch: int) -> np.ndarray:
    arr = _real(name, value)
    if arr.ndim == 0:
        arr = np.full(max(batch, 1), float(arr))
    elif batch == 0 or arr.shape != (batch,):
        raise ValueError(
            f"{name}: expected a scalar{' or shape (' + str(batch) + ',)' if batch else ''}, "
            f"got shape {arr.shape}"
        )
    if not np.all(np.isfinite(arr)) or np.any(arr <= 0):
        raise ValueError(f"{name}: must be finite and > 0, got {value!r}")
    return arr


def per_source(epsilon, batch: int) -> bool:
    """Whether ``epsilon`` gives one ε per source: shape (N,) unbatched, (B, N) batched."""
    return np.ndim(epsilon) == (2 if batch else 1)


def _epsilon(value, batch: int, n_sources: int) -> np.ndarray:
    if per_source(value, batch):
        eps = _real("epsilon", value)
        want = (batch, n_sources) if batch else (n_sources,)
        if eps.shape != want:
            raise ValueError(f"epsilon: one per source needs shape {want}, got {eps.shape}")
        if not np.all(np.isfinite(eps)) or np.any(eps <= 0):
            raise ValueError("epsilon: must be finite and > 0 for every source")
        eps = eps.reshape(max(batch, 1), n_sources)
    else:
        eps = _positive("epsilon", value, batch)
    if np.any(eps < 1.0 / SCALE_LIMIT) or np.any(eps > SCALE_LIMIT):
        found = (f"{float(eps.min()):g}" if eps.min() == eps.max() else
                 f"values from {float(eps.min()):g} to {float(eps.max()):g}")
        raise ValueError(
            f"epsilon: must lie in [{1.0 / SCALE_LIMIT:g}, {SCALE_LIMIT:g}], got {found}"
        )
    return eps


def thread_count(n_threads: int | None) -> int:
    """The threads a call uses: ``n_threads`` (default 1), at most numba's thread pool."""
    n = 1 if n_threads is None else n_threads
    if not isinstance(n, int | np.integer) or n < 1:
        raise ValueError(f"n_threads: must be a positive integer, got {n_threads!r}")
    return min(int(n), numba.config.NUMBA_NUM_THREADS)


@contextlib.contextmanager
def kernel_threads(n_threads: int | None) -> Iterator[int]:
    """Run the enclosed kernels on ``n_threads`` threads (:func:`thread_count`); numba's thread
    count is restored on exit. Yields the count used (the kernels' tiling depends on it)."""
    n = thread_count(n_threads)
    previous = numba.get_num_threads()
    if n != previous:
        numba.set_num_threads(n)
    try:
        yield n
    finally:
        if n != previous:
            numba.set_num_threads(previous)


#: This thread's :func:`routed` destination, if any.
_ROUTE = threading.local()

#: ``route(targets, sources, forces, torques, eps, mu, wall, angular) -> u or (u, w)``: the
#: validated arrays of one unbatched call (``eps`` (1,) or (1, N) per source, ``mu`` (1,)).
Route = Callable[..., object]


@contextlib.contextmanager
def routed(route: Route) -> Iterator[None]:
    """Within it, this thread's unbatched :func:`velocity` calls (the ψ torque blob) go to
    ``route`` instead of the compiled kernels, with their validated arguments (:data:`Route`):
    how :mod:`parastokes.gpu.hosted` batches the fluid products of solves that run on the host
    (rigid bodies' GMRES) into GPU launches. Other threads are not affected."""
    previous = getattr(_ROUTE, "route", None)
    _ROUTE.route = route
    try:
        yield
    finally:
        _ROUTE.route = previous


def _soa(points: np.ndarray, padded: int) -> np.ndarray:
    """(B, N, 3) -> one contiguous (3, B, padded) array, padded by repeating the last point."""
    nb, n, _ = points.shape
    out = np.empty((3, nb, padded))
    out[:, :, :n] = points.transpose(2, 0, 1)
    out[:, :, n:] = points[:, -1, :].T[:, :, None]
    return out


def validated(targets, sources, forces, torques, epsilon, mu, wall: bool) -> tuple:
    """The arguments of :func:`velocity` checked (``ValueError`` naming the argument) and
    converted: ``(targets, sources, forces, torques, eps, mu)``, ``eps`` and ``mu`` as arrays of
    one value per system. Also used by the GPU kernels' entry, :func:`parastokes.gpu.velocity`."""
    targets = _points("targets", targets)
    batch = targets.shape[0] if targets.ndim == 3 else 0
    sources = _points("sources", sources, batch)
    forces = _points("forces", forces, batch)
    if forces.shape != sources.shape:
        raise ValueError(f"forces: shape {forces.shape} differs from sources {sources.shape}")
    if batch and sources.shape[0] != batch:
        raise ValueError(f"sources: batch size {sources.shape[0]} differs from targets {batch}")
    if torques is not None:
        torques = _points("torques", torques, batch)
        if torques.shape != sources.shape:
            raise ValueError(
                f"torques: shape {torques.shape} differs from sources {sources.shape}"
            )
    for name, arr in (("targets", targets), ("sources", sources)):
        if arr.size and np.max(np.abs(arr)) > SCALE_LIMIT:
            raise ValueError(f"{name}: coordinates beyond ±{SCALE_LIMIT:g} are not supported")
        if wall and np.any(arr[..., 2] < 0):
            raise ValueError(f"{name}: points below the wall z = 0 (wall=True)")
    # a fresh writable copy: one numba signature
    eps = np.array(_epsilon(epsilon, batch, sources.shape[-2]))
    visc = _positive("mu", mu, batch)
    return targets, sources, forces, torques, eps, visc


def velocity(
    targets,
    sources,
    forces,
    *,
    epsilon,
    mu,
    torques=None,
    wall: bool = False,
    angular: bool = False,
    torque_blob: str = "psi",
    n_threads: int | None = None,
    check: bool = True,
):
    """Fluid velocity at ``targets`` from regularized point forces (and torques) at ``sources``.

    Free space: the regularized Stokeslet sum of eq. 6 (blob eq. 3), plus the regularized rotlet
    for torques ([1]-[4] of docs/kernels.md). With ``wall=True`` the fluid is bounded by a
    no-slip plane wall at z = 0 and the image systems [5]-[8] are added (method of images, the
    paper's ref. [48]).

    Parameters
    ----------
    targets : (M, 3) or (B, M, 3) array
        Where the velocity is evaluated.
    sources : (N, 3) or (B, N, 3) array
        Positions of the point forces.
    forces, torques : (N, 3) or (B, N, 3) arrays
        Point forces (and torques) exerted on the fluid, same shape as ``sources``. Torques that
        are all zero count as none (without ``wall`` or ``angular``: the force-only kernel).
    epsilon, mu : float, or (B,) arrays for batched input
        Regularization parameter ε > 0 and viscosity μ > 0 (one per system when batched).
        ``epsilon`` may also be one per source, (N,) or (B, N): each source's blob has its own
        width (bodies with their own ε in one fluid, :class:`parastokes.scene.Scene`).
    wall : bool
        Plane wall at z = 0; every point must then have z >= 0.
    angular : bool
        Also return the angular velocity w = ½ curl u.
    torque_blob : {"psi", "phi"}
        The blob of the torque parts. ``"psi"`` (default, "variant L", the paper's authors'
        choice): ψ_ε = 3ε²/(4π r_ε⁵), regularized rotlet [3] and potential dipole [4], free and
        above the wall. ``"phi"`` ("variant Φ"): the force blob φ_ε for the torques too, u = ½ Q
        n × r and w = ¼ [D1 n + D2 (n·r) r] (docs/physics.md section 1); free space only.
    n_threads : int, optional
        Threads over target tiles (default 1). Results are bit-identical for any thread count.
    check : bool
        Validate the input (default). ``False`` skips validation in hot loops whose inputs were
        validated once: then the arrays must already be float64 of the right shapes.

    Returns
    -------
    u or (u, w)
        u, and w too with ``angular``: arrays shaped like ``targets``.
    """
    if torque_blob not in ("psi", "phi"):
        raise ValueError(f"torque_blob: must be 'psi' or 'phi', got {torque_blob!r}")
    if torque_blob == "phi" and wall:
        raise ValueError(
            "torque_blob: 'phi' (variant Φ) is defined in free space only; use 'psi' with wall=True"
        )
    if check:
        targets, sources, forces, torques, eps, visc = validated(
            targets, sources, forces, torques, epsilon, mu, wall
        )
        batch = targets.shape[0] if targets.ndim == 3 else 0
    else:
        targets = np.asarray(targets)
        batch = targets.shape[0] if targets.ndim == 3 else 0
        if per_source(epsilon, batch):
            eps = np.array(epsilon, dtype=np.float64).reshape(max(batch, 1), -1)
        else:
            eps = np.empty(max(batch, 1))
            eps[:] = epsilon
        visc = np.empty(max(batch, 1))
        visc[:] = mu
    route = getattr(_ROUTE, "route", None)
    if route is not None and not batch and torque_blob == "psi":
        return route(targets, sources, forces, torques, eps, visc, bool(wall), angular)

    t3 = targets if batch else targets[None]
    s3 = np.ascontiguousarray(sources if batch else sources[None], dtype=np.float64)
    f3 = np.ascontiguousarray(forces if batch else forces[None], dtype=np.float64)
    nb, m = t3.shape[:2]
    padded = compiled.padded_size(m)
    tp = _soa(t3, padded)
    denom = EIGHT_PI * visc
    # u from f in free space only; torques that are all zero count as none (as in the
    # compiled loops' fluid, parastokes.fluid.compiled), so both give the same bits
    fast = not wall and not angular and (torques is None or not np.any(torques))
    u = np.empty((nb, m, 3))
    w = None if fast else np.empty((nb, m, 3))
    with kernel_threads(n_threads) as n:
        starts = compiled.tile_starts(padded, n)
        if fast:
            compiled.free_u_f(tp, s3, f3, eps, denom, starts, u)
        else:
            if torques is None:
                n3 = np.zeros_like(s3)
            else:
                n3 = np.ascontiguousarray(torques if batch else torques[None], dtype=np.float64)
            phi = torque_blob == "phi"
            compiled.full(tp, s3, f3, n3, eps, bool(wall), phi, denom, starts, u, w)
    if not batch:
        u = u[0]
        w = None if w is None else w[0]  # None when fast
    return (u, w) if angular else u
