"""The vesicle system: the spring-network sphere in shear flow (paper section 5.2; docs/physics.md
section 4), and its public factory :func:`vesicle` (defaults = the paper's).

Free-space regularized Stokeslets (eq. 6) of the spring forces (docs/physics.md (14)) plus the shear
flow u∞ = (γ̇ z, 0, 0) (docs/physics.md (15)); Θ = (ε, μ, κ). The system is a frozen dataclass of
scalars (the mesh is rebuilt on demand and cached per process), so it pickles in a few hundred
bytes. Importing this module registers its compiled loop (:mod:`.compiled`) and its GPU device parts
(:mod:`.device`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import lru_cache
from typing import ClassVar

import numpy as np

from ...bodies import geometry
from ...bodies.base import PointsInShear, replace_params, require_positive
from ...fluid import MRS, Blocks
from ...integrate import loop
from ...mrs.velocity import thread_count
from ...registry import loops as registry
from ...stiff.coloring import from_edges
from .compiled import vesicle_data
from .mechanics import spring_forces
from .transfer import VesicleTransfer, levels_down

__all__ = ["VesicleSystem", "longest_edge", "vesicle"]


@lru_cache(maxsize=8)
def _sphere(subdivisions: int, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """The icosphere of ``subdivisions`` levels scaled to ``radius`` (cached, read-only)."""
    verts, tris = geometry.icosphere(subdivisions)
    verts = verts * radius
    verts.setflags(write=False)
    return verts, tris


@lru_cache(maxsize=8)
def _spring_network(subdivisions: int, radius: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Edges, rest lengths and area of the initial sphere (cached, read-only)."""
    verts, tris = _sphere(subdivisions, radius)
    edges = geometry.mesh_edges(tris)
    rest = geometry.edge_lengths(verts, edges)
    edges.setflags(write=False)
    rest.setflags(write=False)
    return edges, rest, geometry.surface_area(verts, tris)


def longest_edge(subdivisions: int, radius: float = 1.0) -> float:
    """l_max: the longest edge of the initial sphere (the length unit of the paper's ε)."""
    require_positive(radius=radius)
    return float(_spring_network(subdivisions, radius)[1].max())


@dataclass(frozen=True)
class VesicleSystem(PointsInShear):
    """An icosphere (``subdivisions`` levels) of radius ``radius`` with springs on its edges in a
    shear flow.

    Rest lengths are the initial edge lengths (so they scale with the radius); ε is absolute (the
    paper quotes ε = 0.3 l_max, see :func:`vesicle`); κ = ``stiffness``; u∞ = (γ̇ z, 0, 0),
    γ̇ = ``shear_rate``.
    """

    subdivisions: int
    epsilon: float
    viscosity: float
    stiffness: float
    shear_rate: float
    n_threads: int | None = None
    target_blocks: Blocks | None = None
    center: tuple[float, float, float] = (0.0, 0.0, 0.0)
    radius: float = 1.0

    #: ``parastokes tune``'s Lagrange node levels (relative distances of the first node at reach
    #: 0, 1, 2; spacing as a fraction of that distance): level 0 gives Table 8 G³'s nodes, level 2
    #: Table 7 G¹'s, level 1 of ε Table 7 G²'s and of μ Table 8 G¹'s. The rods' default reach
    #: (2-8 % in ε) lies far below them.
    tuning_reach: ClassVar[dict[str, tuple[tuple[float, float, float], float]]] = {
        "epsilon": ((0.2, 0.35, 0.6), 0.5),
        "stiffness": ((0.1, 0.15, 0.2), 0.5),
        "viscosity": ((0.4, 0.6, 1.0), 0.5),
    }

    def __post_init__(self) -> None:
        geometry.icosphere(self.subdivisions)  # validates subdivisions
        require_positive(
            epsilon=self.epsilon,
            viscosity=self.viscosity,
            stiffness=self.stiffness,
            radius=self.radius,
        )
        if not math.isfinite(self.shear_rate):
            raise ValueError(f"shear_rate: must be finite, got {self.shear_rate!r}")
        thread_count(self.n_threads)  # ValueError now, not at the first step

    @property
    def mesh(self) -> tuple[np.ndarray, np.ndarray]:
        """(vertices, triangles) of the initial sphere around the origin (cached, read-only)."""
        return _sphere(self.subdivisions, self.radius)

    @property
    def edges(self) -> np.ndarray:
        return _spring_network(self.subdivisions, self.radius)[0]

    @property
    def rest_lengths(self) -> np.ndarray:
        return _spring_network(self.subdivisions, self.radius)[1]

    @property
    def initial_area(self) -> float:
        return _spring_network(self.subdivisions, self.radius)[2]

    def initial_state(self) -> np.ndarray:
        """The sphere's vertices around ``center``."""
        return self.mesh[0] + np.asarray(self.center, dtype=float)

    def forces(self, state: np.ndarray) -> np.ndarray:
        """Spring forces on the fluid (docs/physics.md (14))."""
        return spring_forces(state, self.edges, self.rest_lengths, self.stiffness)

    def load_coupling(self):
        """A vertex's force depends on itself and the vertices it shares a spring with: the
        pattern of :mod:`parastokes.stiff`'s coloured finite-difference Jacobian."""
        return from_edges(len(self.mesh[0]), self.edges)

    @property
    def params(self) -> dict[str, float]:
        return {"epsilon": self.epsilon, "viscosity": self.viscosity, "stiffness": self.stiffness}

    def with_params(self, **theta: float) -> VesicleSystem:
        """A copy with some of ``epsilon``, ``viscosity``, ``stiffness`` (κ) changed."""
        return replace_params(self, theta)

    @property
    def monitor_limit(self) -> float:
        return 1e-4

    def monitor(self, state: np.ndarray) -> float:
        """Relative change of the surface area from the initial sphere's (section 5.2)."""
        area = geometry.surface_area(state, self.mesh[1])
        return abs(area - self.initial_area) / self.initial_area

    # ---- coarse grid (Remark 4) ------------------------------------------------------------
    def coarsened(self, factor: int) -> tuple[VesicleSystem, VesicleTransfer]:
        """The same vesicle on the icosphere with edges ``factor`` = 2^j times longer (j levels
        fewer; same ε, κ and μ in absolute units: a spring network's membrane modulus does not
        depend on its edge length) and the transfer (:mod:`.transfer`)."""
        j = levels_down(factor, self.subdivisions)
        coarse = replace(self, subdivisions=self.subdivisions - j)
        return coarse, VesicleTransfer(self.subdivisions, coarse.subdivisions, self.radius)


def vesicle(
    subdivisions: int = 3,
    epsilon_factor: float = 0.3,
    stiffness: float = 0.1,
    viscosity: float = 1e-3,
    shear_rate: float = 0.1,
    *,
    radius: float = 1.0,
    center: tuple[float, float, float] = (0.0, 0.0, 0.0),
    n_threads: int | None = None,
) -> VesicleSystem:
    """The elastic sphere of section 5.2 (radius 1 by default, centred at ``center``): icosphere
    (642 points at level 3), Hookean edge springs of stiffness κ = ``stiffness``, free-space
    Stokeslets with ε = ``epsilon_factor`` · l_max (l_max the longest edge, ≈ 0.165 ``radius``),
    shear flow u∞ = (γ̇ z, 0, 0)."""
    if not (isinstance(epsilon_factor, int | float) and epsilon_factor > 0):
        raise ValueError(f"epsilon_factor: must be > 0, got {epsilon_factor!r}")
    if len(center) != 3:
        raise ValueError(f"center: need three coordinates (x, y, z), got {center!r}")
    return VesicleSystem(
        subdivisions=subdivisions,
        epsilon=epsilon_factor * longest_edge(subdivisions, radius),
        viscosity=viscosity,
        stiffness=stiffness,
        shear_rate=shear_rate,
        n_threads=n_threads,
        center=(float(center[0]), float(center[1]), float(center[2])),
        radius=radius,
    )


loop.register_parts(VesicleSystem, vesicle_data, fluid=MRS, in_scenes=True)
registry.register_device(VesicleSystem, "parastokes.kinds.vesicle.device:PARTS")
