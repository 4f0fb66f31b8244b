"""Initial shapes: straight rods (paper section 5.1) and icospheres (section 5.2; docs/physics.md
section 4).

- :func:`straight_rods`: rods X(s) = (s, y_j, height), s = k Δs, with frames D1 = e_y, D2 = e_z,
  D3 = e_x (the tangent), parallel and side by side in y (Table 2; section 5.1.4).
- :func:`icosphere`: the unit sphere triangulated by repeated 4-to-1 splitting of the icosahedron
  through edge midpoints projected onto the sphere; level 3 has 642 vertices, 1280 triangles and
  1920 edges (l_max ≈ 0.165). Triangles are oriented with outward normals.
- :func:`mesh_edges`, :func:`edge_lengths`, :func:`surface_area`: mesh quantities used by the spring
  network (eq. 14 of docs/physics.md) and the vesicle's area monitor.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from numba import njit
from scipy.spatial import ConvexHull


@njit(cache=True)
def crossed_wall(x: np.ndarray, wall: bool) -> bool:
    """Whether a point of the state ``x`` (positions in columns 0-2) is on or below the wall
    z = 0 when there is one: the images of the method are valid for z > 0 only (docs/physics.md), so
    the bodies' monitors report such a state as infinitely unstable."""
    if wall:
        for i in range(x.shape[0]):
            if not x[i, 2] > 0.0:
                return True
    return False


def straight_rods(
    n_rods: int, n_points: int, length: float, height: float, spacing: float
) -> np.ndarray:
    """State (n_rods * n_points, 12) of straight rods along x at height ``height``.

    Rod j lies at y_j = (j - (n_rods - 1)/2) * spacing; rows are ``[X, D1, D2, D3]`` with
    D1 = e_y, D2 = e_z, D3 = e_x (so the preferred curvature Ω̂_2 bends the rod in the xy-plane,
    parallel to the wall).
    """
    if n_rods < 1:
        raise ValueError(f"n_rods: must be >= 1, got {n_rods}")
    if n_points < 2:
        raise ValueError(f"n_points: must be >= 2, got {n_points}")
    s = np.linspace(0.0, length, n_points)
    state = np.zeros((n_rods, n_points, 12))
    state[:, :, 0] = s
    state[:, :, 1] = ((np.arange(n_rods) - (n_rods - 1) / 2) * spacing)[:, None]
    state[:, :, 2] = height
    state[:, :, 4] = 1.0  # D1 = e_y
    state[:, :, 8] = 1.0  # D2 = e_z
    state[:, :, 9] = 1.0  # D3 = e_x
    return state.reshape(n_rods * n_points, 12)


def _icosahedron() -> tuple[np.ndarray, np.ndarray]:
    phi = (1.0 + np.sqrt(5.0)) / 2.0
    v = []
    for a in (-1.0, 1.0):
        for b in (-phi, phi):
            v += [(0.0, a, b), (a, b, 0.0), (b, 0.0, a)]
    verts = np.array(v) / np.hypot(1.0, phi)
    return verts, ConvexHull(verts).simplices


def _orient_outward(verts: np.ndarray, tris: np.ndarray) -> np.ndarray:
    a, b, c = (verts[tris[:, i]] for i in range(3))
    inward = np.einsum("ij,ij->i", np.cross(b - a, c - a), a + b + c) < 0
    tris = tris.copy()
    tris[inward] = tris[inward][:, ::-1]
    return tris


def mesh_edges(triangles: np.ndarray) -> np.ndarray:
    """The unique edges (i < j) of a triangle list, sorted lexicographically, shape (E, 2)."""
    tri = np.asarray(triangles)
    pairs = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    return np.unique(np.sort(pairs, axis=1), axis=0)


@lru_cache(maxsize=8)
def icosphere(subdivisions: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Unit icosphere ``(vertices (V, 3), triangles (T, 3))``, V = 10·4^n + 2, T = 20·4^n.

    The arrays are cached and read-only.
    """
    if not isinstance(subdivisions, int | np.integer) or subdivisions < 0:
        raise ValueError(f"subdivisions: must be an integer >= 0, got {subdivisions!r}")
    verts, tris = _icosahedron()
    tris = _orient_outward(verts, tris)
    for _ in range(subdivisions):
        pairs = np.stack([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]], axis=1)  # (T, 3, 2)
        flat = np.sort(pairs, axis=2).reshape(-1, 2)
        edges, inverse = np.unique(flat, axis=0, return_inverse=True)
        mid = verts[edges[:, 0]] + verts[edges[:, 1]]
        mid /= np.linalg.norm(mid, axis=1, keepdims=True)
        m = (len(verts) + inverse).reshape(-1, 3)  # midpoints of edges ab, bc, ca
        a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
        ab, bc, ca = m[:, 0], m[:, 1], m[:, 2]
        tris = np.concatenate(
            [np.stack(t, axis=1) for t in ((a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca))]
        )
        verts = np.concatenate([verts, mid])
    verts.setflags(write=False)
    tris.setflags(write=False)
    return verts, tris


def edge_lengths(points: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """``|X_j - X_i|`` for every edge (i, j)."""
    return np.linalg.norm(points[edges[:, 1]] - points[edges[:, 0]], axis=1)


@njit(inline="always", cache=True, error_model="numpy")
def triangle_area2(points, i, j, k):
    """Twice the area of the triangle (X_i, X_j, X_k). Also compiled as a CUDA device function by
    :mod:`parastokes.gpu` (hence ``math.sqrt``)."""
    ux = points[j, 0] - points[i, 0]
    uy = points[j, 1] - points[i, 1]
    uz = points[j, 2] - points[i, 2]
    vx = points[k, 0] - points[i, 0]
    vy = points[k, 1] - points[i, 1]
    vz = points[k, 2] - points[i, 2]
    cx = uy * vz - uz * vy
    cy = uz * vx - ux * vz
    cz = ux * vy - uy * vx
    return math.sqrt(cx * cx + cy * cy + cz * cz)


@njit(cache=True, error_model="numpy")
def mesh_area(points, triangles):
    """Total area of the triangles (compiled; :func:`surface_area` is its Python entry)."""
    total = 0.0
    for t in range(triangles.shape[0]):
        total += triangle_area2(points, triangles[t, 0], triangles[t, 1], triangles[t, 2])
    return 0.5 * total


def surface_area(points: np.ndarray, triangles: np.ndarray) -> float:
    """Total area of the triangulated surface (compiled: the vesicle's per-step monitor)."""
    return float(mesh_area(points, triangles))
