"""The fluid as a linear operator: point forces at sources -> velocities at targets.

:class:`StokesletOperator` is the force -> velocity map of the regularized Stokeslets, eq. 6 of the
paper ((1) of docs/physics.md), in free space or above the plane wall z = 0 (plus the image (5)),
with ε one value or one per source. It is applied matrix-free with the compiled kernels
(:func:`parastokes.mrs.velocity`) or assembled as a dense (3M, 3N) matrix in numpy. Row 3i + a,
column 3j + b is u_a(x_i) from a unit force e_b at y_j (both flattened point-major, like
``forces.ravel()``).
"""

from __future__ import annotations

import math

import numpy as np

from .velocity import thread_count, validated
from .velocity import velocity as _velocity

#: Entries of the (tile, N, 3, 3) temporaries of :meth:`StokesletOperator.dense` per tile: rows
#: are assembled a tile of targets at a time so that its temporaries stay near 16 MB.
_TILE_ENTRIES = 2_000_000


def _blocks(targets: np.ndarray, sources: np.ndarray, eps: np.ndarray, wall: bool) -> np.ndarray:
    """8π × the force -> velocity matrices of all (target, source) pairs, (M, 3, N, 3).

    Free space, (1) of docs/physics.md: (r² + 2ε²)/r_ε³ δ_ab + r_a r_b / r_ε³. The wall image (5),
    term by term linear in f (f* = Δ f, R·f* = (Δ R)·f, Δ = diag(s), s = (1, 1, -1), and
    R3 - h = z the target's height), is entry by entry

        [A + B s_b] δ_ab + (-1/R_ε³ + C s_b) R_a R_b + δ_a3 (D s_b + F) R_b + δ_b3 E R_a,

    A = -(R² + 2ε²)/R_ε³ + 6hε² R3/R_ε⁵,  B = 2h² (1/R_ε³ - 3ε²/R_ε⁵) - 2h R3/R_ε³,
    C = 6 h z / R_ε⁵,  D = 2h (R² + 4ε²)/R_ε⁵,  E = 2h/R_ε³,  F = -6hε²/R_ε⁵.
    Each entry is formed from (M, N) arrays, so no (M, N, 3, 3) temporaries.
    """
    e2 = eps**2
    r = targets[:, None, :] - sources[None, :, :]
    r2 = np.einsum("mnk,mnk->mn", r, r)
    i3 = (r2 + e2) ** -1.5
    out = np.empty((len(targets), 3, len(sources), 3))
    diag = (r2 + 2 * e2) * i3
    for a in range(3):
        ra = r[..., a] * i3
        for b in range(a, 3):
            out[:, a, :, b] = ra * r[..., b]
        out[:, a, :, a] += diag
        for b in range(a):
            out[:, a, :, b] = out[:, b, :, a]
    if not wall:
        return out
    h = sources[None, :, 2]
    z = targets[:, None, 2]
    big = r.copy()
    big[..., 2] += 2 * h  # R = x - y*, y* = (y1, y2, -h)
    rr2 = np.einsum("mnk,mnk->mn", big, big)
    j3 = (rr2 + e2) ** -1.5
    j5 = j3 / (rr2 + e2)
    r3 = big[..., 2]
    coef_a = -(rr2 + 2 * e2) * j3 + 6 * h * e2 * r3 * j5
    coef_b = 2 * h**2 * (j3 - 3 * e2 * j5) - 2 * h * r3 * j3
    coef_c = 6 * h * z * j5
    coef_d = 2 * h * (rr2 + 4 * e2) * j5
    coef_e = 2 * h * j3
    coef_f = -6 * h * e2 * j5
    sign = (1.0, 1.0, -1.0)
    for a in range(3):
        for b in range(3):
            rab = big[..., a] * big[..., b]
            entry = (-j3 + sign[b] * coef_c) * rab
            if a == b:
                entry += coef_a + sign[b] * coef_b
            if a == 2:
                entry += (sign[b] * coef_d + coef_f) * big[..., b]
            if b == 2:
                entry += coef_e * big[..., a]
            out[:, a, :, b] += entry
    return out


class StokesletOperator:
    """The force -> velocity map u = A f of the regularized Stokeslets from ``sources`` to
    ``targets`` (eq. 6; with ``wall``, plus the images (5) of docs/physics.md).

    Parameters
    ----------
    targets : (M, 3) array or None
        Where velocities are evaluated; None: the sources themselves (a square, symmetric A).
    sources : (N, 3) array
        Positions of the point forces (exerted on the fluid).
    epsilon : float or (N,) array
        The blob width, one value or one per source.
    mu : float
        Viscosity.
    wall : bool
        No-slip plane wall at z = 0 (every point must have z >= 0).
    n_threads : int, optional
        Threads of the compiled kernels in :meth:`matvec` (default 1).
    """

    def __init__(
        self,
        targets: np.ndarray | None,
        sources: np.ndarray,
        epsilon: float | np.ndarray,
        mu: float,
        wall: bool = False,
        n_threads: int | None = None,
    ) -> None:
        sources_arr = np.asarray(sources, dtype=np.float64)
        if sources_arr.ndim != 2:
            raise ValueError(f"sources: expected shape (N, 3), got {sources_arr.shape}")
        tgt = sources_arr if targets is None else targets
        zero = np.zeros_like(sources_arr)
        t, s, _, _, eps, visc = validated(tgt, sources_arr, zero, None, epsilon, mu, wall)
        if t.ndim != 2:
            raise ValueError(f"targets: expected shape (M, 3), got {t.shape}")
        thread_count(n_threads)  # validates n_threads before any work
        self.targets = np.ascontiguousarray(t)
        #: targets are the sources: A is square and symmetric
        self.square = targets is None
        self.sources = np.ascontiguousarray(s)
        per_source = np.ndim(epsilon) == 1
        self.epsilon: float | np.ndarray = eps[0] if per_source else float(eps[0])
        self.mu = float(visc[0])
        self.wall = bool(wall)
        self.n_threads = n_threads
        self.shape = (3 * len(self.targets), 3 * len(self.sources))

    def matvec(self, f_flat: np.ndarray) -> np.ndarray:
        """A f for flattened forces ``f_flat`` (3N,) -> velocities (3M,), compiled kernels."""
        flat = np.asarray(f_flat, dtype=np.float64)
        if flat.size != self.shape[1]:
            raise ValueError(
                f"f_flat: expected {self.shape[1]} entries (3 per source), got {flat.size}"
            )
        forces = np.ascontiguousarray(flat.reshape(-1, 3))
        u = _velocity(
            self.targets,
            self.sources,
            forces,
            epsilon=self.epsilon,
            mu=self.mu,
            wall=self.wall,
            n_threads=self.n_threads,
            check=False,
        )
        return u.ravel()

    def dense(self) -> np.ndarray:
        """A assembled as a (3M, 3N) array in numpy, a tile of targets at a time."""
        m, n = len(self.targets), len(self.sources)
        eps = np.broadcast_to(np.asarray(self.epsilon, dtype=np.float64), (n,))[None, :]
        out = np.empty((m, 3, n, 3))
        tile = max(1, _TILE_ENTRIES // (9 * n))
        for start in range(0, m, tile):
            t = self.targets[start : start + tile]
            out[start : start + tile] = _blocks(t, self.sources, eps, self.wall)
        out /= 8 * math.pi * self.mu
        return out.reshape(3 * m, 3 * n)

    def as_linear_operator(self):
        """A as a :class:`scipy.sparse.linalg.LinearOperator` applying :meth:`matvec`."""
        from scipy.sparse.linalg import LinearOperator

        return LinearOperator(
            self.shape,
            matvec=self.matvec,
            rmatvec=self.matvec if self.square else None,
            dtype=np.float64,
        )
