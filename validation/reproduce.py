"""The paper's section 5 at full scale: plan, cost, run (resumable, in the background), collect.

The iterates of Parareal do not depend on how many cores run them, so every error curve η^k of the
paper (T = 1, N_c = 40 for the rod; T = 100, N_c = 40 for the vesicle) is reproduced exactly on
one core with the serial executor; only the wall time is longer. The speedups for the paper's 40
cores follow from eq. 14 with γ_G/γ_F measured per solver by a probe that times each auxiliary
coarse solve and each fine slice on its own (:func:`probe`).

Every run goes through the runner's public entry point (``runner.execute``, as ``parastokes run
CONFIG --out DIR --resume``) with ``execution.executor = "serial"``. The serial fine reference of
a problem (model, time, fine solver, N_c) is computed once, as a ``run.mode = "serial"`` run of its
first configuration in ``ROOT/references/NAME``, and its ``reference.npz`` is copied into the
directory of every run that shares it before ``execute(..., resume=True)``: the runner reloads it
when its key matches (and recomputes it otherwise, so a mismatch costs time, never correctness).

Layout of the output root (default ``repro-runs`` beside the checkout, outside the git tree;
nothing there is committed): ``references/REF/``, ``runs/NAME/`` (the runner's files plus
``progress.json``, ``probe.json`` and ``result.json``, the compact summary that
:mod:`validation.reproduce_report` gathers into ``docs/reproduction/NAME.json``),
``logs/NAME.log``, ``scheduler.json`` (pid and state of the background scheduler) and
``status.txt``.

Usage (from the repository root, ``PYTHONPATH=$PWD``)::

    python -m validation.reproduce --dry-run                 # plan and cost of every run
    nohup nice -n 19 env NUMBA_NUM_THREADS=1 python -m validation.reproduce --resume --jobs 2 \\
        > OUT_ROOT/scheduler.log 2>&1 &                      # run (resumes after any stop)
    python -m validation.reproduce --status                  # done / running / not started
    python -m validation.reproduce --collect                 # finished runs -> docs/reproduction/

``--only NAME...`` restricts the runs, ``--status`` and ``--dry-run`` to runs, references or
figure groups (``fig5``, ``fig12``...); a run brings its reference along. ``--collect`` gathers
every finished run and refuses ``--only``.
"""

from __future__ import annotations

import argparse
import fcntl
import json
import math
import os
import resource
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parent.parent
EXPERIMENTS = REPO / "experiments"
#: The output root: ``repro-runs`` in the folder that holds the checkout (outside the git tree).
DEFAULT_ROOT = REPO.parent / "repro-runs"
#: Paper's core count: the speedups of Figs. 6-8, 12, 13 are for 40 cores, one slice each.
PAPER_CORES = 40
#: Every run here: one core, in-process sweeps (the iterates are those of any executor).
OVERRIDES = (
    "execution.executor='serial'",
    "execution.workers=1",
    "execution.threads=1",
    "output.figures=false",
)


# ---- the plan ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Job:
    """One unit of background work: a serial reference (``reference`` is None) or a Parareal run.

    ``config`` is a file of ``experiments/``; ``group`` the paper's figure; ``reference`` the
    name of the reference job whose ``reference.npz`` the run reuses; ``optional`` runs are done
    only when named; ``reachable`` is False for runs beyond two shared cores (dry run only).
    """

    name: str
    config: str
    group: str
    reference: str | None = None
    optional: bool = False
    reachable: bool = True
    overrides: tuple[str, ...] = field(default=())

    @property
    def is_reference(self) -> bool:
        return self.reference is None


def _runs(names: Iterable[str], group: str, reference: str, **kw: Any) -> list[Job]:
    return [Job(n, f"{n}.toml", group, reference, **kw) for n in names]


def plan() -> list[Job]:
    """Every job, in the order the scheduler starts them (dependencies permitting).

    The vesicle comes first on one lane (its cheapest runs first, by the dry run's cost) while the
    rod's ε⁰ = 5 σ_f reference, the longest single job, starts at once on the other. Fig. 5's
    G_{ε⁰,τ_c} line is η¹ of Table 4 G⁴ (the same solver, τ_c = 10 τ_f;
    ``experiments/s511_plain.toml`` is that run stopped after one iteration), so it is not run
    twice, and Table 4 G⁴ comes before Fig. 5's other runs.
    """
    fig5 = [f"table3_g{g}_n{n}" for g in (3, 4) for n in range(2, 7)]
    return [
        Job("ref_table7", "table7_g1.toml", "fig12"),
        Job("ref_rod_eps5", "table4_g1.toml", "fig5"),
        *_runs(["table7_g4"], "fig12", "ref_table7"),
        Job("ref_table8", "table8_g1.toml", "fig13"),
        *_runs(["table8_g1"], "fig13", "ref_table8"),
        *_runs(["table7_g3"], "fig12", "ref_table7"),
        *_runs(["table8_g3", "table8_g2"], "fig13", "ref_table8"),
        *_runs(["table7_g1", "table7_g2"], "fig12", "ref_table7"),
        *_runs(["table4_g4"], "fig6", "ref_rod_eps5"),
        *_runs(fig5, "fig5", "ref_rod_eps5"),
        *_runs(["table4_g1", "table4_g2", "table4_g3"], "fig6", "ref_rod_eps5"),
        Job("ref_rod_eps7", "table5_g1.toml", "fig7"),
        *_runs([f"table5_g{g}" for g in range(1, 4)], "fig7", "ref_rod_eps7"),
        *_runs(["table3_g1", "table3_g2"], "fig4", "ref_rod_eps5", optional=True),
        Job("ref_rod_eps3", "table6_eps3.toml", "fig8", optional=True),
        *_runs(["table6_eps3"], "fig8", "ref_rod_eps3", optional=True),
        Job("ref_rod_eps2", "table6_eps2.toml", "fig8", optional=True, reachable=False),
        *_runs(["table6_eps2"], "fig8", "ref_rod_eps2", optional=True, reachable=False),
        Job("ref_five_rods", "s514_five_rods.toml", "fig10", optional=True, reachable=False),
        *_runs(
            ["s514_five_rods"],
            "fig10",
            "ref_five_rods",
            optional=True,
            reachable=False,
            overrides=(
                "parareal.n_slices=40",
                "parareal.max_iterations=4",
                "parareal.tol=0",
                "run.mode='both'",
            ),
        ),
    ]


def select(
    jobs: Sequence[Job], only: Sequence[str] | None, optional: bool = False
) -> list[Job]:
    """The jobs named in ``only`` (names or figure groups) with their references, in plan order;
    without ``only`` every required, reachable job (and the optional ones with ``optional``).
    Raises ValueError naming unknown names."""
    by_name = {j.name: j for j in jobs}
    if not only:
        return [j for j in jobs if j.reachable and (optional or not j.optional)]
    groups = {j.group for j in jobs}
    unknown = sorted(set(only) - set(by_name) - groups)
    if unknown:
        raise ValueError(
            f"--only: unknown name(s) {unknown}; known runs and references: "
            f"{', '.join(by_name)}; figure groups: {', '.join(sorted(groups))}"
        )
    wanted = {j.name for j in jobs if j.name in only or j.group in only}
    wanted |= {ref for n in wanted if (ref := by_name[n].reference)}
    return [j for j in jobs if j.name in wanted]


def load_config(job: Job, layout: Layout) -> tuple[Any, Any]:
    """The job's configuration (from ``layout.experiments``) with this module's overrides (serial
    executor, one thread) and the layout's extra ones; a reference gets ``run.mode = "serial"``."""
    from parastokes import config

    overrides = [*OVERRIDES, *job.overrides, *layout.overrides]
    if job.is_reference:
        overrides.append("run.mode='serial'")
    return config.load(layout.experiments / job.config, overrides)


# ---- where things are --------------------------------------------------------------------------
@dataclass(frozen=True)
class Layout:
    """Paths under the output root, and where the configurations come from: ``experiments``
    (``experiments/quick`` holds small variants of the same names) with ``overrides`` applied to
    every job (``--set``)."""

    root: Path
    experiments: Path = EXPERIMENTS
    overrides: tuple[str, ...] = ()

    def directory(self, job: Job) -> Path:
        return self.root / ("references" if job.is_reference else "runs") / job.name

    def log(self, job: Job) -> Path:
        return self.root / "logs" / f"{job.name}.log"

    def done(self, job: Job) -> Path:
        """Written last by a finished job: the reference's summary, a run's result."""
        return self.directory(job) / ("done.json" if job.is_reference else "result.json")

    @property
    def scheduler(self) -> Path:
        return self.root / "scheduler.json"

    @property
    def status(self) -> Path:
        return self.root / "status.txt"


def _write_json(path: Path, data: Any) -> None:
    """``data`` as indented JSON, written atomically (a reader never sees half a file)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=1, allow_nan=False) + "\n", encoding="utf-8")
    os.replace(tmp, path)


def _read_json(path: Path) -> Any:
    return json.loads(path.read_text(encoding="utf-8")) if path.exists() else None


# ---- cost: fine steps, CPU time, memory ----------------------------------------------------------
def work(cfg: Any, resolved: Any, reference: bool) -> dict[str, int]:
    """Fine steps and coarse slice solves (G calls) of a job: a reference takes N_c slices of
    fine steps; K iterations of Parareal take sum_{k=1}^K (N_c - k + 1) fine slices (eq. 10) and
    sum_{k=0}^K (N_c - k) G calls (eqs. 9, 11), plus the probe's two fine slices and one G call."""
    n, steps = cfg.parareal.n_slices, resolved.fine_steps
    if reference:
        return {"fine_steps": n * steps, "coarse_calls": 0}
    k = min(cfg.parareal.max_iterations, n)
    fine_slices = sum(n - i + 1 for i in range(1, k + 1)) + 2
    return {"fine_steps": fine_slices * steps, "coarse_calls": sum(n - i for i in range(k + 1)) + 2}


def _timed(fn: Any, *args: Any) -> tuple[Any, float]:
    start = time.perf_counter()
    value = fn(*args)
    return value, time.perf_counter() - start


def measure_rates(setup: Any, fine_steps: int = 20, coarse_steps: int = 12) -> dict[str, float]:
    """Seconds per fine step and per coarse step of the whole combinator (all N_G auxiliary
    solvers one after the other, as on one core), from short propagations of x0."""
    resolved = setup.resolved
    x0 = setup.system.initial_state()
    setup.fine(0.0, resolved.fine_dt, x0)  # first call of this propagator: not timed
    _, fine = _timed(setup.fine, 0.0, fine_steps * resolved.fine_dt, x0)
    span = coarse_steps * resolved.coarse_base_dt  # the largest auxiliary step, τ = τ_c / r^m
    _, coarse = _timed(setup.coarse, 0.0, span, x0)
    return {"fine_step": fine / fine_steps, "coarse_per_time": coarse / span}


def cost(job: Job, layout: Layout, rates_cache: dict[str, dict[str, float]]) -> dict[str, Any]:
    """The job's work, CPU time on one core (from rates measured here and now), memory, and for
    runs the 40-core picture (eq. 12 wall time, core-hours)."""
    from parastokes import parareal
    from parastokes.config import build

    cfg, resolved = load_config(job, layout)
    w = work(cfg, resolved, job.is_reference)
    key = job.config
    if key not in rates_cache:
        setup = build(cfg, resolved)
        size = setup.system.initial_state().size
        rates_cache[key] = {**measure_rates(setup), "state_size": size}
    rates = rates_cache[key]
    slice_length = (cfg.time.t1 - cfg.time.t0) / cfg.parareal.n_slices
    fine_s = w["fine_steps"] * rates["fine_step"]
    coarse_call = rates["coarse_per_time"] * slice_length
    cpu = fine_s + w["coarse_calls"] * coarse_call
    state_bytes = 8 * rates["state_size"]
    out: dict[str, Any] = {
        "name": job.name,
        "kind": "reference" if job.is_reference else "parareal",
        "group": job.group,
        **w,
        "cpu_hours_1core": cpu / 3600,
        "state_mb": state_bytes / 2**20,
        "arrays_mb": 6 * (cfg.parareal.n_slices + 1) * state_bytes / 2**20,
        "done": layout.done(job).exists(),
    }
    if not job.is_reference:
        gamma_f = resolved.fine_steps * rates["fine_step"]
        gamma_g = coarse_call / resolved.n_auxiliary  # its N_G solvers at once on 40 cores
        k = min(cfg.parareal.max_iterations, cfg.parareal.n_slices)
        wall = parareal.parareal_runtime(gamma_g, gamma_f, k, cfg.parareal.n_slices)
        out["wall_hours_40cores"] = wall / 3600
        out["core_hours_40cores"] = PAPER_CORES * wall / 3600
    return out


def dry_run(jobs: Sequence[Job], layout: Layout) -> list[dict[str, Any]]:
    """Print and return the cost of every job (rates measured on this machine, one core)."""
    rates: dict[str, dict[str, float]] = {}
    rows = [cost(job, layout, rates) for job in jobs]
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(
        f"{'job':<16} {'group':<6} {'fine steps':>11} {'G calls':>8} {'CPU h (1 core)':>14} "
        f"{'arrays MB':>9} {'40 cores: wall h':>16} {'core-h':>7}  state"
    )
    for job, row in zip(jobs, rows, strict=True):
        state = "done" if row["done"] else ("out of reach here" if not job.reachable else "")
        wall = row.get("wall_hours_40cores")
        print(
            f"{job.name:<16} {job.group:<6} {row['fine_steps']:>11.3g} {row['coarse_calls']:>8} "
            f"{row['cpu_hours_1core']:>14.2f} {row['arrays_mb']:>9.1f} "
            f"{'' if wall is None else f'{wall:16.2f}'} "
            f"{'' if wall is None else format(row['core_hours_40cores'], '7.1f')}  {state}"
        )
    todo = [r for j, r in zip(jobs, rows, strict=True) if j.reachable and not r["done"]]
    print(
        f"to do here: {len(todo)} jobs, {sum(r['cpu_hours_1core'] for r in todo):.1f} CPU hours "
        f"on one core at this moment's speed; peak memory of this process {rss:.0f} MB (one "
        "process per job here; a 40-core run holds one such process per core)"
    )
    return rows


# ---- one job -----------------------------------------------------------------------------------
class ProgressFile:
    """A runner reporter that logs every event and keeps ``progress.json`` current."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.state: dict[str, Any] = {"phase": None, "done": 0, "total": 0, "iterations": []}
        old = _read_json(path)
        if old:
            self.state["iterations"] = old.get("iterations", [])

    def _save(self) -> None:
        self.state["updated"] = time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime())
        _write_json(self.path, self.state)

    def note(self, text: str) -> None:
        print(text, flush=True)

    def warn(self, text: str) -> None:
        print(f"warning: {text}", file=sys.stderr, flush=True)

    def start(self, what: str, total: int, done: int = 0) -> None:
        self.state.update(phase=what, done=done, total=total)
        print(f"{what}: {total} {'slices' if what == 'serial' else 'iterations'}", flush=True)
        self._save()

    def expect(self, seconds: float) -> None:
        """The runner's estimate of one step (for an ETA): the log's timestamps tell it here."""

    def advance(self) -> None:
        self.state["done"] += 1
        self._save()

    def finish(self) -> None:
        print(f"{self.state['phase']} finished", flush=True)

    def iteration(self, k: int, increment: float, error: float | None, elapsed: float) -> None:
        rows = [r for r in self.state["iterations"] if r["k"] < k]
        rows.append({"k": k, "increment": increment, "error": error, "elapsed": elapsed})
        self.state["iterations"] = rows
        err = "-" if error is None else f"{error:.3e}"
        print(f"k = {k}: η̃ {increment:.3e}, η {err}, elapsed {elapsed:.1f} s", flush=True)
        self._save()


PROBE_METHOD = "slice-costs-cpu"


def probe(setup: Any, times: np.ndarray, x0: np.ndarray, repeats: int = 3) -> dict[str, Any]:
    """γ_F and γ_G for the paper's 40 cores, each solve timed on its own, on the first slice.

    :func:`parastokes.parareal.measure_slice_costs` in this process's CPU time (a shared machine
    stretches wall times, not CPU times): per repeat, back to back, the fine solver over 200 and
    400 steps, every auxiliary solver over 50 steps of the largest auxiliary step, each scaled to
    the slice by its step count, and the combination (weighted sum of eq. 30, projection, grid
    transfer) timed on its own. On 40 cores the N_G <= 40 auxiliaries run at once, so
    γ_G = max(auxiliary) + combination; ``gamma_ratio`` is the median over repeats of γ_G/γ_F.
    """
    from parastokes import parareal

    costs = parareal.measure_slice_costs(
        setup.fine,
        setup.coarse,
        float(times[0]),
        float(times[1]),
        x0,
        repeats=repeats,
        clock=time.process_time,
    )
    found = costs.as_dict()
    found["gamma_ratio"] = costs.gamma_ratio(PAPER_CORES)
    found["method"] = PROBE_METHOD
    return found


def current_probe(job: Job, layout: Layout) -> dict[str, Any]:
    """The run's ``probe.json``, measured again when it was made by an older method (kept beside
    it as ``probe.METHOD.json``); with no probe yet, the first one."""
    from parastokes import parareal
    from parastokes.config import build

    path = layout.directory(job) / "probe.json"
    found = _read_json(path)
    if found is not None and found.get("method") == PROBE_METHOD:
        return found
    if found is not None:
        _write_json(path.with_name(f"probe.{found.get('method', 'wallclock-v1')}.json"), found)
    print(f"{job.name} probe: timing one fine slice and each auxiliary solve on its own",
          flush=True)
    cfg, resolved = load_config(job, layout)
    times = parareal.time_points(cfg.time.t0, cfg.time.t1, cfg.parareal.n_slices)
    setup = build(cfg, resolved)
    found = probe(setup, times, setup.system.initial_state())
    _write_json(path, found)
    return found


def speedup_curve(errors: Sequence[float], ratio: float, n_slices: int) -> dict[str, Any]:
    """Eq. 14 at N_c = ``n_slices`` for N_it = 1..K, and the steps of Fig. 6b: the speedup for a
    desired error e is that of N_it(e) = min{k >= 1: η^k <= e} (at least one iteration)."""
    from parastokes import parareal

    ks = list(range(1, len(errors) + 1))
    speedups = [parareal.speedup(ratio, 1.0, k, n_slices) for k in ks]
    steps = []  # (error threshold, speedup): valid for desired errors >= threshold
    best = math.inf
    for k, (e, s) in enumerate(zip(errors, speedups, strict=True), start=1):
        if e is not None and e < best:
            steps.append({"error": e, "iterations": k, "speedup": s})
            best = e
    return {"n_cores": n_slices, "iterations": ks, "speedup": speedups, "steps": steps}


def result_summary(
    job: Job, layout: Layout, summary: dict[str, Any], found: dict[str, Any]
) -> dict[str, Any]:
    """The compact record of a finished run (``docs/reproduction/NAME.json``)."""
    conf = summary["config"]
    timings = summary["timings"]
    fine = [t for sweep in timings.get("fine", []) for t in sweep]
    coarse = [t for sweep in timings.get("coarse", []) for t in sweep]
    n_aux = found["n_auxiliary"]
    errors = summary["errors"] or []
    ratio_run = (np.mean(coarse) / n_aux) / np.mean(fine) if fine and coarse else None
    return {
        "name": job.name,
        "group": job.group,
        "title": summary["title"],
        "config": _shown(layout.experiments / job.config),
        "overrides": [*OVERRIDES, *job.overrides, *layout.overrides],
        "problem": {
            key: conf.get(key)
            for key in ("model", "time", "fine", "coarse", "parareal")
            if key in conf
        },
        "iterations": summary["iterations"],
        "errors": errors,
        "increments": summary["increments"],
        "probe": found,
        "gamma_ratio": found["gamma_ratio"],
        "gamma_ratio_run_estimate": ratio_run,
        "speedup_40": speedup_curve(errors, found["gamma_ratio"], PAPER_CORES),
        "one_core": {
            "serial_fine_s": timings.get("serial_fine"),
            "parareal_s": timings.get("total"),
            "fine_slice_mean_s": float(np.mean(fine)) if fine else None,
            "coarse_call_mean_s": float(np.mean(coarse)) if coarse else None,
        },
        "monitor": summary["monitor"],
        "stop_reason": summary["stop_reason"],
        "finished": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
        "versions": summary["versions"],
    }


def serial_reference(cfg: Any, resolved: Any, directory: Path, reporter: ProgressFile) -> float:
    """The serial fine solution at T_0..T_N in ``directory/reference.npz``, as the runner writes
    it (``runner.REFERENCE``: its states and wall time under the key of the fine problem), computed
    slice by slice with ``partial.npz`` saved after each, so that a stop loses at most one slice.

    The states are those of the runner's serial run bit for bit (the same fine propagator on the
    same slices), under the key of the fine problem (``runner.fine_identity``), which the runner
    accepts in every run of that problem, whatever its coarse solver. Returns the wall time of
    the whole solve (summed over sessions).
    """
    from parastokes import parareal
    from parastokes import run as runner
    from parastokes.config import build
    from parastokes.output import trajectory as io

    path, partial = directory / runner.REFERENCE, directory / "partial.npz"
    if path.exists():
        return float(io.load_arrays(path)[0]["wall_time"])
    times = parareal.time_points(cfg.time.t0, cfg.time.t1, cfg.parareal.n_slices)
    fine_key = runner.fine_identity(cfg)
    setup = build(cfg, resolved)
    states = np.empty((len(times), *setup.system.initial_state().shape))
    done, wall = 0, 0.0
    if partial.exists():
        meta, arrays = io.load_arrays(partial)
        if meta["key"] == fine_key:
            done, wall = int(meta["done"]), float(meta["wall_time"])
            states[: done + 1] = arrays["states"][: done + 1]
            reporter.note(f"serial fine solution resumed after slice {done}")
    if done == 0:
        states[0] = setup.system.initial_state()
    reporter.start("serial", len(times) - 1, done)
    for n in range(done + 1, len(times)):
        states[n], seconds = _timed(setup.fine, times[n - 1], times[n], states[n - 1])
        wall += seconds
        meta = {"key": fine_key, "done": n, "wall_time": wall}
        io.save_arrays(partial, meta, states=states[: n + 1])
        reporter.advance()
    reporter.finish()
    meta = {"key": fine_key, "done": len(times) - 1, "wall_time": wall}
    io.save_arrays(path, meta, states=states)
    partial.unlink()
    return wall


def _shown(path: Path) -> str:
    """A path relative to the repository when inside it."""
    try:
        return str(path.resolve().relative_to(REPO))
    except ValueError:
        return str(path)


def run_job(job: Job, layout: Layout) -> None:
    """Do one job to the end, resuming whatever its directory holds (the runner's checkpoint, a
    finished reference, a finished probe)."""
    from parastokes import run as runner

    directory = layout.directory(job)
    directory.mkdir(parents=True, exist_ok=True)
    if layout.done(job).exists():
        print(f"{job.name}: already done", flush=True)
        return
    cfg, resolved = load_config(job, layout)
    reporter = ProgressFile(directory / "progress.json")
    if job.reference is None:  # (job.is_reference)
        wall = serial_reference(cfg, resolved, directory, reporter)
        _write_json(layout.done(job), {"serial_fine_s": wall})
        return
    ref = layout.directory(Job(job.reference, "", job.group)) / runner.REFERENCE
    if not ref.exists():
        raise FileNotFoundError(f"{job.name} needs the finished reference {job.reference} ({ref})")
    if not (directory / runner.REFERENCE).exists():
        shutil.copyfile(ref, directory / runner.REFERENCE)
    summary = runner.execute(cfg, resolved, directory, resume=True, reporter=reporter)
    if summary["timings"]["serial_fine"] is None:
        raise RuntimeError(f"{job.name}: the run has no serial reference")
    found = current_probe(job, layout)
    _write_json(layout.done(job), result_summary(job, layout, summary, found))
    print(f"{job.name}: done (η^k = {summary['errors']})", flush=True)


# ---- the scheduler -----------------------------------------------------------------------------
def _alive(pid: int | None) -> bool:
    from parastokes.core.locks import process_alive

    return pid is not None and pid > 0 and process_alive(pid)


def job_state(job: Job, layout: Layout, running: dict[str, int]) -> str:
    """``done``, ``running``, ``failed`` (the last attempt ended with an error), ``started``
    (files there, nothing running: resumes with --resume) or ``not started``."""
    if layout.done(job).exists():
        return "done"
    if job.name in running and _alive(running[job.name]):
        return "running"
    failure = layout.directory(job) / "failed.json"
    if failure.exists():
        return "failed"
    return "started" if layout.directory(job).exists() else "not started"


def status_lines(jobs: Sequence[Job], layout: Layout) -> list[str]:
    """A table of every job's state and progress, and the scheduler's pid."""
    sched = _read_json(layout.scheduler) or {}
    running = sched.get("running", {}) if _alive(sched.get("pid")) else {}
    head = (
        f"scheduler pid {sched.get('pid')} ({'alive' if _alive(sched.get('pid')) else 'stopped'})"
        if sched
        else "scheduler never started here"
    )
    lines = [f"{head}; root {layout.root}; {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}"]
    for job in jobs:
        state = job_state(job, layout, running)
        detail = progress_text(job, layout, state)
        lines.append(f"{job.name:<16} {job.group:<6} {state:<12} {detail}")
    return lines


def progress_text(job: Job, layout: Layout, state: str) -> str:
    """Where an unfinished job stands (phase, slices or iterations, η^k so far), or its error."""
    if state == "failed":
        return (_read_json(layout.directory(job) / "failed.json") or {}).get("error", "")
    progress = _read_json(layout.directory(job) / "progress.json") or {}
    detail = ""
    rows = progress.get("iterations") or []
    # (a resumed runner counts only the iterations left: add those of earlier sessions)
    if state != "done" and progress.get("phase") == "parareal":
        detail = f"parareal {len(rows)}/{len(rows) - progress['done'] + progress['total']}"
    elif state != "done" and progress.get("phase"):
        detail = f"{progress['phase']} {progress['done']}/{progress['total']}"
    if progress.get("iterations"):
        detail += "  η^k: " + " ".join(
            "-" if r["error"] is None else f"{r['error']:.2e}" for r in progress["iterations"]
        )
    from parastokes.parareal.solve_memo import KINDS, memo_directory
    from parastokes.run import CHECKPOINT

    kept = memo_directory(layout.directory(job) / CHECKPOINT)  # the iteration in progress
    if state != "done" and kept.is_dir():
        counts = {kind: len(list(kept.glob(f"{kind}-*.npz"))) for kind in KINDS}
        detail += f" (next: {counts['fine']} fine, {counts['coarse']} coarse solves kept)"
    return detail.strip()


def _write_status(jobs: Sequence[Job], layout: Layout) -> None:
    layout.status.write_text("\n".join(status_lines(jobs, layout)) + "\n", encoding="utf-8")


def _check_fresh(jobs: Sequence[Job], layout: Layout) -> None:
    """Without --resume: refuse to touch directories that hold earlier work (nothing is lost)."""
    started = [str(layout.directory(j)) for j in jobs if layout.directory(j).exists()]
    if started:
        raise ValueError(
            f"{len(started)} job directories already hold work ({started[0]}, ...): add --resume "
            "to continue them (finished jobs are skipped), or choose another --out"
        )


def schedule(jobs: Sequence[Job], layout: Layout, n_jobs: int, poll: float = 5.0) -> int:
    """Run ``jobs`` as child processes, at most ``n_jobs`` at once, each after its reference;
    returns the number of failed jobs. One scheduler per output root (``scheduler.json``)."""
    layout.root.mkdir(parents=True, exist_ok=True)
    old = _read_json(layout.scheduler) or {}
    if _alive(old.get("pid")) and old.get("pid") != os.getpid():
        raise ValueError(
            f"a scheduler (pid {old['pid']}) is already running on {layout.root}; see "
            "`python -m validation.reproduce --status`, stop it with `kill PID` first"
        )
    children: dict[str, subprocess.Popen] = {}
    failed: set[str] = set()

    def save(state: str) -> None:
        running = {name: p.pid for name, p in children.items()}
        _write_json(layout.scheduler, {"pid": os.getpid(), "state": state, "running": running})
        _write_status(jobs, layout)

    def stop(signum: int, _frame: Any) -> None:
        for p in children.values():
            p.send_signal(signal.SIGINT)  # the runner checkpoints and exits 130
        for p in children.values():
            p.wait()
        save("stopped")
        sys.exit(128 + signum)

    signal.signal(signal.SIGTERM, stop)
    names = {j.name for j in jobs}
    env = {**os.environ, "PYTHONPATH": str(REPO), "NUMBA_NUM_THREADS": "1"}
    while True:
        for name, p in list(children.items()):
            if p.poll() is not None:
                del children[name]
                if p.returncode != 0:
                    failed.add(name)
        pending = [
            j for j in jobs if j.name not in children and j.name not in failed
            and not layout.done(j).exists()
        ]
        if not pending and not children:
            break
        for job in pending:
            if len(children) >= n_jobs:
                break
            dep = job.reference
            blocked = dep is not None and dep in names and not layout.done(
                next(j for j in jobs if j.name == dep)
            ).exists()
            if dep in failed:
                failed.add(job.name)
                continue
            if blocked:
                continue
            log = layout.log(job)
            log.parent.mkdir(parents=True, exist_ok=True)
            with open(log, "a", encoding="utf-8") as handle:
                handle.write(f"--- {time.strftime('%Y-%m-%d %H:%M:%S UTC', time.gmtime())}\n")
                handle.flush()
                children[job.name] = subprocess.Popen(
                    [sys.executable, "-m", "validation.reproduce", "--out", str(layout.root),
                     "--experiments", str(layout.experiments), "--one", job.name,
                     *(f"--set={item}" for item in layout.overrides)],
                    cwd=REPO, env=env, stdout=handle, stderr=subprocess.STDOUT,
                )
        save("running")
        time.sleep(poll)
    save("finished")
    return len(failed)


def _one(name: str, layout: Layout) -> int:
    """The child process of one job; a failure is recorded in ``failed.json`` for --status."""
    # a process started in the background (nohup ... &) inherits SIGINT ignored: restore Python's
    # handler, so that the scheduler's SIGINT makes the runner checkpoint and exit
    signal.signal(signal.SIGINT, signal.default_int_handler)
    job = {j.name: j for j in plan()}[name]
    directory = layout.directory(job)
    directory.mkdir(parents=True, exist_ok=True)
    failure = directory / "failed.json"
    lock = open(directory / ".reproduce.lock", "w")  # held until this process ends
    fcntl.flock(lock, fcntl.LOCK_EX)  # a job left running by a killed scheduler: wait for it
    failure.unlink(missing_ok=True)
    try:
        run_job(job, layout)
    except KeyboardInterrupt:
        print(f"{name}: interrupted; --resume continues from the checkpoint", flush=True)
        return 130
    except Exception as error:
        _write_json(failure, {"error": f"{type(error).__name__}: {error}"})
        raise
    return 0


def commit(docs: Path, changed: Sequence[str]) -> None:
    """Commit the page and its records (only those paths) in the repository holding ``docs``."""
    folder = docs / "reproduction"
    paths = [str(docs / "reproduction.md")]
    if folder.is_dir() and any(folder.iterdir()):  # git knows no empty folder
        paths.append(str(folder))
    subprocess.run(["git", "add", *paths], cwd=docs, check=True)
    staged = subprocess.run(["git", "diff", "--cached", "--quiet", "--", *paths], cwd=docs)
    if staged.returncode == 0:
        print("nothing new to commit")
        return
    runs = ", ".join(changed) if changed else "status"
    message = f"docs/reproduction: full-scale runs collected ({runs})"
    subprocess.run(["git", "commit", "-m", message, "--", *paths], cwd=docs, check=True)


# ---- command line ------------------------------------------------------------------------------
def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m validation.reproduce",
        description="Section 5 of the paper at full scale (see the module docstring).",
    )
    parser.add_argument("--out", type=Path, default=DEFAULT_ROOT, help="output root (not in git)")
    parser.add_argument("--only", nargs="+", metavar="NAME", help="runs, references or groups")
    parser.add_argument(
        "--all", action="store_true", help="also the optional runs (Table 3 G1-G2, Table 6 3σ_f)"
    )
    parser.add_argument("--resume", action="store_true", help="continue earlier work in --out")
    parser.add_argument("--dry-run", action="store_true", help="print each job's cost and stop")
    parser.add_argument("--jobs", type=int, default=1, help="jobs at once (one core each)")
    parser.add_argument("--status", action="store_true", help="print the state of every job")
    parser.add_argument(
        "--collect", action="store_true",
        help="gather finished runs into --docs and regenerate the page's tables and figures",
    )
    parser.add_argument("--docs", type=Path, default=REPO / "docs", help="docs folder (--collect)")
    parser.add_argument(
        "--commit", action="store_true", help="with --collect: git commit the page and records"
    )
    parser.add_argument(
        "--experiments", type=Path, default=EXPERIMENTS, help="folder of the configurations"
    )
    parser.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", help="override for every job"
    )
    parser.add_argument("--one", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    layout = Layout(args.out, args.experiments.resolve(), tuple(args.set))
    if args.one:
        return _one(args.one, layout)
    try:
        jobs = select(plan(), args.only, args.all)
        if args.jobs < 1:
            raise ValueError(f"--jobs must be at least 1, got {args.jobs}")
        if args.collect and args.only:
            raise ValueError("--collect gathers every finished run (the page is regenerated "
                             "whole); drop --only")
    except ValueError as error:
        parser.error(str(error))
    if args.status:
        print("\n".join(status_lines(select(plan(), args.only, optional=True), layout)))
        return 0
    if args.collect:
        from .reproduce_report import collect

        changed = collect(plan(), layout, args.docs)
        if args.commit:
            commit(args.docs, changed)
        return 0
    if args.dry_run:
        dry_run(jobs, layout)
        return 0
    try:
        if not args.resume:
            _check_fresh(jobs, layout)
        runnable = [j for j in jobs if j.reachable or args.only]
        return 1 if schedule(runnable, layout, args.jobs) else 0
    except ValueError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
