"""Checks across keys and the values they resolve to (absolute ε, nodes, steps, workers).

Everything here is cheap (no solver is built), so ``parastokes check`` and every run catch a bad
configuration before any expensive work. The rules are the paper's:

- Lagrange nodes (section 4.1): θ^1 < θ^2 < ... (condition 1) and θ⁰ outside [θ^1, θ^N]
  (condition 2); all parameters are positive;
- Richardson (eq. 26): integer m >= 0, r in (0, 1), and the steps r^q τ must give different step
  counts on a slice (otherwise the weights of eq. 27 are undefined);
- N_G = (Π_i N_θi)(m + 1) auxiliary solvers (eq. 31) run at once only with N_G workers: more is an
  error unless ``execution.allow_oversubscribe`` (Algorithm 1 assumes N_G <= N_c), or with
  ``parareal.schedule = "pipelined"`` (its auxiliary solves wait for workers like any task).

And what cannot work or will not end in reasonable time:

- the weights of eq. 30 sum, in absolute value, to Σ|w_j v_q| (Lagrange nodes close together,
  or close to θ⁰, make it large): the coarse solver multiplies the auxiliary solvers' round-off
  and step errors by up to that factor. Above ``coarse.max_weight_sum`` (default 10⁶; the paper's
  configurations reach 1.7·10⁵) the configuration is refused; raise the key to force it;
- a serial fine solution of more than 10¹² steps is refused, and one estimated (from the points
  and steps, :func:`estimated_fine_seconds`) to take more than a day on one core gets a note;
- more workers x threads than the cores of this machine gets a note naming what to pass instead.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

from .. import integrate
from ..contracts import oversubscription
from ..parallel import available_cores
from ..parareal import weights
from .errors import ConfigError
from .schema import Config

__all__ = ["Resolved", "estimated_fine_seconds", "resolve", "resolved_dict"]

#: Most fine steps (all slices) a configuration may ask for: beyond, the run cannot end.
MAX_FINE_STEPS = 10**12
#: Estimated serial fine run time (s) above which ``check`` and every run print a note.
LONG_RUN_SECONDS = 86400.0
# One rate evaluation costs about _EVAL_SECONDS + _PAIR_SECONDS N² on one core (a rod of 301
# nodes above the wall: 0.5 ms per evaluation, docs/benchmarks.md); a rough guide only.
_EVAL_SECONDS = 4e-5
_PAIR_SECONDS = 5.5e-9


@dataclass(frozen=True)
class Resolved:
    """Values derived from a valid :class:`Config`, in absolute units.

    ``coarse_dt`` is τ_c = r^m τ (the smallest auxiliary step, as the paper counts it) and
    ``coarse_base_dt`` the τ of eq. 26; ``coarse_steps[q]`` is the number of steps of
    G_{Θ, r^q τ} on one slice; ``grid_spacing`` is the length ε may be given in units of (σ_f for
    rods, l_max for vesicles; NaN for kinds without one); ``epsilon`` is ε⁰ (NaN for kinds without
    an ε in Θ).
    """

    epsilon: float
    grid_spacing: float
    n_points: int
    theta0: dict[str, float]
    slice_length: float
    fine_dt: float
    fine_steps: int
    coarse_dt: float
    coarse_base_dt: float
    coarse_steps: list[int]
    coarse_points: int
    lagrange: dict[str, list[float]]
    n_auxiliary: int
    workers: int | None
    warnings: list[str] = field(default_factory=list)
    weight_sum: float = 1.0


def _node_values(
    cfg: Config, name: str, theta0: float, issues: list[tuple[str, str]]
) -> list[float]:
    """The absolute nodes of parameter ``name``; appends issues for bad units and orderings."""
    path = f"coarse.lagrange.{name}"
    spec = cfg.coarse.lagrange[name]
    model_unit, grid = cfg.model.parameter_units(name)
    unit = spec.unit or model_unit
    factors = {"absolute": 1.0, "relative": theta0, **grid}
    if unit not in factors:
        issues.append(
            (
                f"{path}.unit",
                f"{unit!r} is not a unit of {name} of a {cfg.model.kind} model; use one of "
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


def _steps(slice_length: float, dt: float, path: str, what: str, warnings: list[str] | None) -> int:
    """Steps of size ~``dt`` on a slice; warns (unless ``warnings`` is None) when dt does not divide
    it (Richardson steps r^q τ rarely do; eq. 27's weights are computed for the steps taken)."""
    n = integrate.n_steps(0.0, slice_length, dt)
    used = slice_length / n
    if warnings is not None and abs(used - dt) > 1e-9 * dt:
        warnings.append(
            f"{path}: the slice length {slice_length:.6g} is not a multiple of {what} = {dt:.6g}; "
            f"{n} steps of {used:.6g} are taken"
        )
    return n


def _duration(seconds: float) -> str:
    for unit, size in (("years", 3.156e7), ("days", 86400.0), ("hours", 3600.0), ("min", 60.0)):
        if seconds >= size:
            return f"{seconds / size:.3g} {unit}"
    return f"{seconds:.3g} s"


def estimated_fine_seconds(scheme: str, steps: float, points: int) -> float:
    """A rough one-core estimate of ``steps`` steps of ``scheme`` with ``points`` points: rate
    evaluations times (overhead + (points)² Stokeslet pairs), from the measured rod step."""
    stages = integrate.SCHEMES[scheme].stages
    return steps * stages * (_EVAL_SECONDS + _PAIR_SECONDS * points**2)


def _cores(cfg: Config, workers: int, warnings: list[str]) -> None:
    """A note when the workers' threads outnumber this machine's cores (processes, serial)."""
    ex = cfg.execution
    cores = available_cores()
    if ex.executor == "mpi" or workers * ex.threads <= cores:
        return
    if ex.executor == "serial":
        fix = f"--set execution.threads={cores}"
    else:
        fix = f"--set execution.workers={max(1, cores // ex.threads)}"
        if ex.threads > 1:
            fix += f" (or execution.threads={max(1, cores // workers)})"
    warnings.append(
        f"execution: {workers} worker(s) x {ex.threads} thread(s) on {cores} cores: they take "
        f"turns on the cores, so the run is slower and its speedup lower than on enough cores; "
        f"pass {fix} here, or run it where there are {workers * ex.threads} cores"
    )


def _weight_sum(cfg: Config, lagrange: dict[str, list[float]], theta0: dict[str, float],
                steps: list[int], slice_length: float, issues: list) -> float:
    """Σ|w_j v_q| of eq. 30 (it factorizes over the parameters and the Richardson steps);
    appends an issue above ``coarse.max_weight_sum``."""
    total = 1.0
    for name, values in lagrange.items():
        if values:
            total *= float(abs(weights.lagrange_weights(theta0[name], values)).sum())
    if len(steps) > 1:
        order = integrate.scheme_order(cfg.coarse.scheme)
        total *= float(abs(weights.step_weights([slice_length / n for n in steps], order)).sum())
    bound = cfg.coarse.max_weight_sum
    if total > bound:
        issues.append(
            (
                "coarse.lagrange",
                f"the extrapolation weights have Σ|w_j v_q| = {total:.3g} > {bound:g}: the nodes "
                "are so close together (or to θ⁰) that the coarse solver multiplies round-off and "
                f"step errors by up to {total:.3g}; move the nodes apart, or raise "
                "coarse.max_weight_sum to force it",
            )
        )
    return total


def _workers(cfg: Config, n_auxiliary: int, issues: list, warnings: list) -> int | None:
    ex = cfg.execution
    if ex.executor == "serial":
        if ex.workers not in (None, 1):
            issues.append(
                ("execution.workers", f"the serial executor has 1 worker, not {ex.workers}")
            )
        _cores(cfg, 1, warnings)
        return 1
    workers = ex.workers
    if workers is None and ex.executor == "gpu":  # one batch holds every solve of a sweep
        workers = max(cfg.parareal.n_slices, n_auxiliary)
    if workers is None and ex.executor == "processes":
        workers = max(1, min(cfg.parareal.n_slices, available_cores() // ex.threads))
    if workers is None:  # mpi: all ranks of the launch, known only when the executor exists
        return None
    _cores(cfg, workers, warnings)
    problem = oversubscription(n_auxiliary, workers, cfg.parareal.schedule)
    if problem and not ex.allow_oversubscribe and cfg.run.mode != "serial":
        issues.append(
            (
                "execution.workers",
                f"{problem}; raise workers or set execution.allow_oversubscribe = true",
            )
        )
    if cfg.parareal.n_slices > workers and cfg.run.mode != "serial":
        warnings.append(
            f"parareal.n_slices: {cfg.parareal.n_slices} slices on {workers} workers: the "
            "parallel sweep runs in waves, while eq. 14 assumes one core per slice"
        )
    return workers


def resolve(cfg: Config, source: str = "") -> Resolved:
    """Check ``cfg`` across keys and compute the derived values; raise :class:`ConfigError`."""
    issues: list[tuple[str, str]] = []
    warnings: list[str] = []
    model = cfg.model
    try:
        body = model.resolve()
    except ValueError as error:  # a user section whose system rejects its values
        raise ConfigError([("model", str(error))], source) from None
    theta0, n_points = body.theta0, body.n_points

    t0, t1 = cfg.time.t0, cfg.time.t1
    if not t1 > t0:
        issues.append(("time.t1", f"must exceed t0 = {t0}, got {t1}"))
        raise ConfigError(issues, source)
    slice_length = (t1 - t0) / cfg.parareal.n_slices
    if cfg.fine.dt > slice_length * (1 + 1e-12):
        issues.append(
            ("fine.dt", f"exceeds the slice length (t1 - t0)/n_slices = {slice_length:.6g}")
        )
    total_steps = (t1 - t0) / cfg.fine.dt
    seconds = estimated_fine_seconds(cfg.fine.scheme, total_steps, n_points)
    if total_steps > MAX_FINE_STEPS:
        issues.append(
            (
                "fine.dt",
                f"{total_steps:.3g} fine steps over [t0, t1] (more than {MAX_FINE_STEPS:.0e}): the "
                f"serial fine solution would take about {_duration(seconds)} on one core; check "
                "fine.dt and time.t1 (units: s)",
            )
        )
        raise ConfigError(issues, source)
    if seconds > LONG_RUN_SECONDS:
        warnings.append(
            f"fine.dt: {total_steps:.3g} fine steps; the serial fine solution would take about "
            f"{_duration(seconds)} on one core (a rough estimate; Parareal divides it by at most "
            "its speedup)"
        )
    fine_steps = _steps(slice_length, cfg.fine.dt, "fine.dt", "τ_f", warnings)

    coarse = cfg.coarse
    if (coarse.dt is None) == (coarse.dt_ratio is None):
        issues.append(("coarse.dt", "give exactly one of coarse.dt and coarse.dt_ratio"))
    coarse_dt = coarse.dt if coarse.dt is not None else (coarse.dt_ratio or 1.0) * cfg.fine.dt
    m, r = coarse.richardson.m, coarse.richardson.r
    if m >= 1 and r is None:
        issues.append(("coarse.richardson.r", "required when m >= 1"))
    base_dt = coarse_dt / (r or 1.0) ** m
    coarse_steps = [
        _steps(slice_length, base_dt * (r or 1.0) ** q, "coarse.dt", "τ_c", None if m else warnings)
        for q in range(m + 1)
    ]
    try:  # the rule of eq. 27 where it lives: the weights of the steps actually taken
        weights.step_weights([slice_length / n for n in coarse_steps], 1)
    except ValueError:
        issues.append(
            (
                "coarse.richardson.r",
                f"the steps r^q τ give the step counts {coarse_steps} on a slice; they must all "
                "differ (choose r farther from 1 or a smaller coarse step)",
            )
        )
    if coarse_dt < cfg.fine.dt:
        warnings.append(f"coarse.dt: τ_c = {coarse_dt:.6g} is smaller than τ_f = {cfg.fine.dt:.6g}")

    lagrange = {}
    for name in coarse.lagrange:
        if name not in theta0:
            issues.append(
                (
                    f"coarse.lagrange.{name}",
                    f"unknown parameter; a {model.kind} model extrapolates in "
                    f"{', '.join(theta0)}",
                )
            )
            continue
        lagrange[name] = _node_values(cfg, name, theta0[name], issues)
    n_auxiliary = math.prod(len(spec.nodes) for spec in coarse.lagrange.values()) * (m + 1)
    weight_sum = 1.0
    if not issues:
        weight_sum = _weight_sum(cfg, lagrange, theta0, coarse_steps, slice_length, issues)

    coarse_points = n_points
    if coarse.grid_factor > 1:
        try:
            coarse_points = model.coarse_points(coarse.grid_factor)
        except ValueError as error:
            issues.append(("coarse.grid_factor", str(error)))

    every = cfg.output.every
    if every is not None and every % fine_steps and fine_steps % every:
        issues.append(
            (
                "output.every",
                f"must be a multiple or a divisor of the {fine_steps} fine steps per slice, "
                f"got {every}",
            )
        )
    tracked = cfg.output.tracked_points
    if tracked:
        if not model.tracks_points():
            issues.append(
                ("output.tracked_points", f"a {model.kind} model marks no points (vesicles only)")
            )
        elif max(tracked) >= n_points:
            issues.append(("output.tracked_points", f"indices must be below {n_points}"))

    workers = _workers(cfg, n_auxiliary, issues, warnings)
    if issues:
        raise ConfigError(issues, source)
    return Resolved(
        epsilon=theta0.get("epsilon", math.nan),
        grid_spacing=body.grid_spacing,
        n_points=n_points,
        theta0=theta0,
        slice_length=slice_length,
        fine_dt=cfg.fine.dt,
        fine_steps=fine_steps,
        coarse_dt=coarse_dt,
        coarse_base_dt=base_dt,
        coarse_steps=coarse_steps,
        coarse_points=coarse_points,
        lagrange=lagrange,
        n_auxiliary=n_auxiliary,
        workers=workers,
        warnings=warnings,
        weight_sum=weight_sum,
    )


def resolved_dict(cfg: Config, resolved: Resolved) -> dict[str, Any]:
    """The resolved configuration stored with every result: all keys with defaults filled in, plus
    the derived absolute values under ``"resolved"``."""
    return {**cfg.model_dump(mode="json"), "resolved": asdict(resolved)}
