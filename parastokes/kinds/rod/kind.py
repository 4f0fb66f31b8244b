"""The rod kind: Kirchhoff rod swimmers (section 5.1, Table 2, eq. 36) as a registered body.

Its config section (:class:`RodModel`), factory (:func:`.system.rod_swimmer`), output
layout (one Polyline per rod, the frames D1, D2, D3 as node vectors) and drawing (every frame in
the x-y plane, coloured by time).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, Literal

import numpy as np
from pydantic import Field

from ...registry.kinds import (
    BodyKind,
    BodyLayout,
    BodyResolution,
    BodySection,
    Positive,
    draw_over_time,
    polyline,
)
from .system import RodSystem, rod_swimmer

__all__ = ["KIND", "RodModel"]


class RodModel(BodySection):
    """Kirchhoff rods swimming above the wall z = 0 (section 5.1, Table 2, eq. 36)."""

    kind: Literal["rod"] = Field(description='"rod" for rod-like swimmers (section 5.1).')
    n_rods: int = Field(1, ge=1, description="Number of rods, side by side in y (5 in 5.1.4).")
    n_points: int = Field(
        301, ge=3, description="Nodes per rod M; the grid spacing is σ_f = length / (M - 1)."
    )
    length: Positive = Field(60.0, description="Rod length L (μm).")
    epsilon: Positive = Field(
        5.0, description="Regularization ε⁰ of the MRS, in the unit `epsilon_unit`."
    )
    epsilon_unit: Literal["absolute", "sigma_f"] = Field(
        "sigma_f", description='"sigma_f": ε⁰ = epsilon · σ_f (the paper\'s way); "absolute": μm.'
    )
    viscosity: Positive = Field(1e-6, description="Fluid viscosity μ⁰ (g μm⁻¹ s⁻¹).")
    bending: Positive = Field(
        1.0, description="Bending and twist modulus a⁰ = a1 = a2 = a3 (g μm³ s⁻²)."
    )
    shear: list[Positive] = Field(
        [0.6, 0.6, 0.6],
        min_length=3,
        max_length=3,
        description="Shear and stretch moduli [b1, b2, b3] (g μm s⁻²).",
    )
    amplitude: float = Field(1.0, allow_inf_nan=False, description="Amplitude A of eq. 36 (μm).")
    frequency: float = Field(
        40.0 * math.pi,
        allow_inf_nan=False,
        description="Frequency f of eq. 36 (rad/s; default 40π). Negative: a wave sin(ks - |f|t).",
    )
    wavelength: Positive = Field(30.0, description="Wavelength λ of eq. 36 (μm), k = 2π/λ.")
    wall: bool = Field(
        True, description="Plane wall at z = 0 (method of images); false: free space."
    )
    height: Positive = Field(10.0, description="Initial distance d of the rods from the wall (μm).")
    spacing: Positive = Field(5.0, description="Distance between neighbouring rods in y (μm).")

    @property
    def sigma(self) -> float:
        """The grid spacing σ_f = L / (M - 1)."""
        return self.length / (self.n_points - 1)

    def resolve(self) -> BodyResolution:
        epsilon = self.epsilon * (self.sigma if self.epsilon_unit == "sigma_f" else 1.0)
        theta0 = {"epsilon": epsilon, "viscosity": self.viscosity, "bending": self.bending}
        return BodyResolution(theta0, self.n_rods * self.n_points, self.sigma, "sigma_f")

    def build(self, threads: int = 1) -> RodSystem:
        return rod_swimmer(
            n_rods=self.n_rods,
            n_points=self.n_points,
            epsilon=self.resolve().theta0["epsilon"],
            length=self.length,
            amplitude=self.amplitude,
            frequency=self.frequency,
            wavelength=self.wavelength,
            bending=self.bending,
            shear=tuple(self.shear),
            viscosity=self.viscosity,
            wall=self.wall,
            height=self.height,
            spacing=self.spacing,
            n_threads=threads,
        )

    def coarse_points(self, factor: int) -> int:
        """Rows on the grid σ_c = factor σ_f (Remark 4), as :meth:`RodSystem.coarsened` has."""
        segments = self.n_points - 1
        if segments % factor or segments // factor < 2:
            raise ValueError(f"must divide n_points - 1 = {segments} and leave at least 3 nodes")
        return self.n_rods * (segments // factor + 1)


def layout(
    section: RodModel, system: RodSystem, frames: bool, tracked: Sequence[int] | None
) -> list[BodyLayout]:
    """One Polyline per rod; the frames D1, D2, D3 (state columns 3-11) when ``frames``."""
    m = section.n_points
    segments = polyline(m)
    vectors = {f"D{i + 1}": slice(3 + 3 * i, 6 + 3 * i) for i in range(3)} if frames else {}
    return [
        BodyLayout(f"rod_{i}", "rod", i * m, m, "Polyline", segments, vectors)
        for i in range(section.n_rods)
    ]


def draw(fig: Any, bodies: Mapping[str, Mapping[str, np.ndarray]], times: np.ndarray,
         run: str) -> None:
    """Every frame of every rod in the x-y and x-z planes (z: the distance to the wall),
    coloured by time, each title stating how much its vertical axis is stretched."""
    fig.set_size_inches(7, 5.5)
    planes = ((0, 1, "y (μm)"), (0, 2, "z (distance to the wall, μm)"))
    draw_over_time(fig, bodies, times, planes, run, lw=1)


def example() -> tuple[RodSystem, np.ndarray, float | None]:
    """Two short swimmers side by side above the wall (travelling wave of eq. 36), at rest."""
    system = rod_swimmer(2, 31, 1.0, length=6.0, wavelength=3.0)
    return system, system.initial_state(), None


KIND = BodyKind("rod", RodModel, layout, draw, example=example)
