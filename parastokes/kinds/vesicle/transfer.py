"""Grid transfer of vesicle states between icosphere levels (paper Remark 4, eqs. 32-33).

An icosphere of level n + 1 keeps the 10·4^n + 2 vertices of level n as its first rows and adds one
vertex per edge of level n, at the edge's midpoint pushed out to the sphere
(:func:`~parastokes.bodies.geometry.icosphere`). So restriction is injection (the first rows), and
prolongation rebuilds each finer level from the coarser one: a new vertex is the midpoint of its
parent edge, moved along the direction from the body's centroid through that midpoint by the sag
the initial sphere has there (``radius (1 - |(v_a + v_b)/2|)`` for unit vertices v_a, v_b). The
initial sphere, and any translate or rotation of it, prolongs exactly (the coarse vertices'
centroid is the sphere's centre); ``restrict(prolong(x_c)) == x_c`` always. A vesicle that deforms
from the sphere prolongs with an error of the order of its deformation times the sag.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ...bodies import geometry

__all__ = ["VesicleTransfer", "levels_down"]


def levels_down(factor: int, subdivisions: int) -> int:
    """The icosphere levels a grid ``factor`` times coarser drops: ``factor`` = 2^j (each level
    halves the edges), j <= ``subdivisions``; ValueError otherwise."""
    if isinstance(factor, bool) or not isinstance(factor, int | np.integer) or factor < 1:
        raise ValueError(f"factor: must be a positive integer, got {factor!r}")
    j = int(factor).bit_length() - 1
    if factor != 1 << j or j > subdivisions:
        raise ValueError(f"must be a power of 2 of at most 2^subdivisions = {1 << subdivisions} "
                         f"(each icosphere level halves the edges), got {factor}")
    return j


@lru_cache(maxsize=16)
def _refinement(level: int) -> tuple[np.ndarray, np.ndarray]:
    """(parent edges (E, 2), sags (E,) on the unit sphere) of the vertices level + 1 adds to
    level ``level``, in their order (as :func:`geometry.icosphere` builds them)."""
    verts, tris = geometry.icosphere(level)
    pairs = np.stack([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]], axis=1)
    edges = np.unique(np.sort(pairs, axis=2).reshape(-1, 2), axis=0)
    sags = 1.0 - np.linalg.norm(0.5 * (verts[edges[:, 0]] + verts[edges[:, 1]]), axis=1)
    for array in (edges, sags):
        array.setflags(write=False)
    return edges, sags


@dataclass(frozen=True)
class VesicleTransfer:
    """Restriction and prolongation between icosphere levels ``fine_level`` > ``coarse_level`` of a
    vesicle of ``radius`` (module docstring)."""

    fine_level: int
    coarse_level: int
    radius: float

    def restrict(self, x_fine: np.ndarray) -> np.ndarray:
        """Fine state -> coarse state: the coarse level's vertices (the first rows)."""
        n = len(geometry.icosphere(self.coarse_level)[0])
        return np.array(x_fine[:n], dtype=float)

    def prolong(self, x_coarse: np.ndarray) -> np.ndarray:
        """Coarse state -> fine state, one level at a time (module docstring)."""
        x = np.asarray(x_coarse, dtype=float)
        for level in range(self.coarse_level, self.fine_level):
            edges, sags = _refinement(level)
            mid = 0.5 * (x[edges[:, 0]] + x[edges[:, 1]])
            out = mid - x.mean(axis=0)
            out /= np.linalg.norm(out, axis=1, keepdims=True)
            x = np.concatenate([x, mid + (self.radius * sags)[:, None] * out])
        return x
