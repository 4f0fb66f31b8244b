"""One run of a configuration, end to end: claim the directory, check what is resumed, start
the session, run serial and/or Parareal, write the summary, trajectory, flow and figures,
and move the results into place whole."""

from __future__ import annotations

import os
import platform
import time
from pathlib import Path
from typing import Any, cast

import numpy as np

from .. import __version__, parareal
from ..config import Config, Resolved, Setup, preflight, resolved_dict
from ..core.contracts import System
from ..core.files import write_text
from ..output import rundir
from ..output import trajectory as io
from . import session
from .advice import previous_blow_up
from .frames import append_frames, check_room, trajectory_writer
from .identity import check_resumable, fine_identity, identity
from .layout import BLOWUP, CHECKPOINT, SUMMARY, TRAJECTORY
from .parareal import parareal_run
from .report import Reporter, ReporterLike
from .serial import serial_run
from .speedups import run_speedups


class MonitorError(ArithmeticError):
    """A run's stability monitor ended above its limit and ``output.monitor_fatal`` is set (its
    results are written all the same; the command line exits with status 3)."""


def _monitor(system: System, states: np.ndarray, times: np.ndarray) -> dict[str, float]:
    """The stability monitor (rod length / vesicle area change) over the slice boundaries: its
    largest value, the time of it, its final value and its limit."""
    values = [system.monitor(state) for state in states]
    worst = int(np.argmax(values))
    return {"max": float(values[worst]), "time": float(times[worst]),
            "final": float(values[-1]), "limit": system.monitor_limit}


def monitor_warning(monitor: dict[str, float]) -> str | None:
    """The warning of a run whose monitor (:func:`_monitor`) exceeds its limit anywhere at the
    slice boundaries (any excess: the limit is the tolerance of the model's constraint, and a
    monitor beyond ``integrate.BLOWUP_FACTOR`` times it is a blow-up), else None."""
    value, limit = monitor["max"], monitor["limit"]
    if value <= limit:  # (a NaN is not within it)
        return None
    return (f"the stability monitor reached {value:.3g} at t = {monitor['time']:.6g}, "
            f"{value / limit:.3g} times its limit {limit:g} (a rod's length, a vesicle's area "
            "changed that much): the results are not to be trusted; reduce fine.dt")


def execute(
    cfg: Config,
    resolved: Resolved,
    out: str | Path,
    *,
    resume: bool = False,
    overwrite: bool = False,
    reporter: ReporterLike | None = None,
    files: dict[str, str] | None = None,
) -> dict[str, Any]:
    """Run ``cfg`` into the directory ``out``; returns the summary (also written to summary.json).

    The directory is claimed first (:func:`parastokes.output.rundir.claim`), before any work: a
    file, an unwritable path, a directory in use by another run, or one holding a finished,
    interrupted or foreign run (unless ``resume`` or ``overwrite``) raises a ValueError that says
    what to do. With ``resume`` the serial solution and the Parareal checkpoint found there are
    continued; a run of another configuration is refused (:class:`ConfigError` naming the keys).
    ``files`` (name -> text, the demo's ``config.toml``) are written into it once that check has
    passed. Results go to the directory whole once complete; figures are drawn last
    (``output.figures``). Raises ``integrate.BlowUpError`` on a numerical blow-up, after saving the
    last good state. Before all of that (:func:`parastokes.output.rundir.check_path`, then
    :func:`parastokes.config.preflight`, as ``parastokes check``): the
    configuration is built and a user's body called once at its initial state; a body that breaks
    the System contract raises :class:`~parastokes.bodies.contract.BodyError` naming the method,
    before the directory is claimed or a worker started.
    """
    reporter = reporter or Reporter()
    rundir.check_path(out)  # a bad --out before any work, and the body before the claim
    known = len(resolved.warnings)
    setup = preflight(cfg, resolved)
    for warning in resolved.warnings[known:]:  # (the notes of the built system)
        reporter.note(f"note: {warning}")
    with rundir.claim(out, resume=resume, overwrite=overwrite) as directory:
        found = directory.entries()
        if resume and not found["state"] and not found["results"]:
            reporter.note(f"--resume: {out} holds no run to continue; starting afresh")
        return _execute(setup, directory, reporter, files or {}, resume)


def _kernels_cached() -> bool:
    """Whether numba's cache holds compiled kernels of this package (else the first run compiles
    them, which takes up to a minute)."""
    root = os.environ.get("NUMBA_CACHE_DIR") or Path(__file__).parents[1]
    return next(Path(root).rglob("*.nbi"), None) is not None


def _execute(
    setup: Setup, directory: rundir.RunDirectory, reporter: ReporterLike, files: dict[str, str],
    resume: bool = False,
) -> dict[str, Any]:
    from ..output import plots

    cfg, resolved = setup.config, setup.resolved
    out, staging = directory.path, directory.staging
    conf = resolved_dict(cfg, resolved)
    key = identity(cfg)
    check_resumable(directory.state, cfg, resume)
    previous = previous_blow_up(out)  # (an earlier run's, to compare a new blow-up with)
    for name, text in files.items():  # (in place with the results: a run cut short keeps the old)
        write_text(staging / name, text)
    mode = cfg.run.mode
    start = time.perf_counter()
    if not _kernels_cached():
        reporter.note("compiling the numerical kernels (first run only; up to a minute) ...")
    with session.start(setup) as running:
        system = setup.system
        x0 = system.initial_state()
        times = parareal.time_points(cfg.time.t0, cfg.time.t1, cfg.parareal.n_slices)
        writer = trajectory_writer(cfg, setup, conf, staging) if cfg.output.trajectory else None
        try:
            if writer is not None:
                check_room(setup, writer)
            reference = serial_time = result = record = fine_steps = None
            if mode in ("serial", "both"):
                reference, serial_time, fine_steps = serial_run(
                    setup, x0, times, out, fine_identity(cfg), reporter, previous,
                    directory.state,
                )
                if writer is not None:
                    append_frames(writer, "serial", running, times, reference)
            if mode in ("parareal", "both"):
                result, record = parareal_run(
                    running, x0, times, reference, out, key, reporter, previous, directory.state
                )
                if writer is not None:
                    append_frames(writer, "parareal", running, times, result.states)
                    writer.write_history(record)
        except BaseException:
            running.abort()
            raise
        finally:
            if writer is not None:
                writer.close()
        final_states = result.states if result is not None else reference
        assert final_states is not None  # run.mode is serial, parareal or both
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
            if result is None or record is None  # (both or neither)
            else run_speedups(result, list(record.elapsed), serial_time),
            "workers": None if running.executor is None else running.executor.workers,
            # adaptive fine steps of the serial run (scheme "auto": its switches), or None
            "fine_steps": fine_steps,
            "monitor": _monitor(system, final_states, times),
            "final_time": float(times[-1]),
            "final_positions": system.positions(final_states[-1]),
            "warnings": resolved.warnings,
            "versions": {
                "parastokes": __version__,
                "numpy": np.__version__,
                "python": platform.python_version(),
            },
        }
    alarm = monitor_warning(cast(dict[str, float], summary["monitor"]))
    if alarm is not None:
        summary["warnings"] = [*resolved.warnings, alarm]
        reporter.warn(alarm)
    summary["wall_time"] = time.perf_counter() - start
    io.write_summary(staging / SUMMARY, summary)
    if writer is not None:
        io.write_xdmf(staging / TRAJECTORY)
        if cfg.output.flow_every is not None:
            from ..flow.command import write_run_flow

            write_run_flow(staging, cfg.output.flow_every, cfg.output.flow_plane,
                           cfg.output.flow_resolution)
    if cfg.output.figures:
        written = plots.draw_run(staging, formats=cfg.output.formats)
        reporter.note(f"figures: {', '.join(sorted({p.stem for p in written}))}")
    directory.commit()  # the new results replace the old ones whole
    (out / BLOWUP).unlink(missing_ok=True)
    if result is not None and not cfg.parareal.checkpoint:
        (out / CHECKPOINT).unlink(missing_ok=True)
    if alarm is not None and cfg.output.monitor_fatal:
        raise MonitorError(f"{alarm} (output.monitor_fatal; the results are in {out})")
    return summary
