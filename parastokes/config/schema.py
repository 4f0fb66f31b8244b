"""The typed schema of a run configuration (one TOML file; docs/config.md is generated from here).

Every section is a pydantic model with ``extra="forbid"`` (a typo is an error naming the key) and
``strict=True`` (no silent coercion: ``n_slices = "4"`` or ``n_slices = 4.0`` is rejected; integers
are accepted where a float is expected). Checks that involve several keys (nodes against θ⁰, steps
against the slice length, auxiliary solvers against workers) live in :mod:`.checks`.

Units follow the paper: μm, s, g. Defaults are the paper's values (Table 2 for rods, section 5.2 for
the vesicle). The ``[model]`` section is the section of its body kind, found through
:mod:`parastokes.registry.kinds` (the package's own live in :mod:`parastokes.kinds`); the
``[coarse]`` section is the section of its coarse-solver family, found through
:mod:`parastokes.registry.coarse` (the package's own: :mod:`parastokes.coarse.extrapolated`).
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, SerializeAsAny, field_validator

from ..registry import coarse as coarse_registry
from ..registry import kinds as registry
from ..registry.coarse import CoarseSection
from ..registry.kinds import BodySection, Positive

__all__ = [
    "Config",
    "Execution",
    "Fine",
    "LagrangeNodes",
    "Output",
    "Parareal",
    "Richardson",
    "RunSection",
    "SceneSettings",
    "Suspension",
    "Time",
    "Tune",
]

#: The schemes of ``parastokes.integrate.SCHEMES`` (explicit Runge-Kutta, the embedded pairs
#: rk23 and rk45 with rtol; linearly implicit Rosenbrock-W, docs/stiff.md), and "auto" (with
#: rtol: an explicit pair or an implicit scheme as stiffness comes and goes).
Scheme = Literal["euler", "rk2", "rk4", "rk23", "rk45", "lieuler", "ros2", "ros2-krylov",
                 "ros34pw2", "ros34pw2-krylov", "auto"]
#: The most nodes of a flow grid along one side (``output.flow_resolution``, ``parastokes flow
#: --resolution``): 4096² nodes of a plane are 400 MB of velocities per frame.
MAX_FLOW_RESOLUTION = 4096
#: The largest coordinate (μm) of a flow plane or box: the wall's image terms go as the fifth
#: power of the distance, which overflows past about 1e61.
MAX_FLOW_COORDINATE = 1e30


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True, validate_default=True)


class Time(_Section):
    """The time interval [t0, t1] = [0, T] of eq. 1."""

    t0: float = Field(0.0, allow_inf_nan=False, description="Start time.")
    t1: float = Field(allow_inf_nan=False, description="End time T (must exceed t0).")


class Fine(_Section):
    """The fine solver F: always the correct parameters Θ⁰ and the fine grid (section 3)."""

    scheme: Scheme = Field("rk2", description="Scheme of F (the paper: rk2 or rk4; the embedded "
                           "pairs rk23, rk45 with rtol; linearly implicit for stiff bodies: "
                           "lieuler, ros2, ros2-krylov, ros34pw2, ros34pw2-krylov, docs/stiff.md; "
                           "auto with rtol).")
    dt: Positive = Field(description="Fine time step τ_f (with rtol: the first step tried).")
    rtol: float | None = Field(
        None, description="Adaptive steps within this relative error per step (a scheme with an "
        "error estimate: rk23, rk45, ros2, ros2-krylov, ros34pw2, ros34pw2-krylov, or auto); "
        "omitted: fixed steps of dt.")
    atol: float | None = Field(
        None, description="Absolute error per step of the adaptive steps (default: rtol; state "
        "units, μm for positions).")


class LagrangeNodes(_Section):
    """Nodes θ^1 < ... < θ^N of one parameter for Lagrangian extrapolation (eqs. 17-25)."""

    nodes: list[Annotated[float, Field(allow_inf_nan=False)]] = Field(
        min_length=1, description="The node values, strictly increasing, θ⁰ outside their range."
    )
    unit: str | None = Field(
        None,
        description='"absolute"; "relative": θ^j/θ⁰ (the tables\' a^j/a⁰); for ε only, the grid '
        'length of the body ("sigma_f" for rods, "l_max" for vesicles); omitted: the unit the '
        "model section uses for that parameter.",
    )


class Richardson(_Section):
    """Richardson extrapolation in the time step (eqs. 26-28)."""

    m: int = Field(0, ge=0, description="Extrapolation depth m (0: none).")
    r: float | None = Field(
        None, gt=0, lt=1, description="Step ratio r in (0, 1); required when m >= 1."
    )


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
    schedule: Literal["standard", "pipelined"] = Field(
        "standard",
        description="standard: Algorithm 1 (parallel sweep, then serial coarse sweep); pipelined: "
        "every fine solve, coarse step and auxiliary solve starts as soon as its inputs exist "
        "(same iterates bit for bit; docs/parareal.md).",
    )
    correction: Literal["classical", "secant"] = Field(
        "classical",
        description="classical: eq. 11; secant: eq. 11 plus a secant estimate of (F - G)' "
        "learned from each slice's previous iterates (fewer iterations where G misses a slow "
        "mode; not with the hodmd coarse solver; docs/parareal.md, \"Learned corrections\").",
    )


class Execution(_Section):
    """Where the work runs: the executor of the sweeps and threads of the kernels."""

    executor: Literal["serial", "processes", "mpi", "gpu"] = Field(
        "processes",
        description="serial (reference), processes (one machine), mpi (clusters) or gpu (one "
        "CUDA GPU: each parallel sweep and each coarse step runs as one batch; rigid bodies' "
        "solves on the host with their fluid products batched on the GPU; parastokes[gpu]).",
    )
    workers: int | None = Field(
        None,
        ge=1,
        description="Workers; default: min(n_slices, available cores // threads) (mpi: all "
        "ranks; gpu: the most solves per batch, default max(n_slices, N_G)).",
    )
    threads: int = Field(1, ge=1, description="Kernel threads per worker (spatial parallelism); "
                         'unset, a run of run.mode = "serial" uses every available core.')
    allow_oversubscribe: bool = Field(
        False,
        description="Allow more auxiliary coarse solvers N_G than workers, run in batches (the "
        "paper keeps N_G <= N_c so that they all run at once); implied by the serial executor.",
    )


#: A point index (``output.tracked_points``).
Index = Annotated[int, Field(ge=0)]


class Output(_Section):
    """What a run writes to its output directory."""

    trajectory: bool = Field(True, description="Write trajectory.h5 and trajectory.xdmf.")
    every: int | None = Field(
        None,
        ge=1,
        description="Frames every this many fine steps τ_f (a multiple or a divisor of the fine "
        "steps per slice). Denser than the slices: the frames inside them are computed after the "
        "run, one more fine solve per slice (on the workers). Default: at every slice boundary.",
    )
    frames: bool = Field(True, description="Rods: also write the frames D1, D2, D3.")
    figures: bool = Field(True, description="Draw the figures after the run.")
    monitor_fatal: bool = Field(
        False,
        description="A run whose stability monitor ends above its limit at a slice boundary is "
        "an error (exit 3, its results written) instead of a warning (summary.json's warnings "
        "and standard error); also --monitor-fatal.",
    )
    formats: list[Literal["png", "pdf"]] = Field(
        ["png", "pdf"], min_length=1, description="Figure file formats."
    )
    flow_every: int | None = Field(
        None,
        ge=1,
        description="Also write the flow (flow.h5 + flow.xdmf, a time series ParaView opens, and "
        "flow.png) at every this many saved frames, on flow_plane (parastokes flow; "
        "docs/tutorial.md). Default: none.",
    )
    flow_plane: str | None = Field(
        None,
        pattern=r"^\s*[xyzXYZ]\s*=\s*\S+\s*$",
        description='The plane of flow_every, e.g. "z=5" or "y=0". Default: the x-z plane '
        "through the bodies.",
    )
    flow_resolution: int = Field(
        64, ge=2, le=MAX_FLOW_RESOLUTION,
        description="Nodes of flow_every's plane along its longest side (square cells).",
    )
    tracked_points: list[Index] | dict[str, list[Index]] | None = Field(
        None,
        description="Vesicle points marked in the output and highlighted in the pictures "
        "(Fig. 11); default three. A scene gives a table by body name, e.g. "
        "{vesicle0 = [0, 5]}; its bodies left out keep the default, [] marks none.",
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
        None, description="Parameters that may be extrapolated, the first in every subset; [] none."
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
    coarse_rtols: list[Annotated[float, Field(gt=0, lt=1)]] | None = Field(
        None, description="The rtol ladder of the adaptive candidates (schemes with an error "
        "estimate, and auto), atol = rtol (default [1e-2, 1e-3, 1e-4])."
    )
    max_weight: Positive | None = Field(None, description="Largest Σ|w_j v_q| considered.")
    pilot_slices: int | None = Field(None, ge=2, description="Slices of the pilot window.")
    pilot_points: int | None = Field(
        None, ge=3, description="Rods: nodes per rod of the shortened pilot rod (same σ_f)."
    )


class RepulsionSettings(BaseModel):
    """`[scene] repulsion`: a short-range push apart between the rigid bodies (and from the wall),
    F0 (1 - h/range)^2 on each along the line of closest approach when their surfaces come a gap
    h < range apart (docs/bodies.md, "Suspensions": keeping bodies apart)."""

    model_config = ConfigDict(extra="forbid", strict=True, validate_default=True)

    range: Positive = Field(description="The gap δ below which the repulsion acts (μm).")
    force: Positive = Field(description="Its strength F0 at contact (pN, the units of a rigid "
                            "body's `force`).")


class SceneSettings(BaseModel):
    """The fluid all `[[bodies]]` share; body tables that omit these keys get them. A key left out
    here is taken from the bodies (the first that states it, else the first whose kind has it, with
    that kind's default), else wall = false and shear_rate = 0. Besides the fluid: coarse_bodies,
    the bodies that coarse.grid_factor coarsens; repulsion, a short-range push between the rigid
    bodies (off by default)."""

    model_config = ConfigDict(extra="forbid", strict=True, validate_default=True)

    viscosity: Positive | None = Field(None, description="Fluid viscosity μ⁰ (g μm⁻¹ s⁻¹).")
    wall: bool | None = Field(None, description="Plane wall at z = 0 (method of images).")
    shear_rate: float | None = Field(
        None, allow_inf_nan=False, description="Shear rate γ̇ of u∞ = (γ̇ z, 0, 0) (1/s)."
    )
    coarse_bodies: list[str] | None = Field(
        None, description="With coarse.grid_factor > 1: the names of the bodies put on their "
        "coarser grid (default: every body that has one: rods, rigid bodies)."
    )
    repulsion: RepulsionSettings | None = Field(
        None, description="A short-range repulsion between the rigid bodies, e.g. "
        "`{ range = 0.5, force = 7.5e-5 }`: F0 (1 - h/range)^2 apart along the line of closest "
        "approach for surfaces a gap h < range apart; with a wall, also up from it (default: "
        "none; `false`: none, as `--set scene.repulsion=false` switches off a file's)."
    )

    @field_validator("repulsion", mode="before")
    @classmethod
    def _switched_off(cls, value: Any) -> Any:
        """``repulsion = false``: none (TOML has no null, so a file's or a base's repulsion is
        switched off from the command line this way)."""
        return None if value is False else value


Finite = Annotated[float, Field(allow_inf_nan=False)]
#: Three positive numbers, one per axis.
PositiveTriple = Annotated[list[Positive], Field(min_length=3, max_length=3)]


class Suspension(BaseModel):
    """Many copies of one body in a scene (docs/bodies.md, "Suspensions"): `body` is a table of
    any kind with a position key (`position` or `center`), as a [[bodies]] table but without
    its position; `placement` puts the copies on a lattice, at random without overlap in a box
    or a sphere (seeded), or at the poses of a file. The bodies are named `name` + index
    (sphere0, sphere1, ...) and join the [[bodies]] of the scene, checked as they are."""

    model_config = ConfigDict(extra="forbid", strict=True, validate_default=True)

    name: str | None = Field(
        None, description="Prefix of the bodies' names: name0, name1, ... (default: the body's "
        "kind, as a [[bodies]] table is named).")
    body: dict[str, Any] = Field(
        description="The body that is copied: `kind` and its keys (a [[bodies]] table without "
        "`name` and without its position).")
    placement: Literal["lattice", "random", "file"] = Field(
        description="lattice: `counts` x `spacing` about `center`; random: `count` bodies (or "
        "`volume_fraction`) without overlap in the `region` about `center`, from `seed`; file: "
        "one pose per line of `file`.")
    center: list[Finite] | None = Field(
        None, min_length=3, max_length=3,
        description="lattice, random: the centre of the lattice or of the region (μm).")
    counts: list[Annotated[int, Field(ge=1)]] | None = Field(
        None, min_length=3, max_length=3, description="lattice: bodies along x, y and z.")
    spacing: Positive | PositiveTriple | None = Field(
        None, description="lattice: distance between neighbouring centres (μm), one number or "
        "[dx, dy, dz].")
    region: Literal["box", "sphere"] = Field(
        "box", description="random: the region the bodies lie in (wholly), a box of `size` or "
        "a sphere of `radius` about `center`.")
    size: list[Positive] | None = Field(
        None, min_length=3, max_length=3, description="random, box: its edges [Lx, Ly, Lz] (μm).")
    radius: Positive | None = Field(None, description="random, sphere: its radius (μm).")
    count: int | None = Field(
        None, ge=1, description="random: the number of bodies (or give volume_fraction).")
    volume_fraction: float | None = Field(
        None, gt=0, lt=1, description="random: the bodies' volume over the region's, each body "
        "counted as its bounding sphere about its position (a sphere's own volume); sets the "
        "number of bodies (or give count).")
    seed: int = Field(0, ge=0, description="random: seed of the positions and orientations "
                      "(the same seed, the same suspension).")
    gap: float | None = Field(
        None, ge=0, allow_inf_nan=False,
        description="lattice, random: least distance between the bounding spheres of two bodies "
        "(μm); default: the larger of a fifth of the bounding radius and 2 ε.")
    orientations: Literal["fixed", "random"] = Field(
        "fixed", description="fixed: every copy turned as the body table says; random: uniform "
        "random orientations from `seed` (kinds with an `orientation` key).")
    file: str | None = Field(
        None, description="file: one body per line, x y z or x y z qw qx qy qz (a quaternion, "
        "kinds with an `orientation` key), in a text file (spaces or commas, # comments) or a "
        ".npy array; a relative path is relative to the configuration file that names it.")


class Config(_Section):
    """A whole run: model, time, fine and coarse solvers, Parareal, execution, output, run."""

    title: str = Field("", description="Free text, e.g. the paper's table and solver.")
    model: SerializeAsAny[BodySection] = Field(
        description="The body: a section of its registered kind (`kind` = rod, vesicle, chain, "
        'or "package.module:ClassName", docs/extending.md).'
    )
    time: Time
    fine: Fine
    coarse: SerializeAsAny[CoarseSection] = Field(
        default_factory=lambda: coarse_registry.get(coarse_registry.DEFAULT).model_validate({}),
        description="The coarse solver: a section of its family (`kind` = extrapolated, the "
        'default, or "package.module:ClassName", docs/extending.md).',
    )
    parareal: Parareal
    execution: Execution = Field(default_factory=Execution)
    output: Output = Field(default_factory=Output)
    run: RunSection = Field(default_factory=RunSection)
    tune: Tune = Field(default_factory=Tune)

    @field_validator("model", mode="before")
    @classmethod
    def _section_of_kind(cls, value: Any) -> Any:
        """A ``[model]`` table is validated by the section class of its kind (the registry)."""
        if isinstance(value, dict):
            return registry.get(value.get("kind", "")).section.model_validate(value)
        return value

    @field_validator("coarse", mode="before")
    @classmethod
    def _coarse_of_kind(cls, value: Any) -> Any:
        """A ``[coarse]`` table is validated by the section class of its family (the coarse
        registry; ``kind`` defaults to ``"extrapolated"``)."""
        if isinstance(value, dict):
            kind = value.get("kind", coarse_registry.DEFAULT)
            return coarse_registry.get(kind).model_validate(value)
        return value


def __getattr__(name: str) -> Any:
    """``RodModel`` and ``VesicleModel``, the sections of the built-in kinds, and ``Coarse``, the
    section of the extrapolated coarse-solver family (loaded on use)."""
    kinds = {"RodModel": "rod", "VesicleModel": "vesicle"}
    if name in kinds:
        return registry.get(kinds[name]).section
    if name == "Coarse":
        return coarse_registry.get("extrapolated")
    raise AttributeError(name)
