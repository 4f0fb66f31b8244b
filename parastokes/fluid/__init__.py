"""The fluid as a value: what turns the point loads of the bodies into velocities.

A system's rates are the background flow plus ``fluid.velocity(points, forces, epsilon=ε,
torques=..., angular=...)`` of its loads (eq. 6; with torques the rotlets, docs/physics.md
(2)-(4); with ``wall`` the images of (5)-(8)). Two implementations compute the same numbers, bit
for bit:

- :class:`MRS`: regularized Stokeslets through :func:`parastokes.mrs.velocity`, the targets in
  tiles over ``n_threads`` numba threads (the threaded spatial parallelization of Remark 1);
- :class:`BlockedMRS`: the same sums split into contiguous blocks of targets by its
  :class:`Blocks` (:class:`parastokes.parallel.spatial.TargetBlocks`: one task per block on an
  executor, process pool or MPI ranks), the loads shipped with all sources to every block, as a
  distributed-memory code broadcasts them (the process-block spatial parallelization). The
  executor part lives above the fluid, in :mod:`parastokes.parallel.spatial`; this module imports no
  executor.

The regularization ε belongs to the body (it is a parameter Θ that extrapolation varies) and is
passed with each evaluation; the fluid holds μ, the wall and how the sums are computed.
Compiled loops of steps are registered per (system type, fluid type)
(:mod:`parastokes.registry.loops`): only the :class:`MRS` fluid has them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal, Protocol, overload

import numpy as np

from .. import mrs

__all__ = ["MRS", "BlockedMRS", "Blocks", "TargetBlocks", "block_velocity"]


@dataclass(frozen=True)
class MRS:
    """Regularized Stokeslets of viscosity μ in free space or above the wall z = 0."""

    viscosity: float
    wall: bool = False
    n_threads: int | None = None

    @overload
    def velocity(
        self,
        points: np.ndarray,
        forces: np.ndarray,
        *,
        epsilon: float,
        torques: np.ndarray | None = None,
        angular: Literal[False] = False,
    ) -> np.ndarray: ...

    @overload
    def velocity(
        self,
        points: np.ndarray,
        forces: np.ndarray,
        *,
        epsilon: float,
        torques: np.ndarray | None = None,
        angular: Literal[True],
    ) -> tuple[np.ndarray, np.ndarray]: ...

    @overload
    def velocity(
        self,
        points: np.ndarray,
        forces: np.ndarray,
        *,
        epsilon: float,
        torques: np.ndarray | None = None,
        angular: bool,
    ) -> np.ndarray | tuple[np.ndarray, np.ndarray]: ...

    def velocity(
        self,
        points: np.ndarray,
        forces: np.ndarray,
        *,
        epsilon: float,
        torques: np.ndarray | None = None,
        angular: bool = False,
    ) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        """u at ``points`` from the loads at the same points (and w with ``angular``).

        The sums run unchecked (``check=False``), so the shapes are checked here, at the cost of
        a comparison: a body's loads one row short (or transposed, or flat) would otherwise be
        read past their end (ValueError naming the argument, the shape found and expected)."""
        expected = (len(points), 3)
        if np.shape(points) != expected:
            raise ValueError(f"fluid.velocity: points of shape {np.shape(points)}; expected "
                             "(N, 3), one row per point")
        for name, value in (("forces", forces), ("torques", torques)):
            if value is not None and np.shape(value) != expected:
                raise ValueError(f"fluid.velocity: {name} of shape {np.shape(value)}; expected "
                                 f"{expected}, one row per point")
        return self._evaluate(points, forces, epsilon, torques, angular)

    def _evaluate(
        self,
        points: np.ndarray,
        forces: np.ndarray,
        epsilon: float,
        torques: np.ndarray | None,
        angular: bool,
    ) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        """:meth:`velocity`'s sums (what an implementation of the fluid overrides)."""
        return mrs.velocity(
            points,
            points,
            forces,
            epsilon=epsilon,
            mu=self.viscosity,
            torques=torques,
            wall=self.wall,
            angular=angular,
            n_threads=self.n_threads,
            check=False,
        )


def block_velocity(
    targets: np.ndarray,
    sources: np.ndarray,
    forces: np.ndarray,
    torques: np.ndarray | None,
    options: dict[str, Any],
) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Eq. 6 at one block of targets from all sources (runs on a worker, one thread)."""
    return mrs.velocity(targets, sources, forces, torques=torques, check=False, **options)


class Blocks(Protocol):
    """How a :class:`BlockedMRS` splits and runs its evaluations: ``n_blocks`` blocks of targets,
    and ``run``, the velocities of every block (in order) of ``points`` from all of them, each
    block's :func:`block_velocity` with ``options`` (ε, μ, wall, angular). Implemented by
    :class:`parastokes.parallel.spatial.TargetBlocks` (one task per block on an executor)."""

    n_blocks: int

    def run(self, points: np.ndarray, forces: np.ndarray, torques: np.ndarray | None,
            options: dict[str, Any]) -> list[Any]: ...


#: The annotation of a body's ``target_blocks`` field as bodies written for earlier releases
#: import it (``from parastokes.fluid import TargetBlocks``, docs/extending.md): the protocol, so
#: that the fluid imports nothing above it; the executor-backed implementation is
#: :class:`parastokes.parallel.spatial.TargetBlocks`.
TargetBlocks = Blocks


@dataclass(frozen=True)
class BlockedMRS(MRS):
    """:class:`MRS` with every evaluation split into blocks of targets (:class:`Blocks`, e.g.
    :class:`parastokes.parallel.spatial.TargetBlocks`); each target's sum is the same sum in the
    same order, so the velocities are the same bits."""

    blocks: Blocks | None = None

    def __post_init__(self) -> None:
        if self.blocks is None:
            raise ValueError("BlockedMRS needs blocks: give it the TargetBlocks to split into")

    def _evaluate(
        self,
        points: np.ndarray,
        forces: np.ndarray,
        epsilon: float,
        torques: np.ndarray | None,
        angular: bool,
    ) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        assert self.blocks is not None  # (__post_init__)
        options = {"epsilon": epsilon, "mu": self.viscosity, "wall": self.wall,
                   "angular": angular}
        parts = self.blocks.run(points, forces, torques, options)
        if angular:
            return (np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts]))
        return np.concatenate(parts)
