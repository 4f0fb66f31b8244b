"""Checks across keys and the values they resolve to (absolute ε, nodes, steps, workers).

Everything here is cheap (no solver is built), so ``parastokes check`` and every run catch a bad
configuration before any expensive work. The rules are the paper's:

- the ``[coarse]`` section resolves itself by the rules of its family (:mod:`parastokes.coarse`;
  the extrapolated G's Lagrange nodes, Richardson step counts and weight sum:
  :mod:`parastokes.coarse.extrapolated`);
- N_G auxiliary solvers run at once only with N_G workers: more is an error unless
  ``execution.allow_oversubscribe`` (Algorithm 1 assumes N_G <= N_c), or with
  ``parareal.schedule = "pipelined"`` (its auxiliary solves wait for workers like any task).

And what cannot work or will not end in reasonable time:

- a serial fine solution of more than 10¹² steps is refused, and one estimated (from the points
  and steps, :func:`estimated_fine_seconds`) to take more than a day on one core gets a note;
- more workers x threads than the cores of this machine gets a note naming what to pass instead;
- a problem whose states (and the dense mobility matrices of its rigid bodies) cannot fit in this
  machine's memory (:func:`estimated_bytes`, a lower bound) is refused before anything is
  allocated: for a kind that builds its body to resolve it, from its keys alone
  (:meth:`~parastokes.registry.kinds.BodySection.planned_size`).
"""

from __future__ import annotations

import math
import os
from dataclasses import asdict, dataclass, field
from typing import Any

from .. import integrate
from ..core.contracts import oversubscription
from ..parallel import available_cores
from ..registry.kinds import PlannedSize
from .errors import ConfigError
from .schema import MAX_FLOW_COORDINATE, Config

__all__ = [
    "Resolved", "estimated_bytes", "estimated_fine_seconds", "physical_memory", "resolve",
    "resolved_dict", "steps_on_slice",
]

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
    an ε in Θ). The coarse fields (``coarse_*``, ``lagrange``, ``n_auxiliary``, ``weight_sum``)
    are the :class:`~parastokes.registry.coarse.CoarseResolution` of the ``[coarse]`` family.
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
    threads: int = 1


def kernel_threads(cfg: Config) -> int:
    """The kernel threads of the system this process builds: ``execution.threads``, or, for a
    run of ``run.mode = "serial"`` that does not set it, every available core (no workers share
    them then; the kernels give the same numbers on any thread count)."""
    given = "threads" in cfg.execution.model_fields_set
    return cfg.execution.threads if given or cfg.run.mode != "serial" else available_cores()


def steps_on_slice(slice_length: float, dt: float, path: str, what: str,
                   warnings: list[str] | None) -> int:
    """Steps of size about ``dt`` on a slice; warns (unless ``warnings`` is None) when dt does
    not divide it (Richardson steps r^q τ rarely do; eq. 27's weights are computed for the steps
    taken)."""
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
    stages = integrate.lookup(scheme).stages
    return steps * stages * (_EVAL_SECONDS + _PAIR_SECONDS * points**2)


def estimated_bytes(cfg: Config, n_points: int, dense_bytes: float = 0.0) -> float:
    """A lower bound on the memory of a run: its states counted at 3 doubles per point (the
    positions; rods hold 12), the Parareal iterates, coarse and fine values at every slice
    boundary (3 (N_c + 1)), the serial solution (N_c + 1) and the stages of one step; plus
    ``dense_bytes``, the dense matrices its solves factorize (rigid bodies)."""
    slices = cfg.parareal.n_slices + 1
    states = 3 * slices + slices + integrate.lookup(cfg.fine.scheme).stages + 2
    return 24.0 * n_points * states + dense_bytes


def physical_memory() -> float:
    """This machine's memory in bytes (inf where the system does not say)."""
    try:
        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return math.inf


def _memory(cfg: Config, size: PlannedSize, issues: list[tuple[str, str]]) -> None:
    """An issue when the run's states and dense matrices cannot fit in memory
    (:func:`estimated_bytes`), naming the keys that set the size."""
    needed, memory = estimated_bytes(cfg, size.rows, size.dense_bytes), physical_memory()
    if not needed > memory:
        return
    what = "states alone need" if not size.dense_bytes else (
        f"states and the dense mobility matrices of its rigid surfaces (each surface's (3N)² "
        f"doubles and their LU factors, {size.dense_bytes / 2**30:.3g} GiB in all) need")
    key = size.keys if size.keys == "bodies" else ", ".join(
        f"model.{k.strip()}" for k in size.keys.split(","))
    issues.append((key, f"{size.rows} points: the run's {what} more than "
                        f"{needed / 2**30:.3g} GiB, and this machine has {memory / 2**30:.3g} "
                        "GiB; use fewer points or slices"))


def _flow_plane_issue(cfg: Config) -> str | None:
    """What is wrong with ``output.flow_plane`` (checked here, before the run, as ``parastokes
    flow --plane`` checks its own): a value that is not a number, beyond
    :data:`~.schema.MAX_FLOW_COORDINATE`, or below the wall z = 0."""
    text = cfg.output.flow_plane
    if text is None:
        return None
    axis, _, value = text.partition("=")
    try:
        number = float(value)
    except ValueError:
        number = math.nan
    if not abs(number) <= MAX_FLOW_COORDINATE:
        return (f"{text!r}: give AXIS=VALUE with a number of at most {MAX_FLOW_COORDINATE:g} "
                'μm, e.g. "y=0"')
    if axis.strip().lower() == "z" and number < 0 and getattr(cfg.model, "wall", False):
        return f"{text!r} is below the wall z = 0 (no fluid there); choose z >= 0"
    return None


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


def _gpu_issue(cfg: Config) -> str | None:
    """Why the GPU executor of ``cfg`` cannot start here (no CUDA device and no simulator, or no
    numba-cuda: :func:`parastokes.gpu.device.missing`), or None. A run of ``run.mode =
    "serial"`` starts no executor."""
    if cfg.execution.executor != "gpu" or cfg.run.mode == "serial":
        return None
    from ..gpu.device import missing

    reason = missing()
    return None if reason is None else (
        f'"gpu": {reason}; or use executor = "processes" here')


def _workers(cfg: Config, n_auxiliary: int, issues: list, warnings: list) -> int | None:
    ex = cfg.execution
    gpu = _gpu_issue(cfg)
    if gpu:
        issues.append(("execution.executor", gpu))
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


def _stiff_issues(cfg: Config) -> list[tuple[str, str]]:
    """The adaptive steps' tolerances (finite, positive, a scheme with an error estimate). (Any
    executor runs the linearly implicit schemes: the GPU's hosts their solves,
    :mod:`parastokes.gpu.hosted`.)"""
    issues = []
    fine = cfg.fine
    if fine.rtol is not None or fine.atol is not None:
        if fine.rtol is None:
            issues.append(("fine.rtol", "required with fine.atol (adaptive steps)"))
        else:
            try:
                integrate.tolerances(fine.scheme, fine.rtol, fine.atol)
            except ValueError as error:
                key, _, text = str(error).partition(": ")
                issues.append((f"fine.{key}", text))
    issues += _fixed_pair_issues(cfg)
    return issues


def _fixed_pair_issues(cfg: Config) -> list[tuple[str, str]]:
    """An embedded explicit pair (rk23, rk45) or "auto" without ``rtol`` in ``[fine]`` or
    ``[coarse]``: "auto" takes adaptive steps only, and a pair on a fixed step is its high-order
    tableau with an estimate nobody reads."""
    issues = []
    for key, section in (("fine", cfg.fine), ("coarse", cfg.coarse)):
        scheme = getattr(section, "scheme", None)
        if scheme not in (*integrate.SCHEMES, integrate.AUTO.name):
            continue
        s = integrate.lookup(scheme)
        if s.adaptive and not s.implicit and getattr(section, "rtol", None) is None:
            issues.append((f"{key}.rtol", f"required by the scheme {scheme!r} (adaptive steps); "
                           "give rtol, or a fixed-step scheme such as rk4"))
    return issues


def _fine_steps_issue(cfg: Config, n_points: int, warnings: list[str]) -> str | None:
    """What is wrong with the fine steps over [t0, t1] (more than :data:`MAX_FINE_STEPS`), and a
    note (into ``warnings``) when the serial fine solution would take more than
    :data:`LONG_RUN_SECONDS` on one core. Adaptive steps (``fine.rtol``) are neither: their
    number is set by the tolerance, not by ``fine.dt`` (the first step tried)."""
    if cfg.fine.rtol is not None:
        return None
    total_steps = (cfg.time.t1 - cfg.time.t0) / cfg.fine.dt
    seconds = estimated_fine_seconds(cfg.fine.scheme, total_steps, n_points)
    if total_steps > MAX_FINE_STEPS:
        return (f"{total_steps:.3g} fine steps over [t0, t1] (more than {MAX_FINE_STEPS:.0e}): "
                f"the serial fine solution would take about {_duration(seconds)} on one core; "
                "check fine.dt and time.t1 (units: s)")
    if seconds > LONG_RUN_SECONDS:
        warnings.append(
            f"fine.dt: {total_steps:.3g} fine steps; the serial fine solution would take about "
            f"{_duration(seconds)} on one core (a rough estimate; Parareal divides it by at most "
            "its speedup)"
        )
    return None


def resolve(cfg: Config, source: str = "") -> Resolved:
    """Check ``cfg`` across keys and compute the derived values; raise :class:`ConfigError`."""
    issues: list[tuple[str, str]] = []
    warnings: list[str] = []
    model = cfg.model
    where = "bodies" if model.kind == "scene" else "model"
    try:
        planned = model.planned_size()
        if planned is not None:  # the body is built to resolve it: refused before if too large
            _memory(cfg, planned, issues)
            if issues:
                raise ConfigError(issues, source)
        body = model.resolve()
    except ValueError as error:  # a user section whose system rejects its values
        if isinstance(error, ConfigError):
            raise
        raise ConfigError([(where, str(error))], source) from None
    theta0, n_points = body.theta0, body.n_points
    _memory(cfg, PlannedSize(n_points, planned.dense_bytes if planned else 0.0), issues)
    if issues:
        raise ConfigError(issues, source)

    t0, t1 = cfg.time.t0, cfg.time.t1
    if not t1 > t0:
        issues.append(("time.t1", f"must exceed t0 = {t0}, got {t1}"))
        raise ConfigError(issues, source)
    slice_length = (t1 - t0) / cfg.parareal.n_slices
    issues += _stiff_issues(cfg)
    if cfg.fine.dt > slice_length * (1 + 1e-12):
        issues.append(
            ("fine.dt", f"exceeds the slice length (t1 - t0)/n_slices = {slice_length:.6g}")
        )
    too_many = _fine_steps_issue(cfg, n_points, warnings)
    if too_many:
        issues.append(("fine.dt", too_many))
        raise ConfigError(issues, source)
    fine_steps = steps_on_slice(slice_length, cfg.fine.dt, "fine.dt", "τ_f", warnings)

    coarse = cfg.coarse.resolve(cfg, body, slice_length, issues, warnings)

    every = cfg.output.every
    if every is not None and every % fine_steps and fine_steps % every:
        issues.append(
            (
                "output.every",
                f"must be a multiple or a divisor of the {fine_steps} fine steps per slice, "
                f"got {every}",
            )
        )
    issues += [("output.tracked_points", issue)
               for issue in model.tracked_issues(cfg.output.tracked_points, n_points)]
    if cfg.output.flow_every is not None and not cfg.output.trajectory:
        issues.append(("output.flow_every", "the flow is computed from the saved frames: set "
                                            "output.trajectory = true or remove flow_every"))
    plane = _flow_plane_issue(cfg)
    if plane:
        issues.append(("output.flow_plane", plane))

    if cfg.parareal.correction == "secant" and getattr(cfg.coarse, "kind", None) == "hodmd":
        issues.append(("parareal.correction", "'secant' adds to G(new) - G(old), which the hodmd "
                       "coarse solver replaces by its own correction: use \"classical\""))
    workers = _workers(cfg, coarse.n_auxiliary, issues, warnings)
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
        workers=workers,
        warnings=warnings,
        threads=kernel_threads(cfg),
        **asdict(coarse),
    )


def resolved_dict(cfg: Config, resolved: Resolved) -> dict[str, Any]:
    """The resolved configuration stored with every result: all keys with defaults filled in, plus
    the derived absolute values under ``"resolved"``."""
    return {**cfg.model_dump(mode="json"), "resolved": asdict(resolved)}
