"""Rigid surfaces: a point cloud in the body frame, its placement in the lab, rigid motion.

- :func:`rigid_motion`: the matrix K (3N, 6) of K [U, Ω] = U + Ω × (x - c) at each point; its
  transpose maps point forces to the total force and the torque about c, Kᵀ f = (Σ f, Σ (x-c) × f).
- :class:`RigidSurface`: the body-frame points and their ε; it keeps the LU factorization of its
  own free-space Stokeslet matrix per viscosity (:mod:`parastokes.mobility.selfsolve`), reused at
  any placement.
- :class:`PlacedSurface`: a surface at a center and a rotation: lab points x = c + R p.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from typing import Any

import numpy as np

#: Held while a surface makes its body-frame factorization (threads of hosted solves share it).
_FACTORING = threading.Lock()


def rigid_motion(points: np.ndarray, center: np.ndarray) -> np.ndarray:
    """K (3N, 6): row block i is [I, -[x_i - c]×], so K @ [U, Ω] = U + Ω × (x_i - c)."""
    d = np.asarray(points, dtype=np.float64) - np.asarray(center, dtype=np.float64)
    n = len(d)
    k = np.zeros((n, 3, 6))
    k[:, 0, 0] = k[:, 1, 1] = k[:, 2, 2] = 1.0
    # Ω × d = -d × Ω = -[d]× Ω
    k[:, 0, 4], k[:, 0, 5] = d[:, 2], -d[:, 1]
    k[:, 1, 3], k[:, 1, 5] = -d[:, 2], d[:, 0]
    k[:, 2, 3], k[:, 2, 4] = d[:, 1], -d[:, 0]
    return k.reshape(3 * n, 6)


def _epsilon_array(epsilon: Any, n: int) -> np.ndarray:
    eps = np.asarray(epsilon, dtype=np.float64)
    if eps.ndim == 0:
        eps = np.full(n, float(eps))
    if eps.shape != (n,):
        raise ValueError(f"epsilon: expected a number or shape ({n},), got shape {eps.shape}")
    if not np.all(np.isfinite(eps)) or np.any(eps <= 0):
        raise ValueError("epsilon: must be finite and > 0 at every point")
    return eps


class RigidSurface:
    """A rigid body's surface: points ``points_body`` (N, 3) in its own frame (about its
    reference point, the origin, which becomes the placement's center) and ε per point.

    ``check=True`` (default) runs :func:`parastokes.mobility.checks.check_surface` (a surface
    too coarse for its ε is refused). The surface keeps its body-frame factorizations (one per
    viscosity) for reuse at every placement in free space.
    """

    def __init__(
        self,
        points_body: np.ndarray,
        epsilon: float | np.ndarray,
        *,
        name: str = "body",
        check: bool = True,
    ) -> None:
        pts = np.array(points_body, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) < 2:
            raise ValueError(f"{name}: points_body must have shape (N, 3), N >= 2; got {pts.shape}")
        if not np.all(np.isfinite(pts)):
            raise ValueError(f"{name}: points_body contains non-finite values")
        self.name = name
        self.points = pts
        self.points.setflags(write=False)
        self.epsilon = _epsilon_array(epsilon, len(pts))
        self.epsilon.setflags(write=False)
        self._factors: dict[float, Any] = {}
        self._spacing: float | None = None
        if check:
            from .checks import check_surface

            check_surface(pts, self.epsilon, name=name)

    def __getstate__(self) -> dict:
        """Pickled without the cached factorizations (hundreds of MB for a few thousand points):
        a worker process makes its own on first use."""
        state = self.__dict__.copy()
        state["_factors"] = {}
        return state

    @property
    def size(self) -> float:
        """The rms distance of the points from the reference point (a length scale)."""
        return float(np.sqrt(np.mean(np.sum(self.points**2, axis=1))))

    @property
    def spacing(self) -> float:
        """The median distance from a point to its nearest neighbour (computed once)."""
        if self._spacing is None:
            from .checks import nearest_spacing

            self._spacing = float(np.median(nearest_spacing(self.points)))
        return self._spacing

    def __len__(self) -> int:
        return len(self.points)

    def place(self, center=(0.0, 0.0, 0.0), rotation: np.ndarray | None = None,
              label: str | None = None) -> PlacedSurface:
        """This surface at ``center`` turned by ``rotation`` (3x3 proper orthogonal), named
        ``label`` (default: the surface's name) in messages."""
        return PlacedSurface(
            self,
            np.asarray(center, dtype=np.float64),
            np.eye(3) if rotation is None else np.asarray(rotation, float),
            label,
        )

    def self_factor(self, mu: float):
        """The cached body-frame factorization of this surface's free-space Stokeslet matrix at
        viscosity ``mu`` (:class:`parastokes.mobility.selfsolve.BodyFrameFactor`)."""
        from .selfsolve import BodyFrameFactor

        key = float(mu)
        with _FACTORING:  # one factorization per viscosity, whatever the threads asking
            if key not in self._factors:
                self._factors[key] = BodyFrameFactor(self, key)
            return self._factors[key]


@dataclass(frozen=True)
class PlacedSurface:
    """A :class:`RigidSurface` at ``center`` (3,) with orientation ``rotation`` (3, 3): lab points
    x_i = center + rotation @ p_i; ``label``: the body's name in messages (default: the
    surface's, which copies of one surface share)."""

    surface: RigidSurface
    center: np.ndarray
    rotation: np.ndarray
    label: str | None = None
    points: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        c, r = self.center, self.rotation
        name = self.name
        if c.shape != (3,) or not np.all(np.isfinite(c)):
            raise ValueError(f"{name}: center must be 3 finite numbers, got {c!r}")
        if (
            r.shape != (3, 3)
            or not np.allclose(r @ r.T, np.eye(3), atol=1e-10)
            or np.linalg.det(r) <= 0
        ):
            raise ValueError(
                f"{name}: rotation must be a proper rotation matrix (RᵀR = I, "
                f"det R = 1): renormalize the orientation"
            )
        object.__setattr__(self, "points", c + self.surface.points @ r.T)

    @property
    def name(self) -> str:
        return self.label or self.surface.name

    @property
    def epsilon(self) -> np.ndarray:
        return self.surface.epsilon

    def motion(self) -> np.ndarray:
        """K (3N, 6) of :func:`rigid_motion` at the lab points about the center."""
        return rigid_motion(self.points, self.center)
