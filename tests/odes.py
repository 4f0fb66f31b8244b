"""Toy problems with known solutions for the Parareal tests.

Everything here is a small picklable class (no lambdas, no closures), so it can travel to executors.
"""

from __future__ import annotations

import os
import pathlib
import time
from concurrent.futures import Future

import numpy as np
from scipy.linalg import expm


class LinearODE:
    """dx/dt = A x with exact solution x(t1) = exp(A (t1 - t0)) x(t0)."""

    def __init__(self, matrix) -> None:
        self.matrix = np.asarray(matrix, dtype=float)

    def rhs(self, t: float, x: np.ndarray) -> np.ndarray:
        return self.matrix @ x

    def exact(self, t0: float, t1: float, x: np.ndarray) -> np.ndarray:
        return expm(self.matrix * (t1 - t0)) @ x


def decay(rate: float = 1.0, dim: int = 1) -> LinearODE:
    """dx/dt = -rate x: contracting."""
    return LinearODE(-rate * np.eye(dim))


def oscillator(omega: float = 2.0) -> LinearODE:
    """The harmonic oscillator x'' = -omega^2 x as a rotation in the (x, x'/omega) plane."""
    return LinearODE([[0.0, omega], [-omega, 0.0]])


class Logistic:
    """dx/dt = rate x (1 - x) with its closed-form solution."""

    def __init__(self, rate: float = 3.0) -> None:
        self.rate = rate

    def rhs(self, t: float, x: np.ndarray) -> np.ndarray:
        return self.rate * x * (1.0 - x)

    def exact(self, t0: float, t1: float, x: np.ndarray) -> np.ndarray:
        grow = np.exp(self.rate * (t1 - t0))
        return x * grow / (1.0 - x + x * grow)


class Stepper:
    """Fixed-step forward Euler (order 1) or classical RK4 (order 4) on ``problem.rhs``."""

    def __init__(self, problem, dt: float, order: int) -> None:
        self.problem, self.dt, self.order = problem, dt, order

    def __call__(self, t_start: float, t_end: float, x: np.ndarray) -> np.ndarray:
        n = max(1, round((t_end - t_start) / self.dt))
        h = (t_end - t_start) / n
        f = self.problem.rhs
        x = np.array(x, dtype=float)
        for i in range(n):
            t = t_start + i * h
            if self.order == 1:
                x = x + h * f(t, x)
            else:
                k1 = f(t, x)
                k2 = f(t + h / 2, x + h / 2 * k1)
                k3 = f(t + h / 2, x + h / 2 * k2)
                k4 = f(t + h, x + h * k3)
                x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        return x


class Exact:
    """The exact propagator of ``problem``."""

    def __init__(self, problem) -> None:
        self.problem = problem

    def __call__(self, t_start: float, t_end: float, x: np.ndarray) -> np.ndarray:
        return self.problem.exact(t_start, t_end, x)


class Recording:
    """Wraps a propagator and records every call (t_start, t_end)."""

    def __init__(self, propagator) -> None:
        self.propagator = propagator
        self.calls: list[tuple[float, float]] = []

    def __call__(self, t_start: float, t_end: float, x: np.ndarray) -> np.ndarray:
        self.calls.append((t_start, t_end))
        return self.propagator(t_start, t_end, x)


class ToySystem:
    """A System of docs/contracts.md: points x_i in R^3 with u = -decay x + (a^2 + b t + c).

    With ``decay = 0`` every forward Euler / RK solution is a polynomial in (a, b, c) of degree
    (2, 1, 1), so Lagrange extrapolation with (3, 2, 2) nodes reproduces it exactly; with
    ``a = b = c = 0`` it is exponential decay with exact solution x exp(-decay t).
    ``with_params_calls`` counts copies made by ``with_params`` (to check that validation comes
    first).
    """

    monitor_limit = 1.0
    with_params_calls = 0

    def __init__(
        self, n_points: int = 5, decay: float = 0.0, a: float = 0.0, b: float = 0.0, c: float = 0.0
    ) -> None:
        self.n_points = n_points
        self.params = {"decay": decay, "a": a, "b": b, "c": c}

    def initial_state(self) -> np.ndarray:
        s = np.linspace(0.0, 1.0, self.n_points)
        return np.stack([1.0 + s, 2.0 - s, 0.5 + 3.0 * s], axis=1)

    def rates(self, t: float, state: np.ndarray) -> np.ndarray:
        p = self.params
        return -p["decay"] * state + (p["a"] ** 2 + p["b"] * t + p["c"])

    def advance(self, state: np.ndarray, rates: np.ndarray, dt: float) -> np.ndarray:
        return state + dt * rates

    def project(self, state: np.ndarray) -> np.ndarray:
        return state

    def positions(self, state: np.ndarray) -> np.ndarray:
        return state

    def monitor(self, state: np.ndarray) -> float:
        return 0.0

    def with_params(self, **theta: float) -> ToySystem:
        unknown = set(theta) - set(self.params)
        if unknown:
            raise ValueError(f"unknown parameters {sorted(unknown)}")
        ToySystem.with_params_calls += 1
        return ToySystem(self.n_points, **{**self.params, **theta})

    def coarsened(self, factor: int) -> tuple[ToySystem, EveryOther]:
        transfer = EveryOther(self.n_points, factor)
        return ToySystem(transfer.n_coarse, **self.params), transfer


class EveryOther:
    """Toy grid transfer: keep every ``factor``-th point; prolong by linear interpolation."""

    def __init__(self, n_fine: int, factor: int) -> None:
        if (n_fine - 1) % factor:
            raise ValueError("factor must divide n_fine - 1")
        self.n_fine, self.factor = n_fine, factor
        self.n_coarse = (n_fine - 1) // factor + 1

    def restrict(self, x_fine: np.ndarray) -> np.ndarray:
        return x_fine[:: self.factor].copy()

    def prolong(self, x_coarse: np.ndarray) -> np.ndarray:
        fine = np.arange(self.n_fine)
        coarse = fine[:: self.factor]
        return np.stack([np.interp(fine, coarse, col) for col in x_coarse.T], axis=1)


class FailsOnSlice:
    """Wraps a propagator; fails on its ``call``-th solve of the slice that starts at ``t_start``.

    ``mode`` is ``"raise"`` (RuntimeError), ``"interrupt"`` (KeyboardInterrupt, as Ctrl-C would) or
    ``"exit"`` (the process dies with ``os._exit(3)``). Calls are counted by marker files in
    ``marker_dir``, so the count is shared by worker processes: in Parareal iteration k the slices
    n >= k are solved, so the slice n (n >= 2) is solved for the k-th time in iteration k.
    """

    def __init__(
        self, propagator, t_start: float, call: int, marker_dir, mode: str = "raise"
    ) -> None:
        self.propagator, self.t_start, self.call = propagator, t_start, call
        self.marker_dir, self.mode = str(marker_dir), mode

    def __call__(self, t_start: float, t_end: float, x: np.ndarray) -> np.ndarray:
        if t_start == self.t_start:
            markers = pathlib.Path(self.marker_dir)
            count = len(list(markers.iterdir())) + 1
            (markers / f"call-{count}").touch()
            if count == self.call:
                if self.mode == "exit":
                    os._exit(3)
                if self.mode == "interrupt":
                    raise KeyboardInterrupt
                raise RuntimeError(f"injected fault at t={t_start}")
        return self.propagator(t_start, t_end, x)


class Sleeping:
    """Wraps a propagator and sleeps ``seconds`` before each call (a slow task of known length)."""

    def __init__(self, propagator, seconds: float) -> None:
        self.propagator, self.seconds = propagator, seconds

    def __call__(self, t_start: float, t_end: float, x: np.ndarray) -> np.ndarray:
        time.sleep(self.seconds)
        return self.propagator(t_start, t_end, x)


class FaultyToySystem(ToySystem):
    """A :class:`ToySystem` whose rates raise RuntimeError when ``a == fail_a`` and
    ``t >= fail_after`` (an auxiliary coarse solver that fails on a chosen slice)."""

    def __init__(self, fail_a: float, fail_after: float, **params: float) -> None:
        super().__init__(**params)
        self.fail_a, self.fail_after = fail_a, fail_after

    def rates(self, t: float, state: np.ndarray) -> np.ndarray:
        if self.params["a"] == self.fail_a and t >= self.fail_after:
            raise RuntimeError(f"injected fault at t={t:.3g}")
        return super().rates(t, state)

    def with_params(self, **theta: float) -> FaultyToySystem:
        unknown = set(theta) - set(self.params)
        if unknown:
            raise ValueError(f"unknown parameters {sorted(unknown)}")
        return FaultyToySystem(
            self.fail_a, self.fail_after, n_points=self.n_points, **{**self.params, **theta}
        )


class CompilesInWorker:
    """A warm-up that imports numba when it is unpickled (as a warm-up holding a system does,
    before the worker sets its thread limits) and compiles a fresh numba function when called."""

    def __reduce__(self):
        return (_compiles_in_worker, ())

    def __call__(self) -> int:
        import numba

        return numba.njit(lambda x: x + 1)(1)


def _compiles_in_worker() -> CompilesInWorker:
    import numba  # noqa: F401  (loaded at unpickling time, on purpose)

    return CompilesInWorker()


class RecordingExecutor:
    """An in-process executor that runs each submission at once and records what it was given."""

    workers = 1

    def __init__(self) -> None:
        self.submitted = []

    def submit(self, fn, *args):
        self.submitted.append(fn)
        future = Future()
        future.set_result(fn(*args))
        return future
