"""Scenes: several bodies of any kinds in one fluid, as one system (one state, one set of Θ).

``Scene(bodies=(rod, vesicle), viscosity=1e-6, wall=True)`` couples its bodies through the fluid:
every body's point loads (forces, and torques for rods) drive the velocity at the points of all
bodies, each source with its own body's ε (regularized Stokeslets and rotlets, eq. 6 and
docs/physics.md (1)-(8); ``wall``: images in the plane z = 0), plus the background shear
u∞ = (γ̇ z, 0, 0) with its rotation w∞ = (0, γ̇/2, 0) for bodies with frames.

- **State**: the bodies' states stacked by rows, padded with zero columns to the widest (a rod's
  12, a vesicle's 3), so positions are the columns 0-2 of every row, as the output expects.
- **Θ**: ``viscosity`` (the one fluid's) and every body's other parameters as ``"name.param"``
  (``"rod.epsilon"``, ``"vesicle.stiffness"``): Lagrangian extrapolation varies any of them.
- **Monitor**: the largest of the bodies' monitors over their limits (``monitor_limit`` = 1).

Rigid and prescribed-motion bodies (:mod:`parastokes.kinds.rigid`: their surface forces are
unknown) join a scene too: a body with ``surface(t, state)`` and ``motion_rates`` is *implicit*.
A scene with one is evaluated by one coupled solve per stage (:meth:`Scene.coupled`): the
explicit bodies' loads are known; their velocity (and u∞) at the implicit surfaces is the
background of one mobility solve of all implicit bodies together (wall included); the explicit
bodies then move with the velocity of their own loads plus the implicit surface forces. Its
rows: an implicit body's centre row and surface rows (docs/contracts.md); its rates take the
body's ``rate_columns``. Such a scene runs the Python loop (no compiled parts). With
``repulsion`` (:class:`Repulsion`, off by default) the implicit bodies also push each other (and
the wall) apart when their surfaces come within its range: extra external forces and torques of
the coupled solve, a function of the state (:mod:`parastokes.scene.repulsion`).

The fluid is evaluated once per stage over all points (:func:`parastokes.mrs.velocity` with ε
per source: each point's blob has its body's width). A scene whose bodies' exact types all have
compiled parts (the rod, the vesicle, the chain) is stepped by a compiled loop composed of them
(:mod:`parastokes.scene.compiled`), with the same bits; a scene with any other body (a user's
Python body) runs the Runge-Kutta tableaux through the Python methods below.

A body in a scene offers ``loads(t, state) -> (forces, torques or None)``, ``angular`` (whether
its rates include angular velocities) and ``body_rates(u, w)`` (its rates from the fluid's
velocities at its points), besides the System contract (docs/contracts.md). Its ``viscosity``,
and its ``wall`` and ``shear_rate`` where it has them, must agree with the scene's.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from functools import cached_property
from typing import Any, NamedTuple

import numpy as np
from scipy.spatial import cKDTree

from .. import mrs
from ..bodies import contract
from ..bodies.geometry import crossed_wall
from ..bodies.sources import FluidSources, fluid_sources
from ..registry import loops as registry
from ..stiff.jacobian import NonFiniteJacobian, block_jacobian, local_jacobian
from . import coarse as scene_coarse
from .coarse import SceneTransfer
from .compiled import scene_loop
from .repulsion import Repulsion, repulsion_loads

__all__ = ["Repulsion", "Scene"]


#: What a body offers a scene beside the System contract (docs/contracts.md).
SCENE_MEMBERS = ("loads", "angular", "body_rates", "epsilon")
#: What an implicit body (its surface forces come from a mobility solve) offers instead.
IMPLICIT_MEMBERS = ("surface", "motion_rates", "inside", "epsilon")


def implicit(body: Any) -> bool:
    """Whether ``body``'s loads come from a mobility solve (a rigid or prescribed-motion body)."""
    return callable(getattr(body, "motion_rates", None))


class Coupled(NamedTuple):
    """One coupled evaluation of a scene with implicit bodies (:meth:`Scene.coupled`): the
    velocities ``u``, ``w`` at every row of the explicit bodies (zero elsewhere), the mobility
    solution of the implicit bodies, their surfaces, and the fluid's sources."""

    u: np.ndarray
    w: np.ndarray
    solution: Any
    surfaces: list[Any]
    sources: FluidSources


def _body_rates(body: Any, u: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``body.body_rates(u, w)``, checked where it enters: one row per point."""
    return contract.array(body, "body_rates(u, w)", body.body_rates(u, w), rows=len(u), ndim=2,
                          what="one row per point")


def _name(body: Any) -> str:
    return type(body).__name__.removesuffix("System").lower()


@dataclass(frozen=True)
class Scene:
    """``bodies`` (systems) in one MRS fluid of ``viscosity``, with ``wall`` and background shear
    ``shear_rate``; ``names`` label the bodies in Θ (default: their kinds, numbered if repeated)."""

    bodies: tuple[Any, ...]
    viscosity: float
    wall: bool = False
    shear_rate: float = 0.0
    names: tuple[str, ...] = ()
    n_threads: int | None = None
    #: The names of the bodies that :meth:`coarsened` puts on their coarser grid (None: every
    #: body that has one).
    coarse_bodies: tuple[str, ...] | None = None
    #: The short-range repulsion between its rigid bodies (and the wall), None: none
    #: (:mod:`parastokes.scene.repulsion`).
    repulsion: Repulsion | None = None

    def __post_init__(self) -> None:
        if not self.bodies:
            raise ValueError("bodies: a scene needs at least one body")
        if self.repulsion is not None and not isinstance(self.repulsion, Repulsion):
            raise ValueError(f"repulsion: a Repulsion(range, force) or None, got "
                             f"{self.repulsion!r}")
        object.__setattr__(self, "bodies", tuple(self.bodies))
        if not self.names:
            kinds = [_name(b) for b in self.bodies]
            names = [k if kinds.count(k) == 1 else f"{k}{kinds[:i].count(k)}"
                     for i, k in enumerate(kinds)]
            object.__setattr__(self, "names", tuple(names))
        if len(self.names) != len(self.bodies) or len(set(self.names)) != len(self.names):
            raise ValueError(f"names: need one distinct name per body, got {self.names!r}")
        if not all(isinstance(n, str) and n and "." not in n for n in self.names):
            raise ValueError(f"names: need non-empty strings without '.' (Θ's keys are "
                             f"\"name.param\"), got {self.names!r}")
        for name, body in zip(self.names, self.bodies, strict=True):
            members = IMPLICIT_MEMBERS if implicit(body) else SCENE_MEMBERS
            missing = [m for m in members if not hasattr(body, m)]
            if missing:
                raise ValueError(
                    f"{name}: a {type(body).__name__} cannot join a scene: it lacks "
                    f"{', '.join(missing)} (what a body offers a scene: docs/contracts.md, "
                    "'System')"
                )
            if self.wall and crossed_wall(np.asarray(body.initial_state()), True):
                raise ValueError(f"{name}: points on or below the wall z = 0 (wall=True); raise "
                                 "the body above the wall")
            if hasattr(body, "viscosity") and "viscosity" not in body.params:
                raise ValueError(
                    f"{name}: its viscosity is not among its params, so the scene's one "
                    f"viscosity could not be varied; add it to {type(body).__name__}.params"
                )
            for key in ("viscosity", "wall", "shear_rate"):
                if hasattr(body, key) and getattr(body, key) != getattr(self, key):
                    raise ValueError(
                        f"{name}.{key}: {getattr(body, key)!r} differs from the scene's "
                        f"{getattr(self, key)!r} (one fluid, one background flow)"
                    )
        if self.coarse_bodies is not None:
            object.__setattr__(self, "coarse_bodies", tuple(self.coarse_bodies))
            scene_coarse.check_names(self)
        if any(implicit(body) for body in self.bodies):
            self._check_overlaps()

    def _check_overlaps(self) -> None:
        """ValueError naming two bodies, one of them implicit, whose initial points come closer
        than the larger of their ε, or one of whose points lies inside the other. Only pairs
        whose bounding spheres come that close are looked at (a k-d tree of the spheres'
        centres), so a suspension of thousands of bodies is checked in a fraction of a second."""
        states = [np.asarray(body.initial_state()) for body in self.bodies]
        points = [x[1:, :3] if implicit(body) else x[:, :3]
                  for body, x in zip(self.bodies, states, strict=True)]
        centers = np.array([p.mean(axis=0) for p in points])
        radii = np.array([np.max(np.linalg.norm(p - c, axis=1))
                          for p, c in zip(points, centers, strict=True)])
        reach = np.array([float(body.epsilon) for body in self.bodies])
        tree = cKDTree(centers)
        pairs = tree.query_pairs(2 * radii.max() + reach.max(), output_type="ndarray")
        for i, j in sorted(map(tuple, pairs)):
            a, b = self.bodies[i], self.bodies[j]
            limit = max(reach[i], reach[j])
            if not (implicit(a) or implicit(b)) or (
                    np.linalg.norm(centers[i] - centers[j]) >= radii[i] + radii[j] + limit):
                continue
            pa, pb = points[i], points[j]
            gap = float(np.min(np.linalg.norm(pa[:, None, :] - pb[None, :, :], axis=-1)))
            inside = (implicit(a) and a.inside(states[i], pb).any()) or (
                implicit(b) and b.inside(states[j], pa).any())
            if inside or gap < limit:
                where = "one lies inside the other" if inside else (
                    f"their points come {gap:.3g} apart, closer than ε = {limit:.3g}")
                raise ValueError(
                    f"{self.names[i]} and {self.names[j]} overlap: {where}; move them "
                    "apart (their position / height)")

    # ---- layout of the state -------------------------------------------------------------
    @cached_property
    def shapes(self) -> tuple[tuple[int, int, int], ...]:
        """(first row, rows, state columns) of every body."""
        out, first = [], 0
        for body in self.bodies:
            rows, cols = np.shape(body.initial_state())
            out.append((first, rows, cols))
            first += rows
        return tuple(out)

    def blocks(self, array: np.ndarray, columns: list[int] | None = None) -> list[np.ndarray]:
        """Every body's view of a stacked ``array`` (its rows; its state columns by default)."""
        cols = columns or [c for _, _, c in self.shapes]
        return [array[f : f + n, :c] for (f, n, _), c in zip(self.shapes, cols, strict=True)]

    def stack(self, parts: list[np.ndarray]) -> np.ndarray:
        """The bodies' blocks (one per body, its rows) stacked into one array, zero-padded to
        the widest."""
        width = max(p.shape[1] for p in parts)
        out = np.zeros((sum(len(p) for p in parts), width))
        for (first, rows, _), part in zip(self.shapes, parts, strict=True):
            out[first : first + rows, : part.shape[1]] = part
        return out

    # ---- the System contract -------------------------------------------------------------
    def initial_state(self) -> np.ndarray:
        return self.stack([body.initial_state() for body in self.bodies])

    def positions(self, state: np.ndarray) -> np.ndarray:
        return np.array(state[:, :3])

    def source_epsilon(self) -> np.ndarray:
        """Every point's ε, its body's (N,)."""
        return np.repeat([float(body.epsilon) for body in self.bodies],
                         [rows for _, rows, _ in self.shapes])

    def fluid_sources(self, t: float, state: np.ndarray) -> FluidSources:
        """Every body's point loads on the fluid (:func:`~parastokes.bodies.sources.fluid_sources`),
        stacked in the order of the bodies, each source with its body's ε; torques None when no
        body has any. With implicit bodies: the explicit bodies' loads, then the implicit
        bodies' solved surface forces (:meth:`coupled`)."""
        if self.implicit_bodies:
            return self.coupled(t, state).sources
        return self._sources(t, state, range(len(self.bodies)))

    def _sources(self, t: float, state: np.ndarray, which: Any) -> FluidSources:
        """The loads of the bodies ``which`` (indices), stacked (empty when there are none)."""
        blocks = self.blocks(state)
        parts = [fluid_sources(self.bodies[i], t, blocks[i]) for i in which]
        if not parts:
            empty = np.zeros((0, 3))
            return FluidSources(empty, empty, None, np.zeros(0))
        torques = None
        if any(p.torques is not None for p in parts):
            torques = np.concatenate([np.zeros_like(p.forces) if p.torques is None else p.torques
                                      for p in parts])
        return FluidSources(np.concatenate([p.points for p in parts]),
                            np.concatenate([p.forces for p in parts]), torques,
                            np.concatenate([p.epsilon for p in parts]))

    def rates(self, t: float, state: np.ndarray) -> np.ndarray:
        """Each body's rates from u∞ + the velocities that all bodies' loads induce at its points:
        one evaluation of the fluid over all points, each source with its body's ε (with
        implicit bodies: :meth:`coupled`)."""
        if self.implicit_bodies:
            return self._coupled_rates(t, state)
        points = np.ascontiguousarray(state[:, :3])
        angular = any(body.angular for body in self.bodies)
        sources = self.fluid_sources(t, state)
        if angular and sources.torques is None:
            sources = sources._replace(torques=np.zeros_like(points))
        u, w = self._flow(points, sources, angular)
        parts = [_body_rates(body, u[f : f + n], w[f : f + n])
                 for body, (f, n, _) in zip(self.bodies, self.shapes, strict=True)]
        return self.stack(parts)

    @property
    def rate_columns(self) -> list[int]:
        """The columns of every body's rates: its ``rate_columns`` if it has them (rigid bodies:
        7), else 6 (u, w) for bodies with angular rates, else 3."""
        return [getattr(body, "rate_columns", 6 if body.angular else 3) for body in self.bodies]

    def advance(self, state: np.ndarray, rates: np.ndarray, dt: float) -> np.ndarray:
        parts = [
            contract.array(body, "advance(state, rates, dt)", body.advance(x, r, dt),
                           shape=x.shape, what="the state's shape")
            for body, x, r in zip(self.bodies, self.blocks(state),
                                  self.blocks(rates, self.rate_columns), strict=True)
        ]
        return self.stack(parts)

    def stiff_jacobian(self, t: float, state: np.ndarray) -> Any:
        """The approximate Jacobian of the linearly implicit schemes (:mod:`parastokes.stiff`):
        each body's own (its near mobility times its load Jacobian; none for rigid and
        prescribed-motion bodies), block-diagonal over the padded rates; the coupling between
        bodies stays out of it (W-methods keep their order with any approximation)."""
        cols = self.rate_columns
        parts = []
        for i, (body, x, (first, rows, _), rc) in enumerate(
                zip(self.bodies, self.blocks(state), self.shapes, cols, strict=True)):
            try:
                parts.append((first, rc, local_jacobian(body, t, x, rows * rc)))
            except contract.BodyError as error:  # a user's hook: which body of the scene
                raise contract.BodyError(f"bodies[{i}] ({self.names[i]!r}): {error}",
                                         error.method) from None
            except NonFiniteJacobian as error:  # a blow-up (exit 3), also naming the body
                raise NonFiniteJacobian(t, f"bodies[{i}] ({self.names[i]!r}): {error.method}",
                                        error.kind) from None
        return block_jacobian(parts, len(state), max(cols))

    def bracket(self, r1: np.ndarray, r2: np.ndarray) -> np.ndarray:
        """The bodies' Lie brackets (zero for bodies without one)."""
        cols = self.rate_columns
        parts = [
            body.bracket(a, b) if hasattr(body, "bracket") else np.zeros_like(a)
            for body, a, b in zip(self.bodies, self.blocks(r1, cols), self.blocks(r2, cols),
                                  strict=True)
        ]
        return self.stack(parts)

    def project(self, state: np.ndarray) -> np.ndarray:
        return self.stack([
            contract.array(body, "project(state)", body.project(x), shape=x.shape,
                           what="the state's shape")
            for body, x in zip(self.bodies, self.blocks(state), strict=True)
        ])

    # ---- implicit bodies: one coupled solve per evaluation -------------------------------
    @cached_property
    def implicit_bodies(self) -> tuple[int, ...]:
        """The indices of the implicit bodies (:func:`implicit`)."""
        return tuple(i for i, body in enumerate(self.bodies) if implicit(body))

    def _flow(self, targets: np.ndarray, sources: FluidSources, angular: bool
              ) -> tuple[np.ndarray, np.ndarray]:
        """u∞ + the velocity (and w∞ + w) of ``sources`` at ``targets``."""
        u, w = np.zeros_like(targets), np.zeros_like(targets)
        if len(sources.points) and len(targets):
            value = mrs.velocity(targets, sources.points, sources.forces,
                                 epsilon=sources.epsilon, mu=self.viscosity,
                                 torques=sources.torques, wall=self.wall, angular=angular,
                                 n_threads=self.n_threads, check=False)
            u, w = value if angular else (value, w)
        u[:, 0] += self.shear_rate * targets[:, 2]
        w[:, 1] += 0.5 * self.shear_rate
        return u, w

    def implicit_surfaces(self, t: float, state: np.ndarray) -> list[Any]:
        """The surfaces of the implicit bodies at ``(t, state)``, in :attr:`implicit_bodies`
        order, their loads with the repulsion's added: what the coupled solve takes."""
        blocks = self.blocks(state)
        surfaces = [dataclasses.replace(self.bodies[i].surface(t, blocks[i]), name=self.names[i])
                    for i in self.implicit_bodies]  # (named as the scene names them)
        if self.repulsion is not None:
            force, torque = repulsion_loads(surfaces, self.repulsion, self.wall)
            surfaces = [dataclasses.replace(s, force=s.force + f, torque=s.torque + q)
                        for s, f, q in zip(surfaces, force, torque, strict=True)]
        return surfaces

    def coupled(self, t: float, state: np.ndarray) -> Coupled:
        """One coupled evaluation (see the module): the explicit loads, the mobility solve of
        all implicit bodies in their background, the velocities at the explicit bodies."""
        from ..kinds.rigid.solve import mobility

        explicit = self._sources(t, state, [i for i in range(len(self.bodies))
                                            if i not in self.implicit_bodies])
        surfaces = self.implicit_surfaces(t, state)
        rigid_points = np.concatenate([s.points for s in surfaces])
        background, _ = self._flow(rigid_points, explicit, False)
        solution = mobility(surfaces, self.viscosity, self.wall, background, self.n_threads)
        rigid = FluidSources(rigid_points, solution.forces, np.zeros_like(rigid_points),
                             np.concatenate([np.full(len(s.points), s.epsilon)
                                             for s in surfaces]))
        torques = (None if explicit.torques is None or rigid.torques is None
                   else np.concatenate([explicit.torques, rigid.torques]))
        sources = FluidSources(np.concatenate([explicit.points, rigid.points]),
                               np.concatenate([explicit.forces, rigid.forces]), torques,
                               np.concatenate([explicit.epsilon, rigid.epsilon]))
        angular = any(self.bodies[i].angular for i in range(len(self.bodies))
                      if i not in self.implicit_bodies)
        u, w = self._flow(explicit.points, sources, angular)
        return Coupled(u, w, solution, surfaces, sources)

    def _coupled_rates(self, t: float, state: np.ndarray) -> np.ndarray:
        value = self.coupled(t, state)
        parts, row, k = [], 0, 0
        for i, (body, x) in enumerate(zip(self.bodies, self.blocks(state), strict=True)):
            if i in self.implicit_bodies:
                parts.append(body.motion_rates(x, value.solution.U[k], value.solution.Omega[k],
                                               value.surfaces[k].slip))
                k += 1
            else:
                n = len(x)
                parts.append(_body_rates(body, value.u[row : row + n], value.w[row : row + n]))
                row += n
        return self.stack(parts)

    # ---- coarse grid (Remark 4) -----------------------------------------------------------
    def coarsened(self, factor: int) -> tuple[Scene, SceneTransfer]:
        """The scene with every body that has a coarser grid on it (rods: σ_c = factor σ_f;
        rigid bodies: ``factor`` times fewer surface points), or the bodies ``coarse_bodies``
        names, the others kept, and the grid transfer that composes the bodies' own
        (:mod:`parastokes.scene.coarse`)."""
        return scene_coarse.coarsened(self, factor)

    # ---- parameters and monitor ----------------------------------------------------------
    @property
    def params(self) -> dict[str, float]:
        """``viscosity`` and every body's other parameters as ``"name.param"``."""
        out = {"viscosity": float(self.viscosity)}
        for name, body in zip(self.names, self.bodies, strict=True):
            out |= {f"{name}.{k}": v for k, v in body.params.items() if k != "viscosity"}
        return out

    def with_params(self, **theta: float) -> Scene:
        """A copy with some of :attr:`params` changed (``viscosity`` for every body)."""
        unknown = sorted(set(theta) - set(self.params))
        if unknown:
            raise ValueError(
                f"with_params: unknown parameter(s) {unknown}; allowed: {sorted(self.params)}"
            )
        bodies = []
        for name, body in zip(self.names, self.bodies, strict=True):
            mine = {k.split(".", 1)[1]: v for k, v in theta.items() if k.startswith(f"{name}.")}
            if "viscosity" in theta and "viscosity" in body.params:
                mine["viscosity"] = theta["viscosity"]
            bodies.append(body.with_params(**mine) if mine else body)
        viscosity = float(theta.get("viscosity", self.viscosity))
        return dataclasses.replace(self, bodies=tuple(bodies), viscosity=viscosity)

    monitor_limit = 1.0

    def monitor(self, state: np.ndarray) -> float:
        """The largest of the bodies' monitors, each over its own limit; infinite when a point
        is on or below the wall."""
        if crossed_wall(state, self.wall):
            return math.inf
        values = [body.monitor(x) / body.monitor_limit
                  for body, x in zip(self.bodies, self.blocks(state), strict=True)]
        return float(max(values)) if all(math.isfinite(v) for v in values) else math.nan


registry.register(Scene, scene_loop)
registry.register_device(Scene, "parastokes.gpu.scene:scene_parts")  # (when all bodies have some)
