"""One step of a linearly implicit scheme (:mod:`.schemes`) over the System interface, and the
step with its embedded solution (:meth:`Stepper.step_with_estimate`), which the step-size
controller of :mod:`parastokes.integrate.controller` calls for adaptive steps.

A :class:`Stepper` belongs to one run: it keeps the approximate Jacobian ``A`` of
:mod:`.jacobian` and the factorization of ``I - hγA``, rebuilding ``A`` every ``refresh`` steps
(1: every step, so ``A`` follows the body as it moves and turns) and the factorization whenever
``A`` changes or the step over the factorized one leaves the scheme's ``reuse`` range. The time
column f_t of the stages is a forward difference at every step, or, for a scheme that says
``hold_time_derivative``, taken with ``A`` and held with it (the W-matrix of the autonomous form
``(x, t)' = (rates, 1)`` is then ``[[A, f_t], [0, 0]]`` taken at one point; a W-method keeps its
order for any such matrix). A step depends only on its inputs and on those counts, so a run is a
deterministic function of its input (Parareal stays bit-reproducible).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from .jacobian import local_jacobian
from .schemes import Rosenbrock
from .solve import GMRES_RTOL, GMRES_RTOL_ORDER3, Factorization, StageSolver

__all__ = ["REFRESH", "Stepper"]

Rates = Callable[[float, np.ndarray], np.ndarray]
Advance = Callable[[np.ndarray, np.ndarray, float], np.ndarray]


#: Steps between rebuilds of the approximate Jacobian (docs/benchmarks.md, "Stiff bodies").
REFRESH = 5


class Stepper:
    """Steps of ``scheme`` for ``system`` through ``rates(t, x)`` and ``advance(x, r, dt)``
    (the integrator's checked calls); ``A`` rebuilt every ``refresh`` steps (default: the
    scheme's own ``refresh``, else :data:`REFRESH`), its factorization kept while the step over
    the factorized one stays within the scheme's ``reuse`` range.

    ``jacobians`` and ``factorizations`` count the builds of ``A`` and of its LU so far."""

    def __init__(self, system: Any, scheme: Rosenbrock, rates: Rates, advance: Advance,
                 refresh: int | None = None) -> None:
        self.system, self.scheme = system, scheme
        self.rates, self.advance = rates, advance
        every = refresh if refresh is not None else scheme.refresh
        self.refresh = REFRESH if every is None else max(1, int(every))
        self.steps = 0
        self._jacobian: Any = None
        self._lu: Factorization | None = None
        #: f_t of the last step that took one (held with ``A`` by ``hold_time_derivative``).
        self._ft: np.ndarray | None = None
        #: GMRES iterations so far (``ros2-krylov``).
        self.iterations = 0
        self.jacobians = 0
        self.factorizations = 0
        #: The Lie bracket of two rates of a body on rotating frames (order 3: :meth:`stages`).
        self._bracket = getattr(system, "bracket", None) if scheme.order >= 3 else None

    @property
    def banded(self) -> bool | None:
        """Whether the last factorization is LAPACK's banded LU (None before any)."""
        return None if self._lu is None else self._lu.banded

    def _stage_solver(self, t: float, x: np.ndarray, h: float, f0: np.ndarray, fresh: bool
                      ) -> StageSolver:
        hgamma = h * self.scheme.gamma
        if fresh:
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
        fresh = self.steps % self.refresh == 0 or self._jacobian is None
        solver = self._stage_solver(t, x, h, f0, fresh)
        if any(s.g) and (fresh or not s.hold_time_derivative):
            self._ft = self._time_derivative(t, x, h, f0)
        ft = self._ft if any(s.g) else None
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

