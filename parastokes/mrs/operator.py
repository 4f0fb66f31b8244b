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

from .velocity import kernel_threads, validated
from .velocity import velocity as _velocity

#: Entries of the (tile, N, 3, 3) temporaries of :meth:`StokesletOperator.dense` per tile: rows
#: are assembled a tile of targets at a time so that its temporaries stay near 16 MB.
_TILE_ENTRIES = 2_000_000

_DELTA = np.array([1.0, 1.0, -1.0])
_E3 = np.array([0.0, 0.0, 1.0])


def _outer(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Pairwise outer products a bᵀ of (..., 3) vectors: (..., 3, 3)."""
    return a[..., :, None] * b[..., None, :]


def free_block(r: np.ndarray, eps: np.ndarray) -> np.ndarray:
    """8π × the free-space regularized Stokeslet (1) as matrices: (H1 I + H2 r rᵀ) 8π for pair
    differences ``r`` (..., 3) and ε broadcast against ``r[..., 0]``; (..., 3, 3)."""
    r2 = np.einsum("...k,...k->...", r, r)
    e2 = eps**2
    i3 = (r2 + e2) ** -1.5
    out = _outer(r, r) * i3[..., None, None]
    diag = (r2 + 2 * e2) * i3
    for a in range(3):
        out[..., a, a] += diag
    return out


def image_block(targets: np.ndarray, sources: np.ndarray, eps: np.ndarray) -> np.ndarray:
    """8π × the wall image of the Stokeslet, (5) of docs/physics.md, as (M, N, 3, 3) matrices.

    Each term of (5) linear in f is written as a matrix: f* = Δ f, R·f* = (Δ R)·f, f3 = e3·f.
    """
    h = sources[None, :, 2]
    big_r = targets[:, None, :] - sources[None, :, :] * _DELTA
    r3 = big_r[..., 2]
    r2 = np.einsum("...k,...k->...", big_r, big_r)
    e2 = eps**2
    i3 = (r2 + e2) ** -1.5
    i5 = (r2 + e2) ** -2.5
    dr = big_r * _DELTA  # R·f* = (ΔR)·f
    x = lambda a: a[..., None, None]  # noqa: E731
    eye = np.eye(3)
    delta = np.diag(_DELTA)
    out = -(x((r2 + 2 * e2) * i3) * eye + x(i3) * _outer(big_r, big_r))
    out += x(2 * h**2) * (x(i3 - 3 * e2 * i5) * delta - x(3 * i5) * _outer(big_r, dr))
    out += x(2 * h) * (
        x((r2 + 4 * e2) * i5) * _outer(np.broadcast_to(_E3, big_r.shape), dr)
        - x(r3 * i3) * delta
        + x(i3) * _outer(big_r, np.broadcast_to(_E3, big_r.shape))
        + x(3 * r3 * i5) * _outer(big_r, dr)
    )
    out -= x(6 * h * e2 * i5) * (_outer(np.broadcast_to(_E3, big_r.shape), big_r) - x(r3) * eye)
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
        with kernel_threads(n_threads):
            pass  # validates n_threads before any work
        self.targets = np.ascontiguousarray(t)
        self.sources = np.ascontiguousarray(s)
        per_source = np.ndim(epsilon) == 1
        self.epsilon: float | np.ndarray = eps[0] if per_source else float(eps[0])
        self.mu = float(visc[0])
        self.wall = bool(wall)
        self.n_threads = n_threads
        self.shape = (3 * len(self.targets), 3 * len(self.sources))

    def matvec(self, f_flat: np.ndarray) -> np.ndarray:
        """A f for flattened forces ``f_flat`` (3N,) -> velocities (3M,), compiled kernels."""
        forces = np.ascontiguousarray(np.asarray(f_flat, dtype=np.float64).reshape(-1, 3))
        if forces.shape[0] != len(self.sources):
            raise ValueError(
                f"f_flat: expected {self.shape[1]} entries (3 per source), got {np.size(f_flat)}"
            )
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
        eps = np.broadcast_to(np.asarray(self.epsilon, dtype=np.float64), (n,))
        out = np.empty((m, 3, n, 3))
        tile = max(1, _TILE_ENTRIES // (9 * n))
        for start in range(0, m, tile):
            t = self.targets[start : start + tile]
            r = t[:, None, :] - self.sources[None, :, :]
            block = free_block(r, eps[None, :])
            if self.wall:
                block += image_block(t, self.sources, eps[None, :])
            out[start : start + tile] = block.transpose(0, 2, 1, 3)
        out /= 8 * math.pi * self.mu
        return out.reshape(3 * m, 3 * n)

    def as_linear_operator(self):
        """A as a :class:`scipy.sparse.linalg.LinearOperator` applying :meth:`matvec`."""
        from scipy.sparse.linalg import LinearOperator

        return LinearOperator(self.shape, matvec=self.matvec, dtype=np.float64)
