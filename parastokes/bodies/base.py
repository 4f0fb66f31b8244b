"""What every system built on the MRS fluid shares (docs/contracts.md; docs/extending.md).

- :class:`FluidBody`: the ``fluid`` value of a body from its ``viscosity``, ``wall``, ``n_threads``
  and ``target_blocks`` (:mod:`parastokes.fluid`), and its compiled loop if its type has one;
- :class:`PointsInShear`: points moved by the fluid under the forces they exert, in the shear flow
  u∞ = (γ̇ z, 0, 0) (docs/physics.md (15)): the base of the vesicle, the chain and users' point
  bodies;
- :func:`replace_params`: ``with_params`` for a frozen dataclass system;
- :func:`require_positive`: the input check of a system's positive scalars.
"""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING, Any, ClassVar, Protocol, TypeVar

import numpy as np

from ..fluid import MRS, BlockedMRS, Blocks
from ..registry import loops as registry
from ..registry.loops import RunSteps
from . import contract

__all__ = ["FluidBody", "PointsInShear", "replace_params", "require_positive"]


def require_positive(**values: float) -> None:
    """ValueError naming the first of ``values`` that is not a finite number > 0."""
    for name, value in values.items():
        if not (isinstance(value, int | float | np.number) and math.isfinite(value) and value > 0):
            raise ValueError(f"{name}: must be a finite number > 0, got {value!r}")


class FluidBody:
    """A body whose point loads act on the MRS fluid of its ``viscosity``, ``wall`` (if it has
    one), ``n_threads`` and ``target_blocks`` (:mod:`parastokes.fluid`)."""

    # Provided by the class this is mixed into (annotations only: no fields, no defaults).
    viscosity: float
    n_threads: int | None
    target_blocks: Blocks | None

    @property
    def fluid(self) -> MRS:
        """:class:`~parastokes.fluid.MRS`, or :class:`~parastokes.fluid.BlockedMRS` with
        ``target_blocks`` (the spatially parallel fine solver of Remark 1)."""
        wall = bool(getattr(self, "wall", False))
        if self.target_blocks is None:
            return MRS(self.viscosity, wall, self.n_threads)
        return BlockedMRS(self.viscosity, wall, self.n_threads, self.target_blocks)

    @property
    def run_steps(self) -> RunSteps | None:
        """The compiled loop of :mod:`parastokes.stepping` registered for this exact type and
        fluid (None otherwise, e.g. for a subclass: it may compute other rates; see
        :mod:`parastokes.registry.loops`)."""
        return registry.compiled_loop(self)


class PointsInShear(FluidBody):
    """Points that move with the fluid under the forces ``forces(state)`` they exert (no frames,
    no torques), in the background shear u∞ = (γ̇ z, 0, 0), γ̇ = ``shear_rate``
    (docs/physics.md (15)). The state is the positions, ``project`` the identity."""

    #: Rates are velocities only (no angular part); for :class:`parastokes.scene.Scene`.
    angular: ClassVar[bool] = False

    # Provided by the class this is mixed into (annotations only: no fields, no defaults).
    epsilon: float
    shear_rate: float

    if TYPE_CHECKING:

        def forces(self, state: np.ndarray) -> np.ndarray:
            """The point forces the points exert on the fluid, (N, 3)."""
            ...

    def checked_forces(self, state: np.ndarray) -> np.ndarray:
        """``forces(state)`` as float64 (N, 3), checked where it enters the package: its shape
        and dtype (:func:`parastokes.bodies.contract.array`; the fluid's sums do not check), a
        :class:`~parastokes.bodies.contract.BodyError` naming ``Type.forces`` otherwise."""
        return contract.array(self, "forces(state)", self.forces(state),
                              shape=(len(state), 3), what="one row per point")

    def loads(self, t: float, state: np.ndarray) -> tuple[np.ndarray, None]:
        """The point forces on the fluid, no torques."""
        return self.checked_forces(state), None

    @staticmethod
    def body_rates(u: np.ndarray, w: np.ndarray) -> np.ndarray:
        """The rates from the fluid velocity at the points (background included): ``u``."""
        return u

    def rates(self, t: float, state: np.ndarray) -> np.ndarray:
        """u∞(X) + Stokeslet velocities (eq. 6) of the forces."""
        u = self.fluid.velocity(state, self.checked_forces(state), epsilon=self.epsilon)
        u[:, 0] += self.shear_rate * state[:, 2]
        return u

    def advance(self, state: np.ndarray, rates: np.ndarray, dt: float) -> np.ndarray:
        return state + dt * rates

    def project(self, state: np.ndarray) -> np.ndarray:
        """The identity (no frames); returns ``state`` itself."""
        return state

    def positions(self, state: np.ndarray) -> np.ndarray:
        return np.array(state)


class DataclassSystem(Protocol):
    """A system that is a dataclass instance (what :func:`replace_params` needs)."""

    __dataclass_fields__: ClassVar[dict[str, dataclasses.Field[Any]]]

    @property
    def params(self) -> dict[str, float]: ...


_D = TypeVar("_D", bound=DataclassSystem)


def replace_params(system: _D, theta: dict[str, float]) -> _D:
    """``dataclasses.replace`` restricted to the names of ``system.params``."""
    unknown = sorted(set(theta) - set(system.params))
    if unknown:
        raise ValueError(
            f"with_params: unknown parameter(s) {unknown}; allowed: {sorted(system.params)}"
        )
    return dataclasses.replace(system, **{k: float(v) for k, v in theta.items()})
