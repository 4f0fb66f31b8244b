"""After a numerical blow-up: the last good state saved, and what to change (or why the step
is not the cause: a body at the wall, the same time with another step)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from .. import integrate
from ..config import Config, Resolved, Setup
from ..core.contracts import StepFailure
from ..integrate import BlowUpError
from ..output import trajectory as io
from .layout import BLOWUP


def blow_up_note(out: Path, error: BlowUpError, where: str, fix: str, step: float) -> str:
    """Save the last good state of a blow-up to ``out/BLOWUP`` (with the step of the solver that
    failed, ``step``, for :func:`_same_time`); the note that says so."""
    io.save_arrays(
        out / BLOWUP,
        {"where": where, "t": error.t, "step": error.step, "monitor": error.monitor, "dt": step},
        last_state=error.last_state,
    )
    taken = "" if where.startswith("the correction") else f" (step {error.step} of that solve)"
    return (
        f"{where} blew up at t = {error.t:.10g}{taken}; the last good state is in "
        f"{out / BLOWUP}; {fix}"
    )


def previous_blow_up(out: Path) -> dict[str, Any] | None:
    """The record of the blow-up of an earlier run in ``out`` (kept through ``--overwrite``
    until a run completes), or None."""
    try:
        meta, _ = io.load_arrays(out / BLOWUP)
    except (OSError, ValueError):
        return None
    return meta


def solver_step(cfg: Config, resolved: Resolved, label: str) -> float:
    """The step of the solver a blow-up of the solve ``label`` happened in."""
    fine = "fine solve" in label or label == "serial"
    return float(resolved.fine_dt if fine else resolved.coarse_dt)


def height_keys(cfg: Config) -> str:
    """The keys that say how far the bodies start from the wall, by kind."""
    model = cfg.model
    if model.kind == "scene":
        return "the bodies' height, position or center ([[bodies]])"
    for key in ("height", "position", "center"):
        if key in type(model).model_fields:
            return f"model.{key}" + (" (its z)" if key != "height" else "")
    return "the body's initial position"


def _smaller_step_passes(setup: Setup, error: BlowUpError, step: float) -> bool:
    """Whether the fine scheme with a step 10 times smaller than ``step`` carries the last good
    state of ``error`` through the time of two such steps without a blow-up: then the step, not
    the model, drove the body into the wall (a probe of 20 small steps)."""
    system, x = setup.system, error.last_state
    if np.shape(x) != np.shape(system.initial_state()):
        return False  # (a coarser grid's state)
    start = error.t - step
    try:
        integrate.run(system, x, start, start + 2 * step, setup.config.fine.scheme, step / 10)
    except (BlowUpError, StepFailure, ValueError, FloatingPointError):
        return False
    return True


def _near_wall(setup: Setup, state: np.ndarray) -> str | None:
    """Why a blow-up at ``state`` is the body reaching the wall z = 0 (its lowest point closer to
    the wall than the blob size ε, where the regularised kernels stop resolving the gap), else
    None."""
    r = setup.resolved
    scale = r.epsilon if math.isfinite(r.epsilon) else r.grid_spacing
    if not getattr(setup.system, "wall", False) or not math.isfinite(scale):
        return None
    try:
        lowest = float(np.min(np.asarray(setup.system.positions(state))[:, 2]))
    except (ValueError, IndexError):
        return None
    if not lowest < scale:
        return None
    return (
        f"a body is at the wall: its lowest point is {lowest:.3g} above z = 0, closer than the "
        f"blob size ε = {scale:.3g}, where the regularised flow no longer keeps it off; it gets "
        "there at this time whatever the step (a step 10 times smaller meets the wall too), so "
        f"a smaller step does not help: start it farther from the wall "
        f"({height_keys(setup.config)}), end the run before (time.t1), or change the forces "
        "that drive it there"
    )


def _same_time(previous: dict[str, Any] | None, error: BlowUpError, where: str, step: float,
               span: float) -> str | None:
    """A note when the earlier run in the directory blew up in the same solver at (about) the
    same time with another step: the time does not move with the step, so the step is not the
    cause."""
    if not previous or previous.get("where") != where:
        return None
    try:
        t_before, step_before = float(previous["t"]), float(previous["dt"])
    except (KeyError, TypeError, ValueError):
        return None
    changed = max(step, step_before) / min(step, step_before) >= 1.2
    if not (changed and abs(error.t - t_before) <= 0.05 * span):
        return None
    return (
        f"the run before blew up there too, at t = {t_before:.6g} with a step of "
        f"{step_before:.3g} (now t = {error.t:.6g} with {step:.3g}): the time does not move with "
        "the step, so the step is not the cause; look at the model (a body reaching the wall, "
        "forces too strong for it)"
    )


def advice(setup: Setup, label: str, error: BlowUpError, where: str,
            previous: dict[str, Any] | None) -> str:
    """What to change after a blow-up of the solve ``label`` (:func:`fix`), or why the step is
    not the cause (:func:`_near_wall`, :func:`_same_time`)."""
    cfg = setup.config
    span = cfg.time.t1 - cfg.time.t0
    step = solver_step(cfg, setup.resolved, label)
    if " overlap or touch" in error.reason:  # (mobility.checks.ContactError, names in reason)
        return ("the bodies came into contact, where the mobility problem can no longer tell "
                "their surfaces apart; a smaller step does not help: enable [scene] repulsion "
                "(e.g. repulsion = { range = 0.5, force = F0 }, a push of F0 at contact that "
                "vanishes a range apart; docs/bodies.md) to keep them apart, or start them "
                "farther apart")
    if " returned " in error.reason:  # a body's own method at the (finite) last good state
        return ("the body's own function named above gives non-finite values, so a smaller step "
                "does not help: fix that function (or the values it is given)")
    wall = _near_wall(setup, error.last_state)
    solve = "solve" in label or label == "serial"  # (not a correction or combination)
    if wall is not None and solve and _smaller_step_passes(setup, error, step):
        wall = None  # the step drove it there: a smaller one is the fix
    found = [note for note in (wall, _same_time(previous, error, where, step, span)) if note]
    return "; ".join(found) if found else fix(cfg, label, error.reason)


def fix(cfg: Config, label: str, reason: str = "") -> str:
    """What to change after a blow-up of the solve named ``label`` (``reason``: the error's)."""
    fine = "fine solve" in label or label == "serial"
    if "step size" in reason:  # adaptive steps shrank to nothing
        return ("loosen fine.rtol/fine.atol, or use fixed steps (no rtol) to see where the "
                "body fails")
    if "linear solve failed" in reason:
        return _linear_solve_fix(cfg, fine)
    if fine:
        return f"reduce fine.dt (now {cfg.fine.dt:g}) or use a more stable fine.scheme"
    if cfg.coarse.kind == "hodmd":
        return ("reduce the steps of the coarse solvers (coarse.g1 and coarse.g2: their dt or "
                "dt_ratio), or use a more stable scheme for them")
    return (
        "reduce the coarse step (coarse.dt_ratio or coarse.dt), or choose Lagrange nodes at which "
        f"the coarse scheme ({getattr(cfg.coarse, 'scheme', cfg.coarse.kind)}) is stable at that "
        "step"
    )


def _linear_solve_fix(cfg: Config, fine: bool) -> str:
    """What to change after a failed stage solve of a linearly implicit scheme: a GMRES one
    (``ros2-krylov``) can use the direct solve of ros2; a direct one (its ``I - hγA`` singular)
    only a smaller step, or a Jacobian hook that is right."""
    which = "fine.dt" if fine else "the coarse step"
    scheme = cfg.fine.scheme if fine else getattr(cfg.coarse, "scheme", "")
    if getattr(integrate.SCHEMES.get(scheme), "krylov", False):
        return (f"reduce {which}, or use the scheme ros2 (a direct solve on the approximate "
                "Jacobian, no GMRES iterations to fail)")
    return (f"reduce {which} (I - hγA of {scheme or 'the scheme'} is singular at this step; a "
            "smaller h moves it away from singular), or check the body's stiff_jacobian or "
            "load_jacobian if it has one")


def find_blow_up(error: BaseException) -> tuple[BlowUpError, str] | None:
    """The BlowUpError inside ``error`` (a TaskError's ``original`` or a cause) and the label of
    the task that raised it."""
    label = ""
    seen: set[int] = set()
    item: BaseException | None = error
    while item is not None and id(item) not in seen:
        seen.add(id(item))
        if isinstance(item, BlowUpError):
            return item, label
        label = getattr(item, "label", label)
        item = getattr(item, "original", None) or item.__cause__
    return None
