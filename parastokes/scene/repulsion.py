"""A short-range repulsion between the rigid bodies of a scene (and the wall), optional.

Bodies that sediment or swim together come close; the mobility solve refuses two surfaces
closer than half their surface spacing (:func:`parastokes.mobility.checks.check_placements`:
the discrete surfaces can no longer be told apart). Suspension codes keep them apart with a
soft contact force; :class:`Repulsion` is the common one: for two bodies whose surfaces come
within the ``range`` δ (gap h < δ),

    F = F₀ (1 − h/δ)²

on each, along the line through their closest points, pushing them apart (equal and opposite:
no net force), applied at the closest point of each surface, so it also turns a body about its
reference point (a sphere: not at all). With ``wall`` the plane z = 0 pushes every body up by
the same law, h the height of its lowest point, applied there.

The gap and the closest points:

- two spheres (a :class:`~parastokes.kinds.rigid.shapes.Sphere` shape, reference point its
  centre): exact, h = ‖c₁ − c₂‖ − a₁ − a₂ along the line of centres (the same on a coarse
  surface, so the coarse scene of Parareal feels the same force);
- a sphere and another body: the other's surface point closest to the sphere's centre, h its
  distance less the radius;
- otherwise: the closest pair of surface points (a k-d tree of one body's points).

Only pairs whose bounding spheres (about the reference points) come within δ are looked at, found
with a k-d tree of the centres: O(bodies) for a dilute suspension. The pairs are visited in a
fixed order, so the loads are a deterministic function of the state (Parareal reproduces its
iterates bit for bit).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from ..kinds.rigid.shapes import Sphere

__all__ = ["Repulsion", "repulsion_loads"]


@dataclass(frozen=True)
class Repulsion:
    """F₀ (1 − h/δ)² between surfaces a gap h < δ apart: ``range`` δ (μm), ``force`` F₀ (the
    force units of a rigid body's ``force``) at contact (see the module)."""

    range: float
    force: float

    def __post_init__(self) -> None:
        for key in ("range", "force"):
            value = getattr(self, key)
            if (isinstance(value, bool) or not isinstance(value, int | float)
                    or not math.isfinite(value) or value <= 0):
                raise ValueError(f"repulsion.{key}: must be a finite number > 0, got {value!r}")
            object.__setattr__(self, key, float(value))

    def magnitude(self, gap: float) -> float:
        """F₀ (1 − gap/δ)² for gap < δ (growing on past contact), else 0."""
        if gap >= self.range:
            return 0.0
        return self.force * (1.0 - gap / self.range) ** 2


def _sphere_radius(surface: Any) -> float | None:
    """The radius of a surface that is a sphere about its reference point, else None."""
    key = getattr(surface, "key", None)
    return float(key.radius) if isinstance(key, Sphere) else None


def _closest(i: int, j: int, points: Sequence[np.ndarray], centers: np.ndarray,
             spheres: list[float | None]) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
    """(gap, unit normal from body j to body i, contact point on i, contact point on j)."""
    ai, aj = spheres[i], spheres[j]
    if ai is not None and aj is not None:
        d = centers[i] - centers[j]
        r = float(np.linalg.norm(d))
        n = d / r
        return r - ai - aj, n, centers[i] - ai * n, centers[j] + aj * n
    if ai is not None or aj is not None:
        s, o = (i, j) if ai is not None else (j, i)
        a = spheres[s]
        assert a is not None
        d = centers[s] - points[o]
        r = np.linalg.norm(d, axis=1)
        k = int(np.argmin(r))
        n = d[k] / r[k]
        gap, on_s, on_o = float(r[k]) - a, centers[s] - a * n, points[o][k]
        return (gap, n, on_s, on_o) if s == i else (gap, -n, on_o, on_s)
    dist, index = cKDTree(points[j]).query(points[i])
    k = int(np.argmin(dist))
    pi, pj = points[i][k], points[j][int(index[k])]
    d = pi - pj
    r = float(np.linalg.norm(d))
    if r == 0.0:  # touching points: push along the line of the reference points
        d = centers[i] - centers[j]
        r = float(np.linalg.norm(d))
    return float(dist[k]), d / r, pi, pj


def repulsion_loads(surfaces: Sequence[Any], repulsion: Repulsion, wall: bool = False
                    ) -> tuple[np.ndarray, np.ndarray]:
    """The repulsion's force and torque (about each reference point) on every one of
    ``surfaces`` (each with lab-frame ``points`` and reference point ``center``, as
    :class:`parastokes.kinds.rigid.solve.Surface`), (B, 3) each; ``wall``: also the wall's
    push (see the module)."""
    n_bodies = len(surfaces)
    force, torque = np.zeros((n_bodies, 3)), np.zeros((n_bodies, 3))
    points = [np.asarray(s.points, dtype=float) for s in surfaces]
    centers = np.array([np.asarray(s.center, dtype=float) for s in surfaces]).reshape(-1, 3)
    spheres = [_sphere_radius(s) for s in surfaces]
    reach = np.array([a if a is not None else float(np.max(np.linalg.norm(p - c, axis=1)))
                      for a, p, c in zip(spheres, points, centers, strict=True)])

    def push(k: int, value: np.ndarray, at: np.ndarray) -> None:
        force[k] += value
        if spheres[k] is None:  # (on a sphere it acts through the centre: no torque)
            torque[k] += np.cross(at - centers[k], value)

    if n_bodies > 1:
        pairs = cKDTree(centers).query_pairs(2 * float(reach.max()) + repulsion.range,
                                             output_type="ndarray")
        for i, j in sorted((int(min(p)), int(max(p))) for p in pairs):
            if np.linalg.norm(centers[i] - centers[j]) >= reach[i] + reach[j] + repulsion.range:
                continue
            gap, n, on_i, on_j = _closest(i, j, points, centers, spheres)
            value = repulsion.magnitude(gap)
            if value > 0.0:
                push(i, value * n, on_i)
                push(j, -value * n, on_j)
    if wall:
        up = np.array([0.0, 0.0, 1.0])
        for k in range(n_bodies):
            a = spheres[k]
            low = centers[k] - a * up if a is not None else points[k][int(np.argmin(
                points[k][:, 2]))]
            value = repulsion.magnitude(float(low[2]))
            if value > 0.0:
                push(k, value * up, low)
    return force, torque
