"""A coarse-solver family written outside the package (tests/test_coarse_family.py): G is one
solver with the correct parameters Θ⁰ and its own step, no extrapolation (the "plain" coarse
solver). Used as ``[coarse] kind = "tests.coarse_family:Plain"``; it imports only the public
extension path, ``parastokes.registry.coarse`` and ``parastokes.integrate``."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import Field

from parastokes import integrate
from parastokes.registry.coarse import CoarseResolution, CoarseSection


class Plain(CoarseSection):
    """G = one solver with Θ⁰ and the step ``dt_ratio`` τ_f."""

    kind: str = "tests.coarse_family:Plain"
    scheme: Literal["euler", "rk2", "rk4"] = "euler"
    dt_ratio: float = Field(gt=0, description="τ_c / τ_f.")

    def resolve(self, cfg: Any, body: Any, slice_length: float, issues: list[tuple[str, str]],
                warnings: list[str]) -> CoarseResolution:
        dt = self.dt_ratio * cfg.fine.dt
        if dt > slice_length:
            issues.append(("coarse.dt_ratio", f"τ_c = {dt:g} exceeds the slice {slice_length:g}"))
        steps = integrate.n_steps(0.0, slice_length, dt)
        return CoarseResolution(dt, dt, [steps], body.n_points)

    def build(self, cfg: Any, resolved: Any, system: Any) -> integrate.Propagator:
        return integrate.Propagator(system, self.scheme, resolved.coarse_dt)

    def gamma_ratio(self, cfg: Any, resolved: Any, cores: int) -> float:
        return 1.0 / self.dt_ratio
