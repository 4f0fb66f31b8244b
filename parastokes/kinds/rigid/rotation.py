"""Unit quaternions for the orientation of rigid bodies (docs/bodies.md, "Rigid bodies").

A quaternion q = (w, x, y, z) with ``|q| = 1`` is the rotation R(q) taking body-frame vectors to the
lab frame. A body turning at the lab-frame angular velocity Ω for a time dt is rotated exactly
(the exponential map, Rodrigues' formula in quaternion form)::

    q(t + dt) = exp(dt Ω / 2) ⊗ q(t),  exp(v) = (cos |v|, sin |v| v / |v|),

so Ω acts from the left, in the lab frame, as a rod's w acts on its frames (docs/physics.md
(13)); the Lie bracket of two rates is then Ω1 × Ω2, as the rod's (RKMK4, parastokes.integrate).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["IDENTITY", "exp_rotate", "matrix", "multiply", "normalized", "rotation_about"]

#: The identity rotation.
IDENTITY = (1.0, 0.0, 0.0, 0.0)


def multiply(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """The Hamilton product p ⊗ q (the rotation q, then p)."""
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return np.array([
        pw * qw - px * qx - py * qy - pz * qz,
        pw * qx + px * qw + py * qz - pz * qy,
        pw * qy - px * qz + py * qw + pz * qx,
        pw * qz + px * qy - py * qx + pz * qw,
    ])


def rotation_about(axis: np.ndarray, angle: float) -> np.ndarray:
    """The unit quaternion of the rotation by ``angle`` about the (non-zero) ``axis``; NaN for a
    non-finite angle or axis (a step that blew up: the integrator reports the state)."""
    axis = np.asarray(axis, dtype=float)
    norm = math.hypot(*axis)  # (no overflow for large components, as the sum of squares has)
    if not (math.isfinite(angle) and math.isfinite(norm)):
        return np.full(4, math.nan)
    if norm == 0.0:
        return np.array(IDENTITY)
    half = 0.5 * angle
    return np.concatenate([[math.cos(half)], math.sin(half) * axis / norm])


def exp_rotate(q: np.ndarray, omega: np.ndarray, dt: float) -> np.ndarray:
    """q turned by the lab-frame angular velocity ``omega`` for ``dt``: exp(dt Ω/2) ⊗ q."""
    angle = math.hypot(*np.asarray(omega, dtype=float)) * dt
    if angle == 0.0:
        return np.array(q, dtype=float)
    return multiply(rotation_about(omega, angle), q)


def normalized(q: np.ndarray) -> np.ndarray:
    """``q / |q|`` (ValueError for a zero quaternion, which is no rotation)."""
    norm = float(np.linalg.norm(q))
    if not norm > 0.0 or not math.isfinite(norm):
        raise ValueError(f"orientation: a quaternion must be finite and non-zero, got {q!r}")
    return np.asarray(q, dtype=float) / norm


def matrix(q: np.ndarray) -> np.ndarray:
    """The rotation matrix R(q) of a unit quaternion (body frame -> lab frame), (3, 3)."""
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])
