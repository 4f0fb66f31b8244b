"""Variants of tests/user_beads.py::Beads with Jacobian hooks (``load_jacobian``,
``stiff_jacobian``) as a body author writes them for the linearly implicit schemes, each broken
in one way (issue 50, item 3), and one correct (``Hooked``): K = -stiffness I, the springs'."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from user_beads import Beads


@dataclass(frozen=True)
class Hooked(Beads):
    def load_jacobian(self, t, state):
        return -self.stiffness * sp.eye_array(3 * self.n_points)


@dataclass(frozen=True)
class ShapeHook(Beads):
    def load_jacobian(self, t, state):
        return np.ones((5, 5))


@dataclass(frozen=True)
class NaNHook(Beads):
    def load_jacobian(self, t, state):
        return np.full((3 * self.n_points, 3 * self.n_points), np.nan)


@dataclass(frozen=True)
class InfHook(Beads):
    def load_jacobian(self, t, state):
        return np.diag(np.full(3 * self.n_points, np.inf))


@dataclass(frozen=True)
class TextHook(Beads):
    def load_jacobian(self, t, state):
        return "dense"


@dataclass(frozen=True)
class NonSquareHook(Beads):
    def stiff_jacobian(self, t, state):
        return np.zeros((3 * self.n_points, 3 * self.n_points - 1))


@dataclass(frozen=True)
class RaisingHook(Beads):
    def load_jacobian(self, t, state):
        raise RuntimeError("the springs' table is missing")


@dataclass(frozen=True)
class NoTimeHook(Beads):
    def load_jacobian(self, state):
        return -self.stiffness * sp.eye_array(3 * self.n_points)


@dataclass(frozen=True)
class LateNaNHook(Hooked):
    """Finite at the initial state, NaN from t = 0.03 on (a blow-up there)."""

    def load_jacobian(self, t, state):
        return super().load_jacobian(t, state) * (np.nan if t > 0.025 else 1.0)


@dataclass(frozen=True)
class LateRaisingHook(Hooked):
    """Correct at the initial state, raising from t = 0.03 on (inside a worker's task)."""

    def load_jacobian(self, t, state):
        if t > 0.025:
            raise KeyError("frame")
        return super().load_jacobian(t, state)
