"""A user's body derived from ``PointsInShear`` as docs/extending.md shows (``Beads``: beads on a
line pulled back to their rest positions by springs, in shear flow), and broken variants of it,
each with one mistake a body author makes (issue 32: the fault table in docs/validation.md)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from parastokes.bodies.base import PointsInShear, replace_params
from parastokes.fluid import TargetBlocks


@dataclass(frozen=True)
class Beads(PointsInShear):
    """``n_points`` beads tethered by springs ``stiffness`` to their rest positions on the x axis
    at height ``height``, in the shear flow γ̇ = ``shear_rate``; free space or the wall z = 0."""

    n_points: int = 8
    stiffness: float = 2.0
    epsilon: float = 0.3
    viscosity: float = 1.0
    shear_rate: float = 1.0
    height: float = 2.0
    wall: bool = False
    n_threads: int | None = None
    target_blocks: TargetBlocks | None = field(default=None, init=False)

    def rest(self) -> np.ndarray:
        x = np.zeros((self.n_points, 3))
        x[:, 0] = np.arange(self.n_points) - (self.n_points - 1) / 2
        x[:, 2] = self.height
        return x

    def initial_state(self) -> np.ndarray:
        x = self.rest()
        x[:, 2] += 0.2 * np.sin(np.arange(self.n_points))
        return x

    def forces(self, state: np.ndarray) -> np.ndarray:
        """The springs' pull on each bead, which the bead exerts on the fluid (N, 3)."""
        return self.stiffness * (self.rest() - state)

    @property
    def params(self) -> dict[str, float]:
        return {"epsilon": self.epsilon, "viscosity": self.viscosity, "stiffness": self.stiffness}

    def with_params(self, **theta: float) -> Beads:
        return replace_params(self, theta)

    monitor_limit = 0.5

    def monitor(self, state: np.ndarray) -> float:
        return float(np.abs(state - self.rest()).max())


@dataclass(frozen=True)
class OneRowShort(Beads):
    def forces(self, state):
        return super().forces(state)[:-1]


@dataclass(frozen=True)
class Flat(Beads):
    """Forces as (3N,)."""

    def forces(self, state):
        return super().forces(state).ravel()


@dataclass(frozen=True)
class Transposed(Beads):
    """Forces as (3, N)."""

    def forces(self, state):
        return super().forces(state).T.copy()


@dataclass(frozen=True)
class NaNForces(Beads):
    def forces(self, state):
        return np.full_like(state, np.nan)


@dataclass(frozen=True)
class NoStateArgument(Beads):
    def forces(self):  # the state argument forgotten
        return np.zeros((self.n_points, 3))


@dataclass(frozen=True)
class TextForces(Beads):
    def forces(self, state):
        return np.full(state.shape, "x")


@dataclass(frozen=True)
class ShortRates(Beads):
    def rates(self, t, state):
        return super().rates(t, state)[:-1]


@dataclass(frozen=True)
class ShortAdvance(Beads):
    def advance(self, state, rates, dt):
        return (state + dt * rates)[:-1]


@dataclass(frozen=True)
class ListState(Beads):
    def initial_state(self):
        return [[0.0, 0.0]] * self.n_points


@dataclass(frozen=True)
class TextMonitor(Beads):
    def monitor(self, state):
        return "small"


@dataclass(frozen=True)
class RatesWithoutTime(Beads):
    def rates(self, state):
        return super().rates(0.0, state)


@dataclass(frozen=True)
class LateNaN(Beads):
    """Correct rates until t = 0.05, NaN from then on: a failure during a run, not at its
    start (the probe at the initial state passes)."""

    def rates(self, t, state):
        return super().rates(t, state) * (np.nan if t >= 0.05 - 1e-12 else 1.0)


