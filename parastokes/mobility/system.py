"""Several placed rigid surfaces in one fluid: their points, ε, rigid-motion matrices, the
input checks, and the fluid operator over all of them."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..mrs.operator import StokesletOperator
from .checks import check_placements
from .errors import SolveError
from .rigid import PlacedSurface


def _vectors(name: str, value, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` (None: zeros) as float64 of ``shape``; one (3,) vector is taken for all rows.
    Non-finite values (loads, slip or a background flow that went NaN in a run) are a
    :class:`SolveError`: a blow-up of the step, not bad input."""
    if value is None:
        return np.zeros(shape)
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape == (3,) and shape != (3,):
        arr = np.broadcast_to(arr, shape)
    if arr.shape != shape:
        raise ValueError(f"{name}: expected shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        why = "; the other bodies' flow is not finite" if name == "background" else ""
        raise SolveError(f"{name}: contains non-finite values ({int((~np.isfinite(arr)).sum())} "
                         f"of {arr.size}){why}")
    return np.array(arr)


class SurfaceSet:
    """Placed rigid surfaces ``placed`` in a fluid of viscosity ``mu`` (``wall``: above z = 0).

    ``offsets[b]:offsets[b+1]`` are body b's rows among the N points; ``motions[b]`` is its
    K (3 N_b, 6). Construction runs the placement checks (wall, overlap).
    """

    def __init__(
        self,
        placed: Sequence[PlacedSurface] | PlacedSurface,
        mu: float,
        wall: bool,
        n_threads: int | None = None,
    ) -> None:
        if isinstance(placed, PlacedSurface):
            placed = [placed]
        self.placed = list(placed)
        if not self.placed:
            raise ValueError("surfaces: no bodies given")
        for p in self.placed:
            if not isinstance(p, PlacedSurface):
                raise TypeError(
                    f"surfaces: expected PlacedSurface items (RigidSurface.place), "
                    f"got {type(p).__name__}"
                )
        if not (np.isfinite(mu) and mu > 0):
            raise ValueError(f"mu: must be finite and > 0, got {mu!r}")
        self.mu = float(mu)
        self.wall = bool(wall)
        self.n_threads = n_threads
        sizes = [len(p.points) for p in self.placed]
        self.offsets = np.concatenate([[0], np.cumsum(sizes)])
        self.points = np.concatenate([p.points for p in self.placed])
        self.epsilon = np.concatenate([p.epsilon for p in self.placed])
        self.motions = [p.motion() for p in self.placed]
        spacings = [p.surface.spacing for p in self.placed]
        self.spacings = spacings
        check_placements(
            [p.points for p in self.placed], spacings, [p.name for p in self.placed], self.wall
        )
        #: a length scale of the bodies (rms distance of the points from their centers), used to
        #: make the augmented system dimensionless
        self.length = float(np.sqrt(np.mean([p.surface.size**2 for p in self.placed])))

    @property
    def n_bodies(self) -> int:
        return len(self.placed)

    @property
    def n_points(self) -> int:
        return len(self.points)

    def operator(self) -> StokesletOperator:
        return StokesletOperator(
            None, self.points, self.epsilon, self.mu, wall=self.wall, n_threads=self.n_threads
        )

    def rows(self, b: int) -> slice:
        return slice(3 * self.offsets[b], 3 * self.offsets[b + 1])

    def motion(self) -> np.ndarray:
        """The block-diagonal K (3N, 6B) of all bodies."""
        k = np.zeros((3 * self.n_points, 6 * self.n_bodies))
        for b, kb in enumerate(self.motions):
            k[self.rows(b), 6 * b : 6 * b + 6] = kb
        return k

    def apply_motion(self, y: np.ndarray) -> np.ndarray:
        """K Y for Y (B, 6): every point's rigid velocity (3N,)."""
        return np.concatenate([kb @ yb for kb, yb in zip(self.motions, y, strict=True)])

    def reduce(self, f: np.ndarray) -> np.ndarray:
        """Kᵀ f for f (3N,): each body's total force and torque about its center, (B, 6)."""
        return np.stack([kb.T @ f[self.rows(b)] for b, kb in enumerate(self.motions)])

    def point_vectors(self, name: str, value) -> np.ndarray:
        """A per-point (N, 3) input (None: zeros) flattened to (3N,)."""
        return _vectors(name, value, (self.n_points, 3)).ravel()

    def slip_vectors(self, value, frame: str) -> tuple[np.ndarray, np.ndarray | None]:
        """The slip (N, 3) (None: zeros) flattened in the lab, and as given when ``frame`` is
        ``"body"`` (each body's rows in its own frame, turned by its rotation to the lab)."""
        if frame not in ("lab", "body"):
            raise ValueError(f"slip_frame: must be 'lab' or 'body', got {frame!r}")
        slip = _vectors("slip", value, (self.n_points, 3))
        if frame == "lab":
            return slip.ravel(), None
        lab = np.concatenate(
            [
                slip[self.offsets[b] : self.offsets[b + 1]] @ p.rotation.T
                for b, p in enumerate(self.placed)
            ]
        )
        return lab.ravel(), slip.ravel()

    def body_vectors(self, name: str, value) -> np.ndarray:
        """A per-body (B, 3) input (None: zeros; one (3,) vector: the same for every body)."""
        return _vectors(name, value, (self.n_bodies, 3))
