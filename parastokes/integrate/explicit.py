"""One step of an explicit Runge-Kutta tableau through ``rates`` and ``advance``, with the RKMK
commutator terms on rotating frames (the module docstring of :mod:`parastokes.integrate`)."""

from __future__ import annotations

import numpy as np

from ..core.contracts import System
from .base import advance, rates
from .schemes import Bracket, Scheme

__all__ = ["PairStepper", "combine", "explicit_step", "stage_rates"]


def combine(
    system: System,
    coefs: tuple[float, ...],
    k: list[np.ndarray],
    brackets: tuple[Bracket, ...],
    dt: float,
) -> np.ndarray:
    """sum_j coefs[j] k_j + dt * sum coefficient * bracket(k_p, k_q)."""
    terms = [(c, kj) for c, kj in zip(coefs, k, strict=False) if c != 0.0]
    if len(terms) == 1 and terms[0][0] == 1.0 and not brackets:
        return terms[0][1]
    if not terms:  # a stage row of zeros: the stage is evaluated at the step's start state
        r = np.zeros_like(k[0])
    else:
        r = terms[0][0] * terms[0][1]
    for c, kj in terms[1:]:
        r += c * kj
    bracket = getattr(system, "bracket", None)
    if bracket is not None:
        for c, p, q in brackets:
            r += (c * dt) * bracket(k[p], k[q])
    return r


def stage_rates(system: System, s: Scheme, t: float, x: np.ndarray, dt: float,
                first: np.ndarray | None = None) -> list[np.ndarray]:
    """The stage rates ``k_i`` of the step of ``s`` from ``(t, x)``; ``first``: ``k_0`` when
    already known (the last stage of the step before, for a first-same-as-last pair)."""
    k: list[np.ndarray] = [rates(system, t, x) if first is None else first]
    for i in range(1, s.stages):
        xi = advance(system, x, combine(system, s.a[i], k, s.stage_brackets[i], dt), dt)
        k.append(rates(system, t + s.c[i] * dt, xi))
    return k


def explicit_step(system: System, s: Scheme, t: float, x: np.ndarray, dt: float) -> np.ndarray:
    """One step of the tableau ``s`` from ``(t, x)`` to ``t + dt`` (no projection)."""
    k = stage_rates(system, s, t, x, dt)
    return advance(system, x, combine(system, s.b, k, s.final_brackets, dt), dt)


class PairStepper:
    """Steps of an embedded pair with their embedded solutions, for the controller of
    :mod:`.controller`; a first-same-as-last pair reuses the last stage of the step that ended
    at ``(t, x)`` (the same array) as the first stage of the step from there, and the first
    stage of a rejected step for its retry, so that only the new stages are evaluated."""

    def __init__(self, system: System, scheme: Scheme) -> None:
        assert scheme.b_low is not None
        self.system, self.scheme = system, scheme
        self.steps = 0
        #: The stage rates of the last step.
        self.k: list[np.ndarray] = []
        #: rates known at (t, state): the start of the last step tried and, for a pair that is
        #: first same as last, its end
        self._known: list[tuple[float, np.ndarray, np.ndarray]] = []

    def _first(self, t: float, x: np.ndarray) -> np.ndarray | None:
        return next((k for tk, xk, k in self._known if tk == t and xk is x), None)

    def step_with_estimate(self, t: float, x: np.ndarray, h: float
                           ) -> tuple[np.ndarray, np.ndarray]:
        """The state at ``t + h`` and the embedded lower-order one."""
        s, system = self.scheme, self.system
        assert s.b_low is not None
        k = stage_rates(system, s, t, x, h, self._first(t, x))
        x_new = advance(system, x, combine(system, s.b, k, s.final_brackets, h), h)
        x_low = advance(system, x, combine(system, s.b_low, k, s.low_brackets, h), h)
        self._known = [(t, x, k[0])] + ([(t + h, x_new, k[-1])] if s.fsal else [])
        self.k = k
        self.steps += 1
        return x_new, x_low
