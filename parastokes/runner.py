"""One run of a configuration: the serial fine solution, Parareal (Algorithm 1), or both, with all
outputs (summary.json, trajectory.h5 + .xdmf, figures) in one directory. Used by the CLI.

Parareal reports every iteration through ``parareal.run``'s ``on_iteration`` hook: the final
positions X^k at T_N of every iteration are saved (so η^k and η̃^k of eq. 34 can be recomputed from
the saved file) and reported live; ``--resume`` after an interruption continues from Parareal's
checkpoint. Files in the output directory while a run is in progress:

- ``checkpoint.npz``: Parareal's checkpoint (removed at the end when ``parareal.checkpoint`` is
  false);
- ``reference.npz``: the serial fine solution at T_0..T_N and its wall time (mode ``both``);
- ``history.npz``: X^k at T_N and the elapsed wall time after every iteration.
"""

from __future__ import annotations

import hashlib
import json
import logging
import platform
import time
from pathlib import Path
from typing import Any

import numpy as np

from . import __version__, io, parareal
from .bodies import registry
from .config import Config, ConfigError, Resolved, Setup, build, resolved_dict

__all__ = ["CHECKPOINT", "HISTORY", "REFERENCE", "Reporter", "execute", "speedup_table"]

logger = logging.getLogger(__name__)

CHECKPOINT = "checkpoint.npz"
REFERENCE = "reference.npz"
HISTORY = "history.npz"
SUMMARY = "summary.json"
TRAJECTORY = "trajectory.h5"


class Reporter:
    """Receives progress from :func:`execute`; this base class stays silent (see the CLI's)."""

    def note(self, text: str) -> None:
        """A line of information."""

    def start(self, what: str, total: int) -> None:
        """A phase of ``total`` steps begins: ``"serial"`` slices or ``"parareal"`` iterations."""

    def advance(self) -> None:
        """One step of the current phase is done."""

    def finish(self) -> None:
        """The current phase is over."""

    def iteration(self, k: int, increment: float, error: float | None, elapsed: float) -> None:
        """Iteration k of Parareal finished: η̃^k, η^k (None without reference), wall time so far."""


def _digest(data: Any) -> str:
    return hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest()


def _keys(cfg: Config) -> tuple[str, str]:
    """Digests of what determines the serial fine solution, and of the whole Parareal problem."""
    dumped = cfg.model_dump(mode="json")
    fine = {k: dumped[k] for k in ("model", "time", "fine")} | {"n": cfg.parareal.n_slices}
    return _digest(fine), _digest(fine | {"coarse": dumped["coarse"]})


def _frame_indices(n_slices: int, every: int) -> list[int]:
    """Slice boundaries written as frames: every ``every``-th, and always the last."""
    return sorted(set(range(0, n_slices + 1, every)) | {n_slices})


# ---- the serial fine run ---------------------------------------------------------------------
def _serial(
    setup: Setup, x0: np.ndarray, times: np.ndarray, path: Path, key: str, reporter: Reporter
) -> tuple[np.ndarray, float]:
    """The serial fine solution F(T_n, T_0, x0) at every T_n (as ``parareal.serial_solution``) and
    its wall time; reloaded from ``path`` when that holds the same problem (``key``)."""
    if path.exists():
        meta, arrays = io.load_arrays(path)
        if meta.get("key") == key:
            reporter.note(f"serial fine solution reloaded from {path.name}")
            return arrays["states"], float(meta["wall_time"])
    n_slices = len(times) - 1
    states = np.empty((n_slices + 1, *x0.shape))
    states[0] = x0
    reporter.start("serial", n_slices)
    start = time.perf_counter()
    for n in range(1, n_slices + 1):
        states[n] = setup.fine(times[n - 1], times[n], states[n - 1])
        reporter.advance()
    wall = time.perf_counter() - start
    reporter.finish()
    io.save_arrays(path, {"key": key, "wall_time": wall}, states=states)
    return states, wall


# ---- Parareal --------------------------------------------------------------------------------
def _parareal(
    setup: Setup,
    x0: np.ndarray,
    times: np.ndarray,
    reference: np.ndarray | None,
    out: Path,
    key: str,
    reporter: Reporter,
) -> tuple[parareal.PararealResult, io.HistoryRecord]:
    """Parareal with the history of an interrupted run in ``out`` (if any) carried on.

    After every iteration (``parareal.run``'s ``on_iteration``) the final positions X^k at T_N and
    the elapsed time are appended to ``history.npz`` and reported; the checkpoint in ``out`` lets
    an interrupted run resume where it stopped.
    """
    cfg, system = setup.config, setup.system
    history_path = out / HISTORY
    finals: list[np.ndarray] = []
    elapsed: list[float] = []
    if history_path.exists():
        meta, arrays = io.load_arrays(history_path)
        if meta.get("key") != key:
            raise ConfigError(
                [("", f"{out} holds a run of another configuration; use a new --out directory")]
            )
        finals, elapsed = list(arrays["final_positions"]), list(arrays["elapsed"])

    def record(report: parareal.IterationReport) -> None:
        k = report.iteration
        del finals[k - 1 :], elapsed[k - 1 :]
        missing = k - 1 - len(finals)  # > 0 only if an interrupt fell between checkpoint and here
        finals.extend([np.full_like(system.positions(x0), np.nan)] * missing)
        elapsed.extend([np.nan] * missing)
        finals.append(system.positions(report.final_state))
        elapsed.append(report.elapsed)
        io.save_arrays(
            history_path,
            {"key": key},
            final_positions=np.asarray(finals),
            elapsed=np.asarray(elapsed),
        )
        reporter.iteration(report.iteration, report.increment, report.error, report.elapsed)
        reporter.advance()

    p = cfg.parareal
    reporter.start("parareal", p.max_iterations)
    result = parareal.run(
        setup.fine,
        setup.coarse,
        x0,
        times[0],
        times[-1],
        p.n_slices,
        p.tol,
        max_iterations=p.max_iterations,
        executor=setup.executor,
        reference=reference,
        project=system.project,
        positions=system.positions,
        checkpoint=out / CHECKPOINT,
        allow_oversubscribe=cfg.execution.allow_oversubscribe
        or cfg.execution.executor == "serial",
        on_iteration=record,
        schedule=p.schedule,
    )
    reporter.finish()
    history = io.HistoryRecord(
        increments=result.increments,
        errors=result.errors,
        final_positions=finals[: result.iterations],
        elapsed=elapsed[: result.iterations],
        timings=result.timings.to_dict(),
    )
    return result, history


# ---- summary ---------------------------------------------------------------------------------
def _speedups(
    result: parareal.PararealResult, elapsed: list[float], serial_time: float | None
) -> dict[str, Any]:
    """Eq. 14 measured and theoretical and eq. 15, for the run and after each iteration k."""
    values = result.speedup(serial_time)
    n = result.n_slices
    g, f = values["gamma_G"], values["gamma_F"]
    ks = list(range(1, result.iterations + 1))
    values["by_iteration"] = {
        "iterations": ks,
        "measured": [values["serial_time"] / t for t in elapsed],
        "theoretical": [parareal.speedup(g, f, k, n) for k in ks],
        "bound": [parareal.speedup_bound(g / f, k, n) for k in ks],
    }
    values["n_slices"] = n
    return values


def _monitor(system: Any, states: np.ndarray) -> dict[str, float]:
    """The stability monitor (rod length / vesicle area change) over the slice boundaries."""
    values = [system.monitor(state) for state in states]
    return {"max": float(max(values)), "final": float(values[-1]), "limit": system.monitor_limit}


def _writer(cfg: Config, setup: Setup, conf: dict[str, Any], out: Path) -> io.TrajectoryWriter:
    """The trajectory writer of the layout that the body's kind gives (registry)."""
    kind = registry.get(cfg.model.kind)
    layout = kind.layout(cfg.model, setup.system, cfg.output.frames, cfg.output.tracked_points)
    return io.TrajectoryWriter(out / TRAJECTORY, layout, config=conf)


def execute(
    cfg: Config,
    resolved: Resolved,
    out: str | Path,
    *,
    resume: bool = False,
    reporter: Reporter | None = None,
) -> dict[str, Any]:
    """Run ``cfg`` into the directory ``out``; returns the summary (also written to summary.json).

    Without ``resume`` earlier run files in ``out`` are removed first; with it the serial solution
    and the Parareal checkpoint found there are reused. Figures are drawn last
    (``output.figures``). Raises ``integrate.BlowUpError`` on a numerical blow-up and
    :class:`ConfigError` when ``out`` holds another problem's checkpoint.
    """
    from . import plots

    reporter = reporter or Reporter()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if not resume:
        for name in (CHECKPOINT, REFERENCE, HISTORY):
            (out / name).unlink(missing_ok=True)
    conf = resolved_dict(cfg, resolved)
    fine_key, parareal_key = _keys(cfg)
    mode = cfg.run.mode
    start = time.perf_counter()
    with build(cfg, resolved) as setup:
        system = setup.system
        x0 = system.initial_state()
        times = parareal.time_points(cfg.time.t0, cfg.time.t1, cfg.parareal.n_slices)
        frames = _frame_indices(cfg.parareal.n_slices, cfg.output.every)
        writer = _writer(cfg, setup, conf, out) if cfg.output.trajectory else None
        try:
            reference = serial_time = result = record = None
            if mode in ("serial", "both"):
                reference, serial_time = _serial(
                    setup, x0, times, out / REFERENCE, fine_key, reporter
                )
                if writer is not None:
                    for n in frames:
                        writer.append("serial", times[n], reference[n])
            if mode in ("parareal", "both"):
                result, record = _parareal(setup, x0, times, reference, out, parareal_key, reporter)
                if writer is not None:
                    for n in frames:
                        writer.append("parareal", times[n], result.states[n])
                    writer.write_history(record)
        finally:
            if writer is not None:
                writer.close()
        final_states = result.states if result is not None else reference
        summary = {
            "title": cfg.title,
            "mode": mode,
            "config": conf,
            "iterations": 0 if result is None else result.iterations,
            "stop_reason": None if result is None else result.stop_reason,
            "converged": None if result is None else result.converged,
            "increments": [] if result is None else result.increments,
            "errors": None if result is None else result.errors,
            "timings": {
                "serial_fine": serial_time,
                **({} if result is None else result.timings.to_dict()),
                "elapsed_by_iteration": [] if record is None else record.elapsed,
            },
            "speedup": None
            if result is None
            else _speedups(result, list(record.elapsed), serial_time),
            "workers": None if setup.executor is None else setup.executor.workers,
            "monitor": _monitor(system, final_states),
            "final_time": float(times[-1]),
            "final_positions": system.positions(final_states[-1]),
            "warnings": resolved.warnings,
            "versions": {
                "parastokes": __version__,
                "numpy": np.__version__,
                "python": platform.python_version(),
            },
        }
    if result is not None and not cfg.parareal.checkpoint:
        (out / CHECKPOINT).unlink(missing_ok=True)
    summary["wall_time"] = time.perf_counter() - start
    io.write_summary(out / SUMMARY, summary)
    if writer is not None:
        io.write_xdmf(out / TRAJECTORY)
    if cfg.output.figures:
        written = plots.draw_run(out, formats=cfg.output.formats)
        reporter.note(f"figures: {', '.join(sorted({p.stem for p in written}))}")
    return summary


def speedup_table(summary: dict[str, Any]) -> str:
    """The speedup report of a summary (eqs. 14-15), as printed after a run."""
    s = summary["speedup"]
    if s is None:
        return "speedup: no Parareal run"
    source = "estimated as N_c γ_F" if s["serial_time_estimated"] else "measured serial fine run"
    lines = [
        f"speedup after K = {summary['iterations']} iterations, N_c = {s['n_slices']} slices, "
        f"{summary['workers']} workers:",
        f"  measured     {s['measured']:8.3f}   (Υ_F = {s['serial_time']:.3f} s, {source}; "
        f"Parareal {summary['timings']['total']:.3f} s)",
        f"  theoretical  {s['theoretical']:8.3f}   (eq. 14 without overhead; "
        f"γ_G/γ_F = {s['gamma_ratio']:.4f})",
        f"  bound        {s['bound']:8.3f}   (eq. 15)",
    ]
    return "\n".join(lines)
