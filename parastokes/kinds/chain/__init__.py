"""The bead-spring chain: a polymer of beads joined by Hookean springs with a bending penalty.

This body is written only through the public extension path (docs/extending.md): this package and
its one line in :data:`parastokes.registry.kinds.BUILTIN`; nothing else in the package names it.
Its mechanics are compiled functions (:mod:`.mechanics`), its compiled parts for the loops of
steps (alone and in scenes) are in :mod:`.stepping`, its GPU device parts in :mod:`.device`, both
registered at the end of this module.

Mechanics (forces only; docs/bodies.md). Beads X_0..X_{N-1}, bonds t_i = X_{i+1} - X_i with rest
length b, unit tangents t̂_i. The elastic energy is::

    E = (k/2) Σ_i (|t_i| - b)²  +  (κ/b) Σ_{i=1}^{N-2} (1 - t̂_{i-1}·t̂_i),

and the force each bead exerts on the fluid is F_i = -∂E/∂X_i plus an optional uniform external
load (e.g. its weight). The beads move with the fluid: u(X_i) = u∞(X_i) + Σ_j S_ε(X_i, X_j) F_j,
the regularized Stokeslets of eq. 6 (free space, or above the plane wall z = 0 with images), with
the background shear u∞ = (γ̇ z, 0, 0) as for the vesicle (docs/physics.md (15)). Θ = (ε, μ, k, κ).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import Field

from ...bodies.base import PointsInShear, replace_params
from ...bodies.geometry import crossed_wall
from ...fluid import MRS, Blocks
from ...integrate.loop import register_parts
from ...mrs.velocity import thread_count
from ...registry.kinds import (
    BodyKind,
    BodyLayout,
    BodyResolution,
    BodySection,
    Positive,
    draw_over_time,
    polyline,
)
from ...registry.loops import register_device
from ...stiff.coloring import banded
from .mechanics import bond_strain, chain_energy, chain_forces
from .stepping import chain_data

__all__ = ["KIND", "ChainModel", "ChainSystem", "chain_energy", "chain_forces"]


def straight_chain(n_beads: int, bond: float, stretch: float, tilt: float,
                   height: float) -> np.ndarray:
    """``n_beads`` beads ``stretch`` · ``bond`` apart along (cos tilt, 0, sin tilt), centred at
    (0, 0, ``height``): the chain's initial state (N, 3)."""
    s = (np.arange(n_beads) - (n_beads - 1) / 2) * bond * stretch
    direction = np.array([math.cos(tilt), 0.0, math.sin(tilt)])
    return s[:, None] * direction + np.array([0.0, 0.0, height])


def require_above_wall(beads: np.ndarray, wall: bool) -> None:
    """ValueError naming ``height`` when ``wall`` and a bead of the start ``beads`` is on or
    below the wall z = 0: the one rule of the config (:meth:`ChainModel.resolve`, so that
    ``parastokes check`` refuses what a run refuses) and of :class:`ChainSystem`."""
    low = float(beads[:, 2].min())
    if wall and low <= 0:
        height = float(beads[:, 2].mean())
        raise ValueError(
            f"height: the chain must start above the wall z = 0 (wall = true), but its lowest "
            f"bead is at z = {low:.6g}; raise height above {height - low:.6g} (now {height:.6g})"
        )


def _positive(**values: float) -> None:
    for name, value in values.items():
        if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
            raise ValueError(f"{name}: must be a finite number > 0, got {value!r}")


@dataclass(frozen=True)
class ChainSystem(PointsInShear):
    """A chain of ``n_beads`` beads, initially straight with bonds ``stretch`` · ``bond`` along
    (cos tilt, 0, sin tilt), centred at (0, 0, ``height``); springs ``stiffness`` k, bending
    ``bending`` κ, regularization ``epsilon`` (absolute), viscosity μ, shear rate γ̇, a uniform
    external ``load`` on every bead, free space or the wall z = 0. State rows: positions."""

    n_beads: int = 32
    bond: float = 1.0
    stiffness: float = 100.0
    bending: float = 10.0
    epsilon: float = 0.25
    viscosity: float = 1.0
    shear_rate: float = 0.0
    load: tuple[float, float, float] = (0.0, 0.0, 0.0)
    wall: bool = False
    height: float = 0.0
    stretch: float = 1.0
    tilt: float = 0.0
    n_threads: int | None = None
    target_blocks: Blocks | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.n_beads, int) or self.n_beads < 2:
            raise ValueError(f"n_beads: must be an integer >= 2, got {self.n_beads!r}")
        _positive(bond=self.bond, stiffness=self.stiffness, epsilon=self.epsilon,
                  viscosity=self.viscosity, stretch=self.stretch)
        if not (math.isfinite(self.bending) and self.bending >= 0):
            raise ValueError(f"bending: must be a finite number >= 0, got {self.bending!r}")
        if len(self.load) != 3:
            raise ValueError(f"load: need three components, got {self.load!r}")
        require_above_wall(self.initial_state(), self.wall)
        thread_count(self.n_threads)  # ValueError now, not at the first step

    def initial_state(self) -> np.ndarray:
        return straight_chain(self.n_beads, self.bond, self.stretch, self.tilt, self.height)

    def forces(self, state: np.ndarray) -> np.ndarray:
        """Elastic forces plus the external load, on the fluid (N, 3)."""
        f = chain_forces(state, self.bond, self.stiffness, self.bending)
        return f + np.asarray(self.load, dtype=float)

    def load_coupling(self):
        """A bead's force depends on the beads within two bonds (its springs and the bending
        of its own and its neighbours' angles): the pattern of :mod:`parastokes.stiff`'s
        coloured finite-difference Jacobian."""
        return banded(1, self.n_beads, 2)

    @property
    def params(self) -> dict[str, float]:
        return {"epsilon": self.epsilon, "viscosity": self.viscosity,
                "stiffness": self.stiffness, "bending": self.bending}

    def with_params(self, **theta: float) -> ChainSystem:
        """A copy with some of ``epsilon``, ``viscosity``, ``stiffness`` (k), ``bending`` (κ)."""
        return replace_params(self, theta)

    @property
    def monitor_limit(self) -> float:
        return 0.5

    def monitor(self, state: np.ndarray) -> float:
        """The largest relative deviation of a bond length from the rest length b; infinite
        when a bead is on or below the wall."""
        if crossed_wall(state, self.wall):
            return math.inf
        return float(bond_strain(state, self.bond))


class ChainModel(BodySection):
    """A bead-spring chain (a polymer): Hookean springs, a bending penalty, optional shear flow,
    external load and wall (docs/bodies.md)."""

    kind: Literal["chain"] = Field(description='"chain" for the bead-spring chain.')
    n_beads: int = Field(32, ge=2, description="Number of beads N.")
    bond: Positive = Field(1.0, description="Rest length b of a bond (μm).")
    stiffness: Positive = Field(100.0, description="Spring constant k (g s⁻²).")
    bending: float = Field(10.0, ge=0, allow_inf_nan=False,
                           description="Bending modulus κ (g μm² s⁻²); energy κ/b Σ (1 - cos θ).")
    epsilon: Positive = Field(0.25, description="Regularization ε⁰, in the unit `epsilon_unit`.")
    epsilon_unit: Literal["absolute", "bond"] = Field(
        "bond", description='"bond": ε⁰ = epsilon · b; "absolute": μm.'
    )
    viscosity: Positive = Field(1.0, description="Fluid viscosity μ⁰ (g μm⁻¹ s⁻¹).")
    shear_rate: float = Field(0.0, allow_inf_nan=False, description="Shear rate γ̇ of u∞ (1/s).")
    load: list[Annotated[float, Field(allow_inf_nan=False)]] = Field(
        [0.0, 0.0, 0.0], min_length=3, max_length=3,
        description="External force on every bead [Fx, Fy, Fz] (g μm s⁻²).",
    )
    wall: bool = Field(False, description="Plane wall at z = 0 (method of images).")
    height: float = Field(0.0, allow_inf_nan=False, description="Initial z of the centre (μm).")
    stretch: Positive = Field(1.0, description="Initial bond length over b.")
    tilt: float = Field(0.0, allow_inf_nan=False,
                        description="Initial angle of the chain from the x axis in the x-z plane "
                        "(radians).")

    def resolve(self) -> BodyResolution:
        require_above_wall(
            straight_chain(self.n_beads, self.bond, self.stretch, self.tilt, self.height),
            self.wall,
        )
        epsilon = self.epsilon * (self.bond if self.epsilon_unit == "bond" else 1.0)
        theta0 = {"epsilon": epsilon, "viscosity": self.viscosity, "stiffness": self.stiffness,
                  "bending": self.bending}
        return BodyResolution(theta0, self.n_beads, self.bond, "bond")

    def build(self, threads: int = 1) -> ChainSystem:
        values = self.model_dump(exclude={"kind", "epsilon_unit"})
        values["epsilon"] = self.resolve().theta0["epsilon"]
        values["load"] = tuple(values["load"])
        return ChainSystem(**values, n_threads=threads)


def layout(section: ChainModel, system: ChainSystem, frames: bool,
           tracked: Sequence[int] | None) -> list[BodyLayout]:
    """One Polyline through the beads."""
    n = system.n_beads
    return [BodyLayout("chain_0", "chain", 0, n, "Polyline", polyline(n))]


def draw(fig: Any, bodies: Mapping[str, Mapping[str, np.ndarray]], times: np.ndarray,
         run: str) -> None:
    """Every frame of every chain in the x-z plane (the plane of the shear flow), by time."""
    fig.set_size_inches(6, 4.5)
    draw_over_time(fig, bodies, times, ((0, 2, "z (μm)"),), run, equal=True, marker="o", lw=1,
                   ms=2)


def example() -> tuple[ChainSystem, np.ndarray, float | None]:
    """A 12-bead chain, bent and stretched, in shear flow: springs, bending and flow all act."""
    system = ChainSystem(n_beads=12, stiffness=20.0, bending=2.0, shear_rate=1.0)
    x = system.initial_state()
    x[:, 2] += 0.3 * np.sin(np.linspace(0.0, np.pi, len(x)))
    x[:, 0] *= 1.05
    return system, x, 0.05


KIND = BodyKind("chain", ChainModel, layout, draw, example=example)


register_parts(ChainSystem, chain_data, fluid=MRS, in_scenes=True)
register_device(ChainSystem, "parastokes.kinds.chain.device:PARTS")
