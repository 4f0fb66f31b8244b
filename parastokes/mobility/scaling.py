"""The dimensionless form of the augmented system (docs/design.md, "Rigid bodies").

Unknowns x = (f, U, Ω) and equations (velocity; force, torque balance) carry different units.
With μ and a body length L, x̃ = (f/(μL), U, ΩL) and the rows (velocity, F/(μL), T/(μL²)) make
every entry a velocity and keep the matrix symmetric; residuals and GMRES tolerances are
measured in this form.
"""

from __future__ import annotations

import numpy as np


class Scaling:
    """x <-> x̃ and (g, ft) <-> b̃ for a set of B bodies with viscosity ``mu`` and length
    ``length``; rigid unknowns Y and loads ft are (B, 6) arrays: (U, Ω) and (F, T)."""

    def __init__(self, mu: float, length: float) -> None:
        self.force = mu * length
        self.length = length

    def y_scaled(self, y: np.ndarray) -> np.ndarray:
        return np.concatenate([y[:, :3], y[:, 3:] * self.length], axis=1)

    def y_unscaled(self, ys: np.ndarray) -> np.ndarray:
        return np.concatenate([ys[:, :3], ys[:, 3:] / self.length], axis=1)

    def ft_scaled(self, ft: np.ndarray) -> np.ndarray:
        return np.concatenate(
            [ft[:, :3] / self.force, ft[:, 3:] / (self.force * self.length)], axis=1
        )

    def ft_unscaled(self, fts: np.ndarray) -> np.ndarray:
        return np.concatenate(
            [fts[:, :3] * self.force, fts[:, 3:] * self.force * self.length], axis=1
        )


def relative_residual(
    r_v: np.ndarray, r_ft: np.ndarray, g: np.ndarray, ft: np.ndarray, scaling: Scaling
) -> float:
    """||r̃|| / ||b̃|| of the scaled system for velocity residual ``r_v`` (3N,), balance residual
    ``r_ft`` (B, 6) and right-hand side ``g`` (3N,), ``ft`` (B, 6); 0 for a zero right side."""
    num = np.hypot(np.linalg.norm(r_v), np.linalg.norm(scaling.ft_scaled(r_ft)))
    den = np.hypot(np.linalg.norm(g), np.linalg.norm(scaling.ft_scaled(ft)))
    return float(num / den) if den > 0 else float(num)
