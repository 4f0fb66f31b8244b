"""A body written outside parastokes, as docs/extending.md teaches: a sedimenting cloud of
regularized Stokeslets (every point pushed down by the same force), used from a config as
``kind = "user_body:SedimentingCloud"`` and checked with ``parastokes.testing.check_system``."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from parastokes import mrs
from parastokes.registry import loops as registry


@dataclass(frozen=True)
class SedimentingCloud:
    """``n_points`` points in a ball of radius ``radius``, each pushing the fluid with the force
    (0, 0, -``weight``); free space, regularization ``epsilon``, viscosity ``viscosity``."""

    n_points: int = 40
    radius: float = 1.0
    weight: float = 1.0
    epsilon: float = 0.1
    viscosity: float = 1.0
    seed: int = 0
    n_threads: int | None = None

    def initial_state(self) -> np.ndarray:
        rng = np.random.default_rng(self.seed)
        x = rng.normal(size=(self.n_points, 3))
        x *= self.radius * rng.uniform(size=(self.n_points, 1)) ** (1 / 3)
        return x / np.linalg.norm(x, axis=1, keepdims=True).clip(min=1.0)

    def rates(self, t: float, state: np.ndarray) -> np.ndarray:
        forces = np.zeros_like(state)
        forces[:, 2] = -self.weight
        return mrs.velocity(state, state, forces, epsilon=self.epsilon, mu=self.viscosity,
                            n_threads=self.n_threads)

    def advance(self, state: np.ndarray, rates: np.ndarray, dt: float) -> np.ndarray:
        return state + dt * rates

    def project(self, state: np.ndarray) -> np.ndarray:
        return state

    def positions(self, state: np.ndarray) -> np.ndarray:
        return np.array(state)

    @property
    def params(self) -> dict[str, float]:
        return {"epsilon": self.epsilon, "viscosity": self.viscosity}

    def with_params(self, **theta: float) -> SedimentingCloud:
        unknown = set(theta) - set(self.params)
        if unknown:
            raise ValueError(f"with_params: unknown parameter(s) {sorted(unknown)}")
        return dataclasses.replace(self, **theta)

    monitor_limit = 0.5

    def monitor(self, state: np.ndarray) -> float:
        """Relative change of the cloud's radius of gyration (it spreads slowly as it falls)."""
        def gyration(x: np.ndarray) -> float:
            return float(np.sqrt(((x - x.mean(axis=0)) ** 2).sum(axis=1).mean()))

        return abs(gyration(state) / gyration(self.initial_state()) - 1.0)


# Its GPU device parts (docs/extending.md, "Running on the GPU"), imported on a GPU solve.
registry.register_device(SedimentingCloud, "user_body_device:PARTS")
