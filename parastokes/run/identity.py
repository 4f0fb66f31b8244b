"""The identity of a run, and the checks that a run directory's files may be resumed.

Every resume file carries the run's identity (:func:`identity`: the resolved model, time,
fine, coarse and slice settings, the mode and the package version); ``--resume`` with any
difference is refused, naming the keys."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from .. import __version__
from ..config import Config, ConfigError
from ..core.files import CorruptFileError
from ..output import trajectory as io
from ..parareal import checkpoint as ckpt
from .layout import CHECKPOINT, HISTORY, REFERENCE, SUMMARY


def _flatten(prefix: str, value: Any, out: dict[str, Any]) -> None:
    if isinstance(value, dict):
        for key, item in value.items():
            _flatten(f"{prefix}.{key}" if prefix else key, item, out)
    else:
        out[prefix] = value


def identity(cfg: Config) -> dict[str, Any]:
    """What determines the iterates, by key path: the model, time, fine and coarse sections,
    ``parareal.n_slices``, ``run.mode`` and the package version (``version``).

    Keys that only say when to stop or where to run (``parareal.tol``, ``max_iterations``,
    ``execution``, ``output``) are left out: ``--resume`` may change them (e.g. to run more
    iterations).
    """
    return _identity(cfg.model_dump(mode="json"), __version__)


def _identity(dumped: dict[str, Any], version: str) -> dict[str, Any]:
    """:func:`identity` of a configuration's ``model_dump(mode="json")`` (as a run's summary
    stores it) and the package ``version``."""
    sections = {key: dumped[key] for key in ("model", "time", "fine", "coarse")}
    sections["parareal"] = {"n_slices": dumped["parareal"]["n_slices"]}
    sections["run"] = {"mode": dumped["run"]["mode"]}
    sections["coarse"] = {k: v for k, v in sections["coarse"].items()
                          if k != "max_weight_sum"}  # a safety bound, not a setting of the solver
    flat: dict[str, Any] = {}
    _flatten("", sections, flat)
    return {**flat, "version": version}


def fine_identity(cfg: Config) -> dict[str, Any]:
    """What determines the serial fine solution (the reference file): :func:`identity` without the
    coarse solver and the run mode, so runs that differ only in their coarse solver can share one
    reference (``reference.npz`` copied from one run directory into another is accepted)."""
    fine = ("model.", "time.", "fine.", "parareal.n_slices", "version")
    coarse = "model.coarse_bodies"  # a scene's choice for G's grid (Scene.coarse_bodies)
    return {k: v for k, v in identity(cfg).items() if k.startswith(fine) and k != coarse}


def _same_run(path: Path, saved: Any, now: dict[str, Any]) -> None:
    """Refuse to resume from ``path`` (written with identity ``saved``) unless it matches ``now``:
    a :class:`ConfigError` names every differing key."""
    if not isinstance(saved, dict):
        raise CorruptFileError(
            path,
            "written by another version of parastokes (no run identity)",
            "resume with that version, or pass --overwrite to start afresh",
        )
    found = ckpt.differences({k: v for k, v in saved.items() if k != ckpt.PROBLEM}, now)
    if found:
        hint = (
            "continues only the same configuration: undo the change, pass --overwrite to "
            "discard the run in that directory, or choose another --out"
        )
        issues = [(key, f"{new!r} now, {old!r} in the run to resume") for key, old, new in found]
        raise ConfigError([*issues, ("--resume", hint)], f"{path} (the run to resume)")


def check_resumable(out: Path, cfg: Config, resume: bool) -> None:
    """Before any work: every resume file in ``out`` is readable and of this run (the reference:
    of its fine problem, :func:`fine_identity`; the others: of the whole run, :func:`identity`),
    and with ``resume`` the finished run's ``summary.json`` too (its results are replaced: by
    this run's only if it is the same run, even when its resume files are gone)."""
    if resume and (out / SUMMARY).exists():
        summary = io.read_summary(out / SUMMARY)
        try:
            saved = _identity(summary["config"], summary["versions"]["parastokes"])
        except (KeyError, TypeError) as error:
            raise CorruptFileError(out / SUMMARY, f"not a run's summary (no {error})",
                                   "pass --overwrite to replace that run") from None
        _same_run(out / SUMMARY, saved, identity(cfg))
    for name, key in ((REFERENCE, fine_identity(cfg)), (HISTORY, identity(cfg)),
                      (CHECKPOINT, identity(cfg))):
        path = out / name
        if path.exists():
            meta = io.load_arrays(path)[0]
            _same_run(path, meta.get("key"), key)
            if name == CHECKPOINT:
                _stops_before(path, meta, cfg)


def _stops_before(path: Path, meta: dict[str, Any], cfg: Config) -> None:
    """Refuse to resume from the checkpoint ``path`` (its ``meta``) when the stopping rule of
    ``cfg`` would have stopped before the iteration it holds: a lower ``max_iterations`` or a
    looser ``tol`` met at an earlier iteration. Only the last iterate is kept, so the run cannot
    go back to that iteration (finished or interrupted alike); a ConfigError says what to do."""
    try:
        done = int(meta["iteration"])
        increments = [float(value) for value in meta["increments"]]
    except (KeyError, TypeError, ValueError):
        return  # (read again, and named if damaged, when Parareal loads it)
    p = cfg.parareal
    met = next((k for k, value in enumerate(increments, 1) if value < p.tol), None)
    issues = []
    if p.max_iterations is not None and done > p.max_iterations:
        issues.append(("parareal.max_iterations",
                       f"{p.max_iterations} now, but the run to resume has done {done} iterations"))
    if met is not None and met < done:
        issues.append(("parareal.tol", f"{p.tol:g} now: met after iteration {met} (η̃ = "
                                       f"{increments[met - 1]:.3g}), but the run to resume has "
                                       f"done {done} iterations"))
    if issues:
        issues.append(("--resume", f"{path} keeps only the iterate of iteration {done}, so the run "
                                   f"cannot stop earlier: keep parareal.max_iterations >= {done} "
                                   "and a tol not met before it (that run's result is then "
                                   "reported as it is), or pass --overwrite to run it again with "
                                   "the new rule"))
        raise ConfigError(issues, f"{path} (the run to resume)")
