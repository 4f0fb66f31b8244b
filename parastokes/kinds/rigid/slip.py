"""Prescribed surface velocities relative to a body's frame (docs/bodies.md, "Swimmers").

A slip is a small frozen dataclass with ``velocity(t, points) -> (N, 3)``: the velocity of the
surface at the body-frame ``points`` relative to the body frame, in body-frame components, at
time t. The mobility solve adds it to the rigid motion U + Ω × r, so a body with a slip and no
external load swims free of force and torque.

- :class:`Squirmer`: the tangential slip of Lighthill and Blake on a sphere about the origin,
  u_s(θ) = (B1 sin θ + B2 sin θ cos θ) e_θ, θ the polar angle from the body axis e1 (Blake 1971);
  with n the unit normal and e_θ sin θ = cos θ n − e1, u_s = (B1 + B2 cos θ)(cos θ n − e1). In
  free space it swims along e1 at U = 2 B1 / 3 whatever B2 (Blake 1971).
- :class:`UserSlip`: a user's picklable ``function(t, points) -> (N, 3)``, or a
  ``"module:function"`` naming one (configs).
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...core import plugins
from ...core.contracts import StepFailure

__all__ = ["Squirmer", "UserSlip"]


@dataclass(frozen=True)
class Squirmer:
    """Blake's squirmer slip with the modes ``b1`` and ``b2`` (μm/s), axis e1."""

    b1: float = 1.0
    b2: float = 0.0

    def __post_init__(self) -> None:
        for name in ("b1", "b2"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value)):
                raise ValueError(f"{name}: must be a finite number, got {value!r}")

    def velocity(self, t: float, points: np.ndarray) -> np.ndarray:
        n = points / np.linalg.norm(points, axis=1, keepdims=True)
        cos = n[:, 0]
        tangent = cos[:, None] * n
        tangent[:, 0] -= 1.0
        return (self.b1 + self.b2 * cos)[:, None] * tangent


@dataclass(frozen=True)
class UserSlip:
    """A user's slip: ``function(t, points) -> (N, 3)``, a picklable callable (a module-level
    function) or its ``"module:function"``."""

    function: str | Callable[[float, np.ndarray], Any]

    def __post_init__(self) -> None:
        self._callable()  # import and signature errors now, not at the first step

    def _callable(self) -> Callable[[float, np.ndarray], Any]:
        if isinstance(self.function, str):
            found = plugins.import_target(self.function, self.function, ValueError)
            if not callable(found):
                raise ValueError(f"slip: {self.function!r} is not a function")
        elif callable(self.function):
            found = self.function
        else:
            raise ValueError(f"slip: need a function or \"module:function\", got "
                             f"{self.function!r}")
        try:
            signature = inspect.signature(found)
        except (TypeError, ValueError):  # a builtin without one: its call says
            return found
        try:
            signature.bind(0.0, np.zeros((1, 3)))
        except TypeError:
            raise ValueError(f"slip: {self.function!r} takes {signature}, but a slip is called "
                             "as function(t, points): write it as def slip(t, points) returning "
                             "the (N, 3) body-frame velocities") from None
        return found

    def velocity(self, t: float, points: np.ndarray) -> np.ndarray:
        """The body-frame slip at ``points``: ValueError for a result of another shape or
        type, :class:`~parastokes.core.contracts.StepFailure` (a blow-up) for a non-finite one."""
        try:
            value = np.asarray(self._callable()(t, points), dtype=float)
        except (TypeError, ValueError) as error:
            raise ValueError(f"slip: {self.function!r} must return (N, 3) numbers for the N = "
                             f"{len(points)} points ({error})") from None
        if value.shape != points.shape:
            raise ValueError(
                f"slip: {self.function!r} must return finite (N, 3) velocities for N = "
                f"{len(points)} points, got shape {value.shape}")
        if not np.isfinite(value).all():
            raise StepFailure(f"slip: {self.function!r} returned non-finite velocities at "
                              f"t = {t:.6g} ({int((~np.isfinite(value)).sum())} of "
                              f"{value.size} values)")
        return value
