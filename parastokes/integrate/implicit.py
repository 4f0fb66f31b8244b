"""The linearly implicit schemes of :mod:`parastokes.stiff` on the checked calls of a run: a
:class:`parastokes.stiff.Stepper` per run, and its failures as blow-ups."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from .. import stiff
from ..core.contracts import System
from ..stiff import Rosenbrock
from .base import BlowUpError, advance, rates

__all__ = ["checked_stepper", "implicit_stepper", "solve_blowup"]


def solve_blowup(error: stiff.StiffSolveError, step: int, x: np.ndarray) -> BlowUpError:
    """A failed stage solve, as the blow-up of a run."""
    return BlowUpError(error.t, step, math.nan, x, str(error))


def checked_stepper(system: System, scheme: Rosenbrock) -> stiff.Stepper:
    """A :class:`parastokes.stiff.Stepper` on the checked ``rates`` and ``advance``."""
    return stiff.Stepper(system, scheme, lambda t, y: rates(system, t, y),
                         lambda y, r, h: advance(system, y, r, h))


def implicit_stepper(system: System, scheme: Rosenbrock
                     ) -> Callable[[float, np.ndarray, float], np.ndarray]:
    """``step(t, x, dt)`` of a linearly implicit scheme: a :class:`parastokes.stiff.Stepper`
    (it keeps the Jacobian and its factorization across the steps of one run) on the checked
    ``rates`` and ``advance``; a failed solve is a :class:`BlowUpError`."""
    stepper = checked_stepper(system, scheme)

    def take(t: float, x: np.ndarray, dt: float) -> np.ndarray:
        try:
            return stepper.step(t, x, dt)
        except stiff.StiffSolveError as error:
            raise solve_blowup(error, stepper.steps, x) from error

    return take
