"""The resistance problem's coarse correction on the 6B rigid modes, in front of the block sweep
of :mod:`parastokes.mobility.precondition`.

The resistance problem solves M f = g (motions given; (1) of docs/physics.md, images (5) with
a wall). Its block preconditioner solves each body alone, so the collective modes (all bodies
pushing the fluid together, a row squeezing toward the wall) are left to GMRES, which in the
mobility problem the rigid unknowns take up. Here each body's six unit rigid motions give the
coarse space: Z = blockdiag(M_bb⁻¹ K_b) (3N x 6B, the force densities of each body's rigid
motions alone, from the block factorizations), tested with K (each body's total velocity
moments), coarse matrix C = Kᵀ M Z (6B x 6B). With Q = Z C⁻¹ Kᵀ and the sweep S,

    P⁻¹ r = Q r + S (r - M Q r),

so the residual left to the sweep has no rigid-mode moments on any body (Kᵀ (r - M Q r) = 0,
what the mobility problem's saddle blocks impose). M Z is formed once per solve: column
(b, j) is body b's forces alone, so the 6B columns cost six products of the whole operator
(kernels from each body's points to all points), and an application of P⁻¹ costs two dense
(3N x 6B) products on top of the sweep. P⁻¹ is linear and applied exactly, so right
preconditioning keeps GMRES's residual the true one. Measured in docs/benchmarks.md, "Rigid
bodies", (b).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from ..mrs.operator import StokesletOperator
from .precondition import BlockSweep
from .selfsolve import LabFactor, RotatedFactor
from .system import SurfaceSet
from .threads import LAPACK

#: Fewest bodies given the correction. Its setup costs about seven products of the whole
#: operator (measured, docs/benchmarks.md "Rigid bodies" (b)); rows of 2 spheres save 3-4
#: iterations with it (a loss), rows of 4 save 5-9 and rows of 8 7-14.
MIN_BODIES = 4
#: Most entries of the stored M Z (3N x 6B floats: 64 MB); larger systems (hundreds of bodies)
#: use the sweep alone.
MAX_ENTRIES = 2**23


def use_rigid_modes(sset: SurfaceSet) -> bool:
    """Whether the resistance preconditioner adds the rigid-mode correction: at least
    :data:`MIN_BODIES` bodies and M Z within :data:`MAX_ENTRIES`."""
    nb = sset.n_bodies
    return nb >= MIN_BODIES and 3 * sset.n_points * 6 * nb <= MAX_ENTRIES


class RigidModeSweep:
    """P⁻¹ of the module docstring for ``sset``: ``sweep`` (:class:`BlockSweep` over the bodies'
    ``factors``) behind the coarse correction on their rigid modes."""

    def __init__(
        self, sset: SurfaceSet, factors: list[LabFactor | RotatedFactor], sweep: BlockSweep
    ) -> None:
        self.sweep = sweep
        self.rows = [sset.rows(b) for b in range(sset.n_bodies)]
        self.motions = sset.motions
        self.minv_k = [f.minv_k for f in factors]
        nb = sset.n_bodies
        self.mz = np.empty((3 * sset.n_points, 6 * nb))
        for b, p in enumerate(sset.placed):
            op = StokesletOperator(
                sset.points, p.points, p.epsilon, sset.mu, wall=sset.wall, n_threads=sset.n_threads
            )
            for j in range(6):
                self.mz[:, 6 * b + j] = op.matvec(np.ascontiguousarray(self.minv_k[b][:, j]))
        with LAPACK:
            self._lu = sla.lu_factor(self._moments(self.mz), check_finite=False)  # C = Kᵀ M Z

    def _moments(self, rv: np.ndarray) -> np.ndarray:
        """Kᵀ rv (6B,) or (6B, k): each body's total velocity moments (of each column)."""
        return np.concatenate([k.T @ rv[r] for k, r in zip(self.motions, self.rows, strict=True)])

    def forces(self, rv: np.ndarray) -> np.ndarray:
        """P⁻¹ rv (3N,) for velocity residual ``rv``."""
        moments = self._moments(rv)
        with LAPACK:
            c = sla.lu_solve(self._lu, moments, check_finite=False)
        f = self.sweep.forces(rv - self.mz @ c)
        for b, r in enumerate(self.rows):
            f[r] += self.minv_k[b] @ c[6 * b : 6 * b + 6]
        return f
