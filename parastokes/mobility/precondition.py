"""The GMRES preconditioner: each body's own solve, swept over the bodies in order (block
Gauss–Seidel) with the flow of the near bodies already swept.

Write the Stokeslet matrix of B bodies in blocks M_ab (velocity at body a's points from the
point forces on body b; (1) of docs/physics.md, plus the images (5) with a wall). Block Jacobi
solves each body alone, f_a = M_aa⁻¹ r_a (in the mobility problem the saddle system of M_aa and
K_a, :func:`parastokes.mobility.selfsolve.saddle_solve`). Near contact, the coupling M_ab of
two close bodies is as strong as their self blocks and GMRES has to resolve it. The forward
sweep here subtracts from body a's residual the flow of the forces just found on the near bodies
swept before it,

    f_a = M_aa⁻¹ (r_a - Σ_{b < a, b near a} M_ab f_b),

so P is block lower triangular with the near couplings below the diagonal; P⁻¹ is applied
exactly (one sweep), so right preconditioning keeps GMRES's residual the true one. A pair is
near when its surfaces come within :data:`NEAR_GAP` times the smaller body's length
(:attr:`parastokes.mobility.rigid.RigidSurface.size`); each near coupling is a compiled kernel
call over the two bodies' points (:class:`parastokes.mrs.operator.StokesletOperator` with
targets), nothing assembled. Far pairs are left to GMRES: they add iterations only near contact
(docs/benchmarks.md, "Rigid bodies", (b)).

``precondition`` picks each body's own block: ``"free"`` its reused free-space body-frame
factorization (:class:`RotatedFactor`, nothing refactorized), ``"wall"`` its block with the wall
images, assembled and factorized at every solve (:class:`LabFactor`).
"""

from __future__ import annotations

import typing
from collections.abc import Callable

import numpy as np
from scipy.spatial import cKDTree

from ..mrs.operator import StokesletOperator
from .selfsolve import LabFactor, RotatedBatch, RotatedFactor, saddle_solve
from .system import SurfaceSet

#: Two bodies are coupled in the sweep when their surfaces come closer than this many times the
#: smaller body's length (rms distance of its points from its center). Measured on rows of unit
#: spheres above the wall (docs/benchmarks.md): coupling pairs at gap 0.1a saves 8-11 of 30-37
#: iterations for 8-27% more work per iteration; at 0.5a it saves 2-4 of 14-18 for as much more
#: work, a wash; at 2a nothing.
NEAR_GAP = 0.4

PRECONDITIONERS = ("free", "wall")


def block_factors(sset: SurfaceSet, precondition: str) -> list[LabFactor | RotatedFactor]:
    """Each body's self-block factorization (see the module docstring for ``precondition``)."""
    if precondition not in PRECONDITIONERS:
        raise ValueError(f"precondition: must be 'free' or 'wall', got {precondition!r}")
    out: list[LabFactor | RotatedFactor] = []
    for b, p in enumerate(sset.placed):
        if precondition == "wall" and sset.wall:
            out.append(LabFactor(p.points, p.epsilon, sset.mu, True, sset.motions[b], p.name))
        else:
            out.append(RotatedFactor(p, sset.mu))
    return out


def near_pairs(sset: SurfaceSet, gap: float | None = None) -> list[tuple[int, int]]:
    """Pairs (a, b), b < a, whose surfaces come closer than ``gap`` (default
    :data:`NEAR_GAP`) times the smaller body's length, by a then b. Only pairs whose bounding
    spheres (about the centers) come that close are looked at (a k-d tree of the centers: no
    B x B array for a suspension of thousands of bodies)."""
    gap = NEAR_GAP if gap is None else gap
    placed = sset.placed
    if gap <= 0 or len(placed) < 2:
        return []
    centers = np.array([p.center for p in placed])
    reach = np.array([np.max(np.linalg.norm(p.points - p.center, axis=1)) for p in placed])
    sizes = np.array([p.surface.size for p in placed])
    candidates = cKDTree(centers).query_pairs(
        2 * reach.max() + gap * sizes.max(), output_type="ndarray")
    trees: dict[int, cKDTree] = {}
    pairs = []
    for b, a in sorted(map(tuple, np.sort(candidates, axis=1)), key=lambda p: (p[1], p[0])):
        limit = gap * min(sizes[a], sizes[b])
        if np.linalg.norm(centers[a] - centers[b]) - reach[a] - reach[b] >= limit:
            continue
        if b not in trees:
            trees[b] = cKDTree(placed[b].points)
        dist, _ = trees[b].query(placed[a].points, k=1, distance_upper_bound=limit)
        if np.min(dist) < limit:
            pairs.append((int(a), int(b)))
    return pairs


class BlockSweep:
    """P⁻¹ of the module docstring for the bodies of ``sset``: their ``factors``
    (:func:`block_factors`) and the couplings of their :func:`near_pairs`."""

    def __init__(
        self,
        sset: SurfaceSet,
        factors: list[LabFactor | RotatedFactor],
        gap: float | None = None,
    ) -> None:
        self.factors = factors
        self.rows = [sset.rows(b) for b in range(sset.n_bodies)]
        self.n3 = 3 * sset.n_points
        #: body a -> [(b, M_ab)] for its near bodies b swept before it
        self.lower: list[list[tuple[int, StokesletOperator]]] = [[] for _ in self.rows]
        for a, b in near_pairs(sset, gap):
            pa, pb = sset.placed[a], sset.placed[b]
            op = StokesletOperator(
                pa.points, pb.points, pb.epsilon, sset.mu, wall=sset.wall, n_threads=sset.n_threads
            )
            self.lower[a].append((b, op))
        self.batches, self.alone = self._batches()

    def _batches(self) -> tuple[list[tuple[np.ndarray, np.ndarray, RotatedBatch]], list[int]]:
        """The bodies solved together (:class:`RotatedBatch`: two or more placements of one
        body-frame factorization that couple to no body before them, so their solves depend on
        nothing swept before), as (bodies, their rows (k, 3n), batch); the others, in order."""
        groups: dict[int, list[int]] = {}
        for a, factor in enumerate(self.factors):
            if isinstance(factor, RotatedFactor) and not self.lower[a]:
                groups.setdefault(id(factor.base), []).append(a)
        batches = []
        for bodies in groups.values():
            if len(bodies) > 1:
                rows = np.array([np.arange(self.rows[a].start, self.rows[a].stop)
                                 for a in bodies])
                batch = RotatedBatch([typing.cast(RotatedFactor, self.factors[a])
                                      for a in bodies])
                batches.append((np.array(bodies), rows, batch))
        together = {int(a) for bodies, _, _ in batches for a in bodies}
        return batches, [a for a in range(len(self.factors)) if a not in together]

    @property
    def n_couplings(self) -> int:
        """How many near pairs the sweep couples."""
        return sum(len(c) for c in self.lower)

    def _sweep(self, rv: np.ndarray, solve_batch: Callable[[int, np.ndarray], np.ndarray],
               solve_block: Callable[[int, np.ndarray], np.ndarray]) -> np.ndarray:
        """Forces f (3N,) of one forward sweep over velocity residual ``rv``: first the batches
        (``solve_batch(k, rows of rv)``: their forces, one row per body), then every other body
        in order (``solve_block(a, r_a)``: body a's forces for its own residual r_a, less the
        flow of the near bodies swept before it)."""
        f = np.zeros(self.n3)
        for k, (_, rows, _) in enumerate(self.batches):
            f[rows] = solve_batch(k, rv[rows])
        for a in self.alone:
            r = self.rows[a]
            ra = rv[r]
            if self.lower[a]:
                ra = ra - sum(op.matvec(f[self.rows[b]]) for b, op in self.lower[a])
            f[r] = solve_block(a, ra)
        return f

    def forces(self, rv: np.ndarray) -> np.ndarray:
        """P⁻¹ rv for the velocity rows only (the resistance problem: motions known)."""
        return self._sweep(rv, lambda k, g: self.batches[k][2].solve(g),
                           lambda a, ra: self.factors[a].solve(ra))

    def saddle(self, rv: np.ndarray, rft: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """P⁻¹ of the augmented system (the mobility problem): forces (3N,) and rigid motions
        Y (B, 6) for velocity residual ``rv`` and force/torque residual ``rft`` (B, 6)."""
        y = np.empty((len(self.factors), 6))

        def solve_batch(k: int, g: np.ndarray) -> np.ndarray:
            bodies, _, batch = self.batches[k]
            f_k, y[bodies] = batch.saddle(g, rft[bodies])
            return f_k

        def solve_block(a: int, ra: np.ndarray) -> np.ndarray:
            fa = self.factors[a]
            f_a, y[a] = saddle_solve(fa, fa.motion, ra, rft[a])
            return f_a

        return self._sweep(rv, solve_batch, solve_block), y
