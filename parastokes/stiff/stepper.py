"""One step of a linearly implicit scheme (:mod:`.schemes`) over the System interface, and the
error estimate of its embedded solution for adaptive steps.

A :class:`Stepper` belongs to one run: it keeps the approximate Jacobian ``A`` of
:mod:`.jacobian` and the factorization of ``I - hγA``, rebuilding ``A`` every ``refresh`` steps
(1: every step, so ``A`` follows the body as it moves and turns) and the factorization whenever
``A`` changes or the step over the factorized one leaves the scheme's ``reuse`` range. A step
depends only on its inputs and on those counts, so a run is a deterministic function of its
input (Parareal stays bit-reproducible).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from .jacobian import local_jacobian
from .schemes import Rosenbrock
from .solve import GMRES_RTOL, GMRES_RTOL_ORDER3, Factorization, StageSolver

__all__ = ["REFRESH", "AdaptiveResult", "StepSizeError", "Stepper", "adaptive_steps"]

Rates = Callable[[float, np.ndarray], np.ndarray]
Advance = Callable[[np.ndarray, np.ndarray, float], np.ndarray]


class StepSizeError(RuntimeError):
    """The adaptive steps shrank below 1e-12 of the interval at time ``t``."""

    def __init__(self, t: float, step: float) -> None:
        super().__init__(f"step size {step:.3g} too small at t={t:.10g}")
        self.t, self.step = t, step

    def __reduce__(self) -> tuple:
        return type(self), (self.t, self.step)


#: Steps between rebuilds of the approximate Jacobian (docs/benchmarks.md, "Stiff bodies").
REFRESH = 5
class Stepper:
    """Steps of ``scheme`` for ``system`` through ``rates(t, x)`` and ``advance(x, r, dt)``
    (the integrator's checked calls); ``A`` rebuilt every ``refresh`` steps (default
    :data:`REFRESH`), its factorization kept while the step over the factorized one stays
    within the scheme's ``reuse`` range.

    ``jacobians`` and ``factorizations`` count the builds of ``A`` and of its LU so far."""

    def __init__(self, system: Any, scheme: Rosenbrock, rates: Rates, advance: Advance,
                 refresh: int | None = None) -> None:
        self.system, self.scheme = system, scheme
        self.rates, self.advance = rates, advance
        self.refresh = REFRESH if refresh is None else max(1, int(refresh))
        self.steps = 0
        self._jacobian: Any = None
        self._lu: Factorization | None = None
        #: GMRES iterations so far (``ros2-krylov``).
        self.iterations = 0
        self.jacobians = 0
        self.factorizations = 0
        #: The Lie bracket of two rates of a body on rotating frames (order 3: :meth:`stages`).
        self._bracket = getattr(system, "bracket", None) if scheme.order >= 3 else None

    def _stage_solver(self, t: float, x: np.ndarray, h: float, f0: np.ndarray) -> StageSolver:
        hgamma = h * self.scheme.gamma
        if self.steps % self.refresh == 0 or self._jacobian is None:
            self._jacobian = (local_jacobian(self.system, t, x, f0.size),)
            self.jacobians += 1
            self._lu = None
        matrix = self._jacobian[0]
        low, high = self.scheme.reuse
        stale = self._lu is None or not low <= hgamma / self._lu.hgamma <= high
        if matrix is not None and matrix.nnz and stale:
            self._lu = Factorization(matrix, hgamma, t)
            self.factorizations += 1
        if self.scheme.krylov:  # the exact Jacobian's products are taken at this step's state
            return StageSolver(self._lu, hgamma, t, krylov=True,
                               rates_at=lambda y: self.rates(t, y), advance=self.advance,
                               x=x, f0=f0, rtol=GMRES_RTOL if self.scheme.order < 3
                               else GMRES_RTOL_ORDER3)
        return StageSolver(self._lu, hgamma, t)

    def stages(self, t: float, x: np.ndarray, h: float) -> list[np.ndarray]:
        """The stage rates ``k_i`` of the step of size ``h`` from ``(t, x)``."""
        s = self.scheme
        f0 = self.rates(t, x)
        solver = self._stage_solver(t, x, h, f0)
        ft = self._time_derivative(t, x, h, f0) if any(s.g) else None
        k: list[np.ndarray] = []
        for i in range(s.stages):
            if i == 0:
                r = f0
            else:
                shift = sum((a * kj for a, kj in zip(s.a[i], k, strict=False) if a != 0.0),
                            np.zeros_like(f0))
                r = self.rates(t + s.c[i] * h, self.advance(x, shift, h))
                if self._bracket is not None:  # dexp⁻¹ of the stage's rotation, to first order
                    r = r - (0.5 * h) * self._bracket(shift, r)
            for dij, kj in zip(s.d[i], k, strict=False):
                if dij != 0.0:
                    r = r + dij * kj
            if ft is not None and s.g[i] != 0.0:
                r = r + (s.g[i] * h) * ft
            k.append(solver.solve(r))
        self.iterations += solver.iterations
        self.steps += 1
        return k

    def _time_derivative(self, t: float, x: np.ndarray, h: float, f0: np.ndarray
                         ) -> np.ndarray | None:
        """f_t: the rates' derivative in time at ``x`` (a forward difference over 1e-3 h; None
        for rates that do not depend on time, e.g. a rod without a beat)."""
        delta = 1e-3 * h
        ft = (self.rates(t + delta, x) - f0) / delta
        return ft if np.any(ft) else None

    def _combine(self, weights: tuple[float, ...], k: list[np.ndarray]) -> np.ndarray:
        return sum((w * kj for w, kj in zip(weights, k, strict=True) if w != 0.0),
                   np.zeros_like(k[0]))

    def step(self, t: float, x: np.ndarray, h: float) -> np.ndarray:
        """The state at ``t + h``."""
        return self.advance(x, self._combine(self.scheme.b, self.stages(t, x, h)), h)

    def step_with_estimate(self, t: float, x: np.ndarray, h: float
                           ) -> tuple[np.ndarray, np.ndarray]:
        """The state at ``t + h`` and the embedded lower-order one (the scheme must have one)."""
        assert self.scheme.b_low is not None
        k = self.stages(t, x, h)
        return (self.advance(x, self._combine(self.scheme.b, k), h),
                self.advance(x, self._combine(self.scheme.b_low, k), h))


def error_norm(x: np.ndarray, x_new: np.ndarray, x_low: np.ndarray, rtol: float,
               atol: float) -> float:
    """The RMS over the state's entries of ``(x_new - x_low) / (atol + rtol max(|x|, |x_new|))``
    (the norm of Hairer, Nørsett & Wanner, *Solving ODEs I*, II.4; scipy's solve_ivp)."""
    scale = atol + rtol * np.maximum(np.abs(x), np.abs(x_new))
    return float(np.sqrt(np.mean(((x_new - x_low) / scale) ** 2)))


@dataclass(frozen=True)
class AdaptiveResult:
    """Steps accepted and rejected by :func:`adaptive_steps`, and the last step size tried."""

    accepted: int
    rejected: int
    last_step: float


#: Step-size controller: safety factor, smallest and largest change of a step.
SAFETY, SHRINK, GROW = 0.9, 0.2, 5.0


def adaptive_steps(stepper: Stepper, x: np.ndarray, t0: float, t1: float, h0: float,
                   rtol: float, atol: float,
                   accept: Callable[[float, np.ndarray, int], bool]
                   ) -> tuple[np.ndarray, AdaptiveResult]:
    """Steps from ``(t0, x)`` to ``t1`` whose estimated local error stays within ``rtol`` and
    ``atol`` (:func:`error_norm` <= 1), the first of size ``h0``, the next ones by the
    elementary controller ``h (SAFETY / err)^(1/2)`` (the estimate is of first order), within
    ``[SHRINK h, GROW h]``, the last one cut to end at ``t1``.

    ``accept(t, x_new, step)`` sees every step whose error is small enough; it returns False for
    a state the run cannot keep (its monitor beyond the limit: the step is halved and redone)
    and may raise to end the run. Returns the state at ``t1`` and the counts.
    """
    t, h = t0, min(h0, t1 - t0)
    accepted = rejected = 0
    while t < t1:
        last = t + h >= t1 * (1 - 1e-14) if t1 else t + h >= t1
        step = t1 - t if last else h
        x_new, x_low = stepper.step_with_estimate(t, x, step)
        err = error_norm(x, x_new, x_low, rtol, atol)
        if not np.isfinite(err):
            err = np.inf
        if err <= 1.0 and accept(t + step, x_new, accepted):
            t = t1 if last else t + step
            x = x_new
            accepted += 1
            factor = GROW if err == 0 else min(GROW, max(SHRINK, SAFETY * err ** -0.5))
        else:
            rejected += 1
            factor = SHRINK if not np.isfinite(err) else max(SHRINK, min(0.5, SAFETY * err ** -0.5))
        h = step * factor
        if h < 1e-12 * max(abs(t1 - t0), abs(t1)):
            raise StepSizeError(t, h)
    return x, AdaptiveResult(accepted, rejected, h)
