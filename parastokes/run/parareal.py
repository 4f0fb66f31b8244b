"""Parareal inside a run: Algorithm 1 with the run's checkpoint and history, every iteration
reported and its final positions saved (so η^k and η̃^k of eq. 34 can be recomputed)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from .. import parareal
from ..output import trajectory as io
from . import session
from .advice import advice, blow_up_note, find_blow_up, solver_step
from .layout import CHECKPOINT, HISTORY
from .report import ReporterLike
from .serial import slice_seconds


def parareal_run(
    running: session.Session,
    x0: np.ndarray,
    times: np.ndarray,
    reference: np.ndarray | None,
    out: Path,
    key: dict,
    reporter: ReporterLike,
    previous: dict[str, Any] | None = None,
    state: Path | None = None,
) -> tuple[parareal.PararealResult, io.HistoryRecord]:
    """Parareal with the history of an interrupted run in ``state`` (default ``out``; if any)
    carried on.

    After every iteration (``parareal.run``'s ``on_iteration``) the final positions X^k at T_N and
    the elapsed time are appended to ``history.npz`` and reported; the checkpoint in ``state``
    lets an interrupted run resume where it stopped. A blow-up's last good state is saved in
    ``out``.
    """
    setup, executor = running.setup, running.executor
    cfg, system = setup.config, setup.system
    state = out if state is None else state
    history_path = state / HISTORY
    finals: list[np.ndarray] = []
    elapsed: list[float] = []
    checkpoint = state / CHECKPOINT
    if history_path.exists():
        _, arrays = io.load_arrays(history_path, required=("final_positions", "elapsed"))
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
    reporter.start("parareal", max(p.max_iterations - len(finals), 0))  # (resumed: what is left)
    workers = getattr(executor, "workers", 1)
    reporter.expect(slice_seconds(setup) * -(-p.n_slices // workers))  # one parallel sweep
    try:
        result = parareal.run(
            setup.fine,
            setup.coarse,
            x0,
            times[0],
            times[-1],
            p.n_slices,
            stopping=parareal.Stopping(tol=p.tol, max_iterations=p.max_iterations),
            checkpoint=parareal.Checkpoint(checkpoint, identity=key),
            reporting=parareal.Reporting(on_iteration=record),
            executor=executor,
            reference=reference,
            project=system.project,
            positions=system.positions,
            allow_oversubscribe=cfg.execution.allow_oversubscribe
            or cfg.execution.executor == "serial",
            schedule=p.schedule,
            correction=p.correction,
        )
    except Exception as error:
        found = find_blow_up(error)
        if found is not None:
            blow, label = found
            where = f"the {label or 'solve'} (Parareal)"
            fix = advice(setup, label, blow, where, previous)
            step = solver_step(cfg, setup.resolved, label)
            error.add_note(blow_up_note(out, blow, where, fix, step))
        raise
    reporter.finish()
    if len(elapsed) >= result.iterations > 0:  # the last one as the report's total (same speedup)
        elapsed[result.iterations - 1] = result.timings.total
    history = io.HistoryRecord(
        increments=result.increments,
        errors=result.errors,
        final_positions=finals[: result.iterations],
        elapsed=elapsed[: result.iterations],
        timings=result.timings.to_dict(),
    )
    return result, history
