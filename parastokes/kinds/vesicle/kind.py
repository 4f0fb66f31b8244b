"""The vesicle kind: the spring-network sphere in shear flow (section 5.2) as a registered body.

Its config section (:class:`VesicleModel`, which resolves ε in l_max and builds a
:class:`.system.VesicleSystem`), output layout (one Triangle mesh, the tracked points of Fig. 11 as
a 0/1 mark) and drawing (the x-z projection at the first and the last frame, tracked points
marked).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import Field

from ...bodies import geometry
from ...registry.kinds import BodyKind, BodyLayout, BodyResolution, BodySection, Positive
from .system import VesicleSystem, longest_edge, vesicle
from .transfer import levels_down

__all__ = ["KIND", "VesicleModel"]


class VesicleModel(BodySection):
    """The spring-network sphere in the shear flow u∞ = (γ̇ z, 0, 0) (section 5.2)."""

    kind: Literal["vesicle"] = Field(description='"vesicle" for the elastic sphere (section 5.2).')
    subdivisions: int = Field(
        3, ge=0, le=6, description="Icosphere refinement level (3: 642 points, 1280 triangles)."
    )
    epsilon: Positive = Field(
        0.3, description="Regularization ε⁰ of the MRS, in the unit `epsilon_unit`."
    )
    epsilon_unit: Literal["absolute", "l_max"] = Field(
        "l_max", description='"l_max": ε⁰ = epsilon · l_max (longest edge); "absolute".'
    )
    stiffness: Positive = Field(0.1, description="Spring constant κ⁰ (g s⁻²).")
    viscosity: Positive = Field(1e-3, description="Fluid viscosity μ⁰ (g μm⁻¹ s⁻¹).")
    shear_rate: float = Field(0.1, allow_inf_nan=False, description="Shear rate γ̇ of u∞ (1/s).")
    center: list[Annotated[float, Field(allow_inf_nan=False)]] = Field(
        [0.0, 0.0, 0.0], min_length=3, max_length=3,
        description="Initial centre of the sphere [x, y, z] (μm).",
    )
    radius: Positive = Field(
        1.0, description="Radius R of the sphere (μm); the mesh, the springs' rest lengths and "
        "l_max (so ε in the unit l_max) scale with it.",
    )

    def resolve(self) -> BodyResolution:
        l_max = longest_edge(self.subdivisions, self.radius)
        epsilon = self.epsilon * (l_max if self.epsilon_unit == "l_max" else 1.0)
        theta0 = {"epsilon": epsilon, "viscosity": self.viscosity, "stiffness": self.stiffness}
        n_points = len(geometry.icosphere(self.subdivisions)[0])
        return BodyResolution(theta0, n_points, l_max, "l_max")

    def build(self, threads: int = 1) -> VesicleSystem:
        x, y, z = self.center  # three, by the field's min_length and max_length
        return VesicleSystem(
            subdivisions=self.subdivisions,
            epsilon=self.resolve().theta0["epsilon"],
            viscosity=self.viscosity,
            stiffness=self.stiffness,
            shear_rate=self.shear_rate,
            n_threads=threads,
            center=(x, y, z),
            radius=self.radius,
        )

    def coarse_points(self, factor: int) -> int:
        """Vertices of the icosphere with edges ``factor`` = 2^j times longer, as
        :meth:`VesicleSystem.coarsened` builds it."""
        return len(geometry.icosphere(self.subdivisions - levels_down(factor,
                                                                      self.subdivisions))[0])


def default_tracked(system: VesicleSystem) -> list[int]:
    """Three points on the x-z circle (top, front, lower back) as in Fig. 11."""
    x0 = (system.initial_state() - np.asarray(system.center)) / system.radius
    targets = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [-0.6, 0.0, -0.8]])
    return [int(np.argmin(np.linalg.norm(x0 - t, axis=1))) for t in targets]


def layout(
    section: VesicleModel, system: VesicleSystem, frames: bool, tracked: Sequence[int] | None
) -> list[BodyLayout]:
    """One Triangle mesh with the tracked points (default :func:`default_tracked`) marked."""
    n = len(system.initial_state())
    mask = np.zeros(n, dtype=np.int32)
    mask[list(default_tracked(system) if tracked is None else tracked)] = 1
    triangles = np.asarray(system.mesh[1], dtype=np.int64)
    marks = {"tracked": mask}
    return [BodyLayout("vesicle_0", "vesicle", 0, n, "Triangle", triangles, marks=marks)]


def draw(fig: Any, bodies: Mapping[str, Mapping[str, np.ndarray]], times: np.ndarray,
         run: str) -> None:
    """The x-z projection of the first body at the first and the last frame (Fig. 11)."""
    from matplotlib.collections import LineCollection

    body = next(iter(bodies.values()))
    tracked = np.flatnonzero(body.get("tracked", ()))
    fig.set_size_inches(8, 4)
    axes = fig.subplots(1, 2, sharex=True, sharey=True)
    for ax, index in zip(axes, (0, -1), strict=True):
        points = body["positions"][index][:, [0, 2]]
        edges = points[body["connectivity"][:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)]
        ax.add_collection(LineCollection(edges, colors="0.6", linewidths=0.3))
        for j, p in enumerate(tracked):
            ax.plot(*points[p], "o", color=f"C{j + 1}", ms=7)
        ax.set_title(f"t = {times[index]:g}")
        ax.set_xlabel("x")
        ax.set_aspect("equal")
        ax.autoscale_view()
    axes[0].set_ylabel("z")


def example() -> tuple[VesicleSystem, np.ndarray, float | None]:
    """A small vesicle (162 points) stretched by 2% along x, so that its springs pull."""
    system = vesicle(subdivisions=2)
    return system, system.initial_state() * np.array([1.02, 1.0, 1 / 1.02]), 0.02


KIND = BodyKind("vesicle", VesicleModel, layout, draw, tracks_points=True, example=example)
