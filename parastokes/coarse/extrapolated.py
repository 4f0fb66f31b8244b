"""The extrapolated coarse solver G of eq. 30, the package's own family (``kind = "extrapolated"``).

G = Σ_j w_j Σ_q v_q G_{Θ^j, r^q τ}: Lagrangian extrapolation in the parameters (eqs. 17-25) and
Richardson extrapolation in the step (eqs. 26-28), optionally on a coarser grid (Remark 4). Its
rules, checked before any solver is built:

- Lagrange nodes (section 4.1): θ^1 < θ^2 < ... (condition 1) and θ⁰ outside [θ^1, θ^N]
  (condition 2); all parameters are positive;
- Richardson (eq. 26): integer m >= 0, r in (0, 1), and the steps r^q τ must give different step
  counts on a slice (otherwise the weights of eq. 27 are undefined);
- N_G = (Π_i N_θi)(m + 1) auxiliary solvers (eq. 31);
- the weights sum, in absolute value, to Σ|w_j v_q| (nodes close together, or close to θ⁰, make it
  large): above ``coarse.max_weight_sum`` (default 10⁶; the paper's configurations reach 1.7·10⁵)
  the configuration is refused.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Literal

from pydantic import Field, field_validator

from .. import integrate, parareal
from ..config.build import build_system
from ..config.checks import steps_on_slice
from ..config.schema import LagrangeNodes, Richardson, Scheme
from ..core.contracts import System, rounds
from ..parareal import weights
from ..parareal.extrapolation import adaptive_tolerances
from ..registry.coarse import CoarseResolution, CoarseSection
from ..registry.kinds import BodyResolution, Positive
from ..stiff.schemes import ROSENBROCK, Rosenbrock, refreshed_every
from .step_cost import FINE_PROBE_STEPS, evaluations_per_step

__all__ = ["Extrapolated"]


class Extrapolated(CoarseSection):
    """The coarse solver G of eq. 30: Σ_j w_j Σ_q v_q G_{Θ^j, r^q τ} (optionally on a coarser grid).

    As in the paper (section 5.1), the coarse step τ_c is the SMALLEST step of the auxiliary
    solvers, r^m τ; the base step of eq. 26 is τ = τ_c / r^m.
    """

    kind: Literal["extrapolated"] = Field(
        "extrapolated",
        description="The coarse-solver family: the extrapolated G of eq. 30, or "
        '"package.module:ClassName" (docs/extending.md).',
    )
    scheme: Scheme = Field("euler", description="Scheme of the auxiliary solvers (paper: euler).")
    dt: Positive | None = Field(None, description="Coarse step τ_c = r^m τ (give dt or dt_ratio).")
    dt_ratio: Positive | None = Field(None, description="τ_c / τ_f (the tables' τ_c = 18 τ_f: 18).")
    lagrange: dict[str, LagrangeNodes] = Field(
        default_factory=dict,
        description="Parameter name -> nodes (rods: epsilon, bending, viscosity; vesicles: "
        'epsilon, stiffness, viscosity; scenes: "body.parameter", e.g. "rod.epsilon", or '
        "viscosity). A plain list is short for {nodes = [...]}.",
    )
    richardson: Richardson = Field(
        default_factory=Richardson, description="Richardson extrapolation {m, r}."
    )
    rtol: float | None = Field(
        None, description="Adaptive steps of every auxiliary solver within this relative error "
        "per step (ros2, ros2-krylov; not with richardson.m >= 1); dt is then the first step.")
    atol: float | None = Field(None, description="Absolute error per step (default: rtol).")
    grid_factor: int = Field(1, ge=1, description="σ_c / σ_f (rods; Table 6 uses 6); vesicles: "
                             "2^j, the icosphere j levels coarser; rigid bodies: each part of the "
                             "surface with factor times fewer points; scenes: "
                             "every body that has a coarser grid, or those of "
                             "scene.coarse_bodies.")
    jacobian_every: int | None = Field(
        None, ge=1, description="Linearly implicit schemes: rebuild the approximate Jacobian A "
        "(and refactorize) every this many steps of an auxiliary solve; default 5 "
        "(parastokes.stiff.stepper.REFRESH). Fewer rebuilds: cheaper steps, a staler A "
        "(docs/benchmarks.md, \"Parareal against the fastest serial run\").")
    hold_time_derivative: bool = Field(
        False, description="Linearly implicit schemes: take the rates' time derivative f_t "
        "with A and hold it until A is rebuilt (one rate evaluation less per step) instead of "
        "a forward difference at every step.")
    max_weight_sum: Positive = Field(
        1e6,
        description="Refuse a coarse solver whose weights have Σ|w_j v_q| above this (nearly "
        "coinciding nodes amplify round-off by that factor; the paper's reach 1.7e5).",
    )

    @field_validator("lagrange", mode="before")
    @classmethod
    def _plain_lists(cls, value: Any) -> Any:
        """``epsilon = [5.6, 5.65]`` is short for ``epsilon = {nodes = [5.6, 5.65]}``."""
        if isinstance(value, dict):
            return {k: {"nodes": v} if isinstance(v, list) else v for k, v in value.items()}
        return value

    def resolve(self, cfg: Any, body: BodyResolution, slice_length: float,
                issues: list[tuple[str, str]], warnings: list[str]) -> CoarseResolution:
        """τ_c, τ = τ_c / r^m, the step counts of eq. 26, the absolute nodes, N_G, Σ|w_j v_q| and
        the coarse grid's points; issues for every rule of the module docstring."""
        model, theta0 = cfg.model, body.theta0
        if (self.dt is None) == (self.dt_ratio is None):
            issues.append(("coarse.dt", "give exactly one of coarse.dt and coarse.dt_ratio"))
        coarse_dt = self.dt if self.dt is not None else (self.dt_ratio or 1.0) * cfg.fine.dt
        m, r = self.richardson.m, self.richardson.r
        if m >= 1 and r is None:
            issues.append(("coarse.richardson.r", "required when m >= 1"))
        base_dt = coarse_dt / (r or 1.0) ** m
        coarse_steps = [
            steps_on_slice(slice_length, base_dt * (r or 1.0) ** q, "coarse.dt", "τ_c",
                           None if m else warnings)
            for q in range(m + 1)
        ]
        try:  # the rule of eq. 27 where it lives: the weights of the steps actually taken
            weights.step_weights([slice_length / n for n in coarse_steps], 1)
        except ValueError:
            issues.append(
                (
                    "coarse.richardson.r",
                    f"the steps r^q τ give the step counts {coarse_steps} on a slice; they must "
                    "all differ (choose r farther from 1 or a smaller coarse step)",
                )
            )
        if self.rtol is not None or self.atol is not None:
            try:
                adaptive_tolerances(self.scheme, self.rtol, self.atol, m)
            except ValueError as error:
                key, _, text = str(error).partition(": ")
                issues.append((f"coarse.{key}", text))
        if (self.jacobian_every is not None or self.hold_time_derivative) and not (
                integrate.lookup(self.scheme).implicit):
            key = "jacobian_every" if self.jacobian_every is not None else "hold_time_derivative"
            issues.append((f"coarse.{key}", f"only for a linearly implicit scheme (lieuler, "
                           f"ros2, ros34pw2, ...); {self.scheme!r} takes no Jacobian: remove it"))
        if coarse_dt < cfg.fine.dt:
            warnings.append(
                f"coarse.dt: τ_c = {coarse_dt:.6g} is smaller than τ_f = {cfg.fine.dt:.6g}"
            )

        lagrange = {}
        for name in self.lagrange:
            if name not in theta0:
                issues.append(
                    (
                        f"coarse.lagrange.{name}",
                        f"unknown parameter; a {model.kind} model extrapolates in "
                        f"{', '.join(theta0)}",
                    )
                )
                continue
            lagrange[name] = self._node_values(model, name, theta0[name], issues)
        n_auxiliary = math.prod(len(spec.nodes) for spec in self.lagrange.values()) * (m + 1)
        weight_sum = 1.0
        if not issues:
            weight_sum = self._weight_sum(lagrange, theta0, coarse_steps, slice_length, issues)

        coarse_points = body.n_points
        if self.grid_factor > 1:
            try:
                coarse_points = model.coarse_points(self.grid_factor)
            except ValueError as error:
                issues.append(("coarse.grid_factor", str(error)))
        return CoarseResolution(coarse_dt, base_dt, coarse_steps, coarse_points, lagrange,
                                n_auxiliary, weight_sum)

    def _node_values(self, model: Any, name: str, theta0: float,
                     issues: list[tuple[str, str]]) -> list[float]:
        """The absolute nodes of parameter ``name``; appends issues for bad units and orderings."""
        path = f"coarse.lagrange.{name}"
        spec = self.lagrange[name]
        model_unit, grid = model.parameter_units(name)
        unit = spec.unit or model_unit
        factors = {"absolute": 1.0, "relative": theta0, **grid}
        if unit not in factors:
            issues.append(
                (
                    f"{path}.unit",
                    f"{unit!r} is not a unit of {name} of a {model.kind} model; use one of "
                    f"{', '.join(factors)}",
                )
            )
            return []
        factor = factors[unit]
        values = [v * factor for v in spec.nodes]
        if min(spec.nodes) <= 0:
            issues.append((path, f"nodes must be positive, got {spec.nodes}"))
        elif any(b <= a for a, b in zip(spec.nodes, spec.nodes[1:], strict=False)):
            issues.append((path, f"nodes must be strictly increasing, got {spec.nodes}"))
        elif values[0] <= theta0 <= values[-1]:
            issues.append(
                (
                    path,
                    f"θ⁰ = {theta0:.6g} must lie outside the node interval [{values[0]:.6g}, "
                    f"{values[-1]:.6g}] (section 4.1, condition 2)",
                )
            )
        return values

    def _weight_sum(self, lagrange: dict[str, list[float]], theta0: dict[str, float],
                    steps: list[int], slice_length: float, issues: list) -> float:
        """Σ|w_j v_q| of eq. 30 (it factorizes over the parameters and the Richardson steps);
        appends an issue above ``coarse.max_weight_sum``."""
        total = 1.0
        for name, values in lagrange.items():
            if values:
                total *= float(abs(weights.lagrange_weights(theta0[name], values)).sum())
        if len(steps) > 1:
            order = integrate.scheme_order(self.scheme)
            total *= float(
                abs(weights.step_weights([slice_length / n for n in steps], order)).sum()
            )
        bound = self.max_weight_sum
        if total > bound:
            issues.append(
                (
                    "coarse.lagrange",
                    f"the extrapolation weights have Σ|w_j v_q| = {total:.3g} > {bound:g}: the "
                    "nodes are so close together (or to θ⁰) that the coarse solver multiplies "
                    f"round-off and step errors by up to {total:.3g}; move the nodes apart, or "
                    "raise coarse.max_weight_sum to force it",
                )
            )
        return total

    def build(self, cfg: Any, resolved: Any, system: System
              ) -> parareal.Extrapolated | parareal.OnCoarseGrid:
        """G of eq. 30 with the base step τ = τ_c / r^m (``resolved.coarse_base_dt``)."""
        richardson = self.richardson
        return parareal.extrapolated(
            system,
            self.auxiliary_scheme(),
            resolved.coarse_base_dt,
            lagrange=resolved.lagrange or None,
            richardson={"m": richardson.m, "r": richardson.r} if richardson.m else None,
            grid=self.grid_factor if self.grid_factor > 1 else None,
            rtol=self.rtol,
            atol=self.atol,
        )

    def auxiliary_scheme(self) -> str | Rosenbrock:
        """The auxiliary solvers' scheme: its name, or with ``jacobian_every`` or
        ``hold_time_derivative`` the linearly implicit scheme that carries them."""
        if self.jacobian_every is None and not self.hold_time_derivative:
            return self.scheme
        return refreshed_every(ROSENBROCK[self.scheme], self.jacobian_every,
                               self.hold_time_derivative)

    def gamma_ratio(self, cfg: Any, resolved: Any, cores: int) -> float:
        """γ_G/γ_F from operation counts: rate evaluations per slice times (points)² (the O(N²)
        Stokeslet sums dominate), with the N_G auxiliary solvers in ceil(N_G / cores) waves. An
        implicit or adaptive scheme's evaluations per step are measured on the body
        (:mod:`..step_cost`: its Jacobians, factorizations and GMRES iterations included)."""
        fine, (slowest,) = operation_counts(cfg, resolved, [(self, resolved)])
        return rounds(resolved.n_auxiliary, cores) * slowest * resolved.coarse_points**2 / fine



def operation_counts(cfg: Any, resolved: Any, sections: Sequence[tuple[Extrapolated, Any]]
                     ) -> tuple[float, list[float]]:
    """The operation counts of one slice: F's rate evaluations times (points)², and for each
    (section, its resolution) the evaluations of its slowest auxiliary solver
    (:func:`~.step_cost.evaluations_per_step`; the body is built once, when a count is measured)."""
    schemes = [cfg.fine.scheme, *(section.scheme for section, _ in sections)]
    measured = any(integrate.lookup(name).implicit for name in schemes) or any(
        rtol is not None for rtol in (cfg.fine.rtol, *(section.rtol for section, _ in sections)))
    body = build_system(cfg, resolved) if measured else None
    per_fine = evaluations_per_step(cfg, resolved, cfg.fine.scheme, resolved.fine_steps,
                                    rtol=cfg.fine.rtol, atol=cfg.fine.atol, system=body,
                                    probe=FINE_PROBE_STEPS)
    coarse = []
    for section, res in sections:
        steps = max(res.coarse_steps)
        coarse.append(steps * evaluations_per_step(cfg, res, section.auxiliary_scheme(), steps,
                                                   section.grid_factor, section.rtol,
                                                   section.atol, system=body))
    return resolved.fine_steps * per_fine * resolved.n_points**2, coarse
