"""The typed schema of a run configuration (one TOML file; docs/config.md is generated from here).

Every section is a pydantic model with ``extra="forbid"`` (a typo is an error naming the key) and
``strict=True`` (no silent coercion: ``n_slices = "4"`` or ``n_slices = 4.0`` is rejected; integers
are accepted where a float is expected). Checks that involve several keys (nodes against θ⁰, steps
against the slice length, auxiliary solvers against workers) live in :mod:`.checks`.

Units follow the paper: μm, s, g. Defaults are the paper's values (Table 2 for rods, section 5.2 for
the vesicle).
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

__all__ = [
    "Coarse",
    "Config",
    "Execution",
    "Fine",
    "LagrangeNodes",
    "Output",
    "Parareal",
    "Richardson",
    "RodModel",
    "RunSection",
    "Time",
    "Tune",
    "VesicleModel",
]

Scheme = Literal["euler", "rk2", "rk4"]
Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True, validate_default=True)


class RodModel(_Section):
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


class VesicleModel(_Section):
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


class Time(_Section):
    """The time interval [t0, t1] = [0, T] of eq. 1."""

    t0: float = Field(0.0, allow_inf_nan=False, description="Start time.")
    t1: float = Field(allow_inf_nan=False, description="End time T (must exceed t0).")


class Fine(_Section):
    """The fine solver F: always the correct parameters Θ⁰ and the fine grid (section 3)."""

    scheme: Scheme = Field("rk2", description="Runge-Kutta scheme of F (the paper: rk2 or rk4).")
    dt: Positive = Field(description="Fine time step τ_f.")


class LagrangeNodes(_Section):
    """Nodes θ^1 < ... < θ^N of one parameter for Lagrangian extrapolation (eqs. 17-25)."""

    nodes: list[Annotated[float, Field(allow_inf_nan=False)]] = Field(
        min_length=1, description="The node values, strictly increasing, θ⁰ outside their range."
    )
    unit: Literal["absolute", "relative", "sigma_f", "l_max"] | None = Field(
        None,
        description='"relative": θ^j/θ⁰ (the tables\' a^j/a⁰); "sigma_f" / "l_max": ε only; '
        "omitted: the unit the model section uses for that parameter.",
    )


class Richardson(_Section):
    """Richardson extrapolation in the time step (eqs. 26-28)."""

    m: int = Field(0, ge=0, description="Extrapolation depth m (0: none).")
    r: float | None = Field(
        None, gt=0, lt=1, description="Step ratio r in (0, 1); required when m >= 1."
    )


class Coarse(_Section):
    """The coarse solver G of eq. 30: Σ_j w_j Σ_q v_q G_{Θ^j, r^q τ} (optionally on a coarser grid).

    As in the paper (section 5.1), the coarse step τ_c is the SMALLEST step of the auxiliary
    solvers, r^m τ; the base step of eq. 26 is τ = τ_c / r^m.
    """

    scheme: Scheme = Field("euler", description="Scheme of the auxiliary solvers (paper: euler).")
    dt: Positive | None = Field(None, description="Coarse step τ_c = r^m τ (give dt or dt_ratio).")
    dt_ratio: Positive | None = Field(None, description="τ_c / τ_f (the tables' τ_c = 18 τ_f: 18).")
    lagrange: dict[str, LagrangeNodes] = Field(
        default_factory=dict,
        description="Parameter name -> nodes (rods: epsilon, bending, viscosity; vesicles: "
        "epsilon, stiffness, viscosity). A plain list is short for {nodes = [...]}.",
    )
    richardson: Richardson = Field(
        default_factory=Richardson, description="Richardson extrapolation {m, r}."
    )
    grid_factor: int = Field(1, ge=1, description="σ_c / σ_f (rods only; Table 6 uses 6).")

    @field_validator("lagrange", mode="before")
    @classmethod
    def _plain_lists(cls, value: Any) -> Any:
        """``epsilon = [5.6, 5.65]`` is short for ``epsilon = {nodes = [5.6, 5.65]}``."""
        if isinstance(value, dict):
            return {k: {"nodes": v} if isinstance(v, list) else v for k, v in value.items()}
        return value


class Parareal(_Section):
    """Algorithm 1: slices, stopping rule (relative increment η̃ of eq. 34), checkpoints."""

    n_slices: int = Field(ge=1, description="Number of time slices N_c (the paper: one per core).")
    tol: float = Field(
        0.0, ge=0, allow_inf_nan=False, description="Stop when η̃^k < tol (0: run max_iterations)."
    )
    max_iterations: int = Field(3, ge=1, description="Largest number of iterations N_it.")
    checkpoint: bool = Field(
        True, description="Keep DIR/checkpoint.npz after every iteration (for --resume)."
    )


class Execution(_Section):
    """Where the work runs: the executor of the sweeps and threads of the kernels."""

    executor: Literal["serial", "processes", "mpi"] = Field(
        "processes", description="serial (reference), processes (one machine) or mpi (clusters)."
    )
    workers: int | None = Field(
        None, ge=1, description="Workers; default: min(n_slices, available cores) (mpi: all ranks)."
    )
    threads: int = Field(1, ge=1, description="Kernel threads per worker (spatial parallelism).")
    allow_oversubscribe: bool = Field(
        False,
        description="Allow more auxiliary coarse solvers N_G than workers, run in batches (the "
        "paper keeps N_G <= N_c so that they all run at once); implied by the serial executor.",
    )


class Output(_Section):
    """What a run writes to its output directory."""

    trajectory: bool = Field(True, description="Write trajectory.h5 and trajectory.xdmf.")
    every: int = Field(1, ge=1, description="Write every n-th slice boundary T_n as a frame.")
    frames: bool = Field(True, description="Rods: also write the frames D1, D2, D3.")
    figures: bool = Field(True, description="Draw the figures after the run.")
    formats: list[Literal["png", "pdf"]] = Field(
        ["png", "pdf"], min_length=1, description="Figure file formats."
    )
    tracked_points: list[Annotated[int, Field(ge=0)]] | None = Field(
        None, description="Vesicle points highlighted in the pictures (Fig. 11); default three."
    )


class RunSection(_Section):
    """What to compute."""

    mode: Literal["serial", "parareal", "both"] = Field(
        "both",
        description="serial: the fine solution only; parareal: Algorithm 1 only; both: also the "
        "true errors η^k (eq. 34) and the measured speedup against the serial run.",
    )


class Tune(_Section):
    """Narrows the search of ``parastokes tune`` (docs/tuning.md); omitted keys: the tuner's
    defaults. Ignored by ``run``."""

    schemes: list[Scheme] | None = Field(None, description="Schemes of the auxiliary solvers.")
    parameters: list[str] | None = Field(
        None, description="Parameters that may be extrapolated, in order (nested subsets); [] none."
    )
    reach: list[Literal[0, 1, 2]] | None = Field(None, description="Node distance levels.")
    nodes: list[Annotated[int, Field(ge=1)]] | None = Field(
        None, description="Node counts of the first parameter (the others at most 3)."
    )
    richardson: list[Annotated[int, Field(ge=0)]] | None = Field(
        None, description="Richardson depths m to try."
    )
    grid_factors: list[Annotated[int, Field(ge=1)]] | None = Field(
        None, description="Coarse-grid factors σ_c/σ_f to try (rods); [1] forbids the coarse grid."
    )
    step_fractions: list[Annotated[float, Field(gt=0, le=1)]] | None = Field(
        None, description="Coarse steps as fractions of the largest safe step."
    )
    max_weight: Positive | None = Field(None, description="Largest Σ|w_j v_q| considered.")
    pilot_slices: int | None = Field(None, ge=2, description="Slices of the pilot window.")
    pilot_points: int | None = Field(
        None, ge=3, description="Rods: nodes per rod of the shortened pilot rod (same σ_f)."
    )


class Config(_Section):
    """A whole run: model, time, fine and coarse solvers, Parareal, execution, output, run."""

    title: str = Field("", description="Free text, e.g. the paper's table and solver.")
    model: Annotated[RodModel | VesicleModel, Field(discriminator="kind")] = Field(
        description="The physical model (rod or vesicle)."
    )
    time: Time
    fine: Fine
    coarse: Coarse = Field(default_factory=Coarse)
    parareal: Parareal
    execution: Execution = Field(default_factory=Execution)
    output: Output = Field(default_factory=Output)
    run: RunSection = Field(default_factory=RunSection)
    tune: Tune = Field(default_factory=Tune)
