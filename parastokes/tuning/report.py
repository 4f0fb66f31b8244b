"""What ``parastokes tune`` writes: the report (TUNED.json), the tuned configuration (TUNED.toml),
the printed table and the figure of predicted speedup against the target error (the paper's
Fig. 6b)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from .. import integrate
from ..core.files import Staging, atomic_write
from .cost import caution
from .pilot import Pilot

__all__ = ["build_report", "config_text", "draw_curves", "table", "toml_dumps"]

#: Extrapolation "helps" when the tuned speedup is at least this multiple of the baseline's.
HELPS = 1.3


def _helps(chosen: Any, baseline: Any) -> dict[str, Any]:
    if chosen is None:
        return {"helps": False, "ratio": None, "note": "no candidate reaches the target"}
    if baseline.speedup is None and chosen.settings.plain:
        return {"helps": False, "ratio": None,
                "note": f"the baseline does not reach the target ({baseline.reason}); the "
                        f"chosen solver ({chosen.settings.label()}) is not extrapolated either"}
    if baseline.speedup is None:
        return {"helps": True, "ratio": None,
                "note": f"the plain solver does not reach the target ({baseline.reason})"}
    ratio = chosen.speedup / baseline.speedup
    if chosen.settings.plain or ratio < HELPS:
        note = (f"extrapolation does not help here: the best candidate's predicted speedup is "
                f"{ratio:.2f}x the plain solver's (below {HELPS}x)")
        return {"helps": False, "ratio": ratio, "note": note}
    return {"helps": True, "ratio": ratio,
            "note": f"extrapolation helps: {ratio:.2f}x the plain solver's predicted speedup"}


def build_report(
    *, chosen: Any, baseline: Any, candidates: list, fine: integrate.Propagator, pilot: Pilot,
    n_slices: int, cores: int, target: float, t0: float, t1: float, cost: dict, search: dict,
    full_points: int,
) -> dict[str, Any]:
    """The content of TUNED.json (keys fixed in design.md: chosen, baseline, candidates, cost)."""
    pilot_points = len(pilot.system.positions(pilot.x0))
    return {
        "problem": {
            "t0": t0, "t1": t1, "n_slices": n_slices, "cores": cores, "target": target,
            "slice_length": (t1 - t0) / n_slices,
            "fine": {"scheme": fine.scheme, "dt": fine.dt, "rtol": fine.rtol, "atol": fine.atol},
            "points": full_points,
            "fine_error": pilot.fine_error,
        },
        "pilot": {
            "slices": pilot.n_slices, "points": pilot_points,
            "shortened": pilot_points != full_points,
            "gamma_f": pilot.gamma_f, "seconds": pilot.seconds,
            "note": (f"measured on {pilot.n_slices} slices of the run's length with "
                     f"{pilot_points} points" + (f" (the run has {full_points})"
                                                  if pilot_points != full_points else "")),
        },
        "chosen": None if chosen is None else chosen.as_dict(fine.dt),
        "baseline": baseline.as_dict(fine.dt),
        "extrapolation": _helps(chosen, baseline),
        "caution": None if chosen is None else caution(chosen.iterations,
                                                       len(chosen.pilot_errors),
                                                       chosen.contraction),
        "candidates": [c.as_dict(fine.dt) for c in candidates],
        "cost": cost,
        "search": search,
    }


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ValueError(f"cannot write {value} to TOML")
        return repr(value)
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, Mapping):
        return "{ " + ", ".join(f"{k} = {_toml_value(v)}" for k, v in value.items()) + " }"
    raise TypeError(f"cannot write {type(value).__name__} to TOML")


def toml_dumps(data: Mapping[str, Any], header: str = "") -> str:
    """TOML text of a two-level table (top-level keys, then one [section] per sub-table and one
    [[section]] per table of a list of tables; deeper tables inline), which is all a
    configuration holds."""
    lines = [f"# {line}" for line in header.splitlines()]

    def is_tables(value: Any) -> bool:
        return isinstance(value, list) and bool(value) and all(isinstance(v, Mapping)
                                                               for v in value)

    scalars = {k: v for k, v in data.items() if not isinstance(v, Mapping) and not is_tables(v)}
    lines += [f"{k} = {_toml_value(v)}" for k, v in scalars.items()]
    for key, value in data.items():
        tables = [(f"[{key}]", value)] if isinstance(value, Mapping) else (
            [(f"[[{key}]]", v) for v in value] if is_tables(value) else [])
        for title, table in tables:
            lines += ["", title]
            lines += [f"{k} = {_toml_value(v)}" for k, v in table.items()]
    return "\n".join(lines) + "\n"


def config_text(config: Mapping[str, Any], result: Any, cores: int, source: str,
                command: str | None = None) -> str:
    """TUNED.toml: ``config`` (a configuration dumped as a dict) with the chosen [coarse],
    parareal.n_slices = cores, max_iterations = the predicted N_it, workers = cores; its title
    says that it was tuned, from ``source``, and its header the whole ``command`` (every flag;
    default: the source, cores and target)."""
    chosen = result.chosen
    target = result.report["problem"]["target"]
    data = {k: v for k, v in config.items() if k != "tune"}
    title = data.get("title")
    data["title"] = (f"tuned from {source} for {cores} cores, η* = {target:g}"
                     + (f": {title}" if title else ""))
    data["coarse"] = chosen.settings.coarse_table()
    data["parareal"] = {**data["parareal"], "n_slices": cores,
                        "max_iterations": chosen.iterations}
    execution = dict(data.get("execution", {}))
    if execution.get("executor", "processes") != "serial":
        if execution.get("executor", "processes") == "processes":
            execution["workers"] = cores
        if chosen.settings.n_auxiliary > cores:
            execution["allow_oversubscribe"] = True
    data["execution"] = execution
    predicted = chosen.predicted()
    command = command or f"parastokes tune {source} --cores {cores} --target {target:g}"
    header = (
        f"Tuned by `{command}`: {chosen.settings.label()}\n"
        f"predicted: speedup {predicted['speedup']:.3g} (eq. 14), N_it = "
        f"{predicted['iterations']}, gamma_G/gamma_F = {predicted['gamma_ratio']:.3g}; "
        "see TUNED.json"
    )
    if result.report.get("caution"):
        header += f"\n{result.report['caution']}"
    return toml_dumps(data, header)


def _fmt(value: Any, spec: str) -> str:
    return "-" if value is None else format(value, spec)


def steps_cell(candidate: Mapping[str, Any], slice_length: float) -> str:
    """The table's steps per slice of one auxiliary solver: ``accepted/rejected`` (means over
    the measured calls) for an adaptive candidate, the count of its smallest step otherwise."""
    steps = candidate.get("adaptive_steps")
    if steps is not None:
        return f"{steps['accepted']:.0f}/{steps['rejected']:.0f}"
    if candidate["dt"] is None:
        return "-"
    return str(integrate.n_steps(0.0, slice_length, candidate["dt"]))


def table(report: Mapping[str, Any], rows: int = 8) -> str:
    """A short text table: baseline, chosen and the best measured candidates (an adaptive one
    with its rtol in the label and its accepted/rejected steps per slice)."""
    head = (f"{'':3}{'candidate':44} {'τ_c/τ_f':>8} {'steps':>7} {'N_G':>4} {'ρ(DG)':>7} "
            f"{'η¹ pilot':>9} {'contr.':>8} {'N_it':>4} {'γ_G/γ_F':>8} {'speedup':>8}")
    slice_length = report["problem"]["slice_length"]
    lines = [head]
    measured = [c for c in report["candidates"] if c["pilot"]["eta1"] is not None]
    measured.sort(key=lambda c: -(c["predicted"]["speedup"] or 0))
    chosen = report["chosen"]
    baseline = report["baseline"]
    for c in measured[:rows]:
        won = chosen is not None and (c["label"], c["dt"]) == (chosen["label"], chosen["dt"])
        base = (c["label"], c["dt"]) == (baseline["label"], baseline["dt"])
        mark = ("*" if won else " ") + ("b" if base else " ") + " "
        ratio = None if c.get("rtol") is not None else c.get("dt_ratio")  # (adaptive: no τ_c)
        lines.append(
            f"{mark}{c['label'][:44]:44} {_fmt(ratio, '8.3g')} "
            f"{steps_cell(c, slice_length):>7} "
            f"{c['n_auxiliary']:>4} {_fmt(c['stability']['spectral_radius'], '7.4g')} "
            f"{_fmt(c['pilot']['eta1'], '9.2e')} {_fmt(c['pilot']['contraction'], '8.2e')} "
            f"{_fmt(c['predicted']['iterations'], '>4')} "
            f"{_fmt(c['predicted']['gamma_ratio'], '8.4f')} "
            f"{_fmt(c['predicted']['speedup'], '8.3g')}"
        )
    counts: dict[str, int] = {}
    for c in report["candidates"]:
        counts[c["status"]] = counts.get(c["status"], 0) + 1
    lines.append(f"(* chosen, b baseline) {len(report['candidates'])} candidates with the "
                 "baseline: " + ", ".join(f"{v} {k}" for k, v in counts.items()))
    return "\n".join(lines)


def draw_curves(result: Any, path: str | Path, n_slices: int, best: int = 4,
                staging: Staging | None = None) -> Path:
    """Predicted speedup against the target error for the baseline and the best few candidates,
    written to ``path`` through ``staging`` (in place when it commits), else atomically."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    targets = np.logspace(-3, -11, 33)
    accepted = sorted((c for c in result.candidates if c.status == "accepted"),
                      key=lambda c: -c.speedup)[:best]
    shown = accepted + ([result.baseline] if result.baseline not in accepted and
                        result.baseline.pilot_errors else [])
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for cand in shown:
        values = result.speedup_curve(cand, targets, n_slices)
        ys = [np.nan if v is None else v for v in values]
        style = "--" if cand is result.baseline else "-"
        ax.semilogx(targets, ys, style, marker=".", label=cand.settings.label())
    ax.axvline(result.report["problem"]["target"], color="0.6", lw=0.8)
    ax.invert_xaxis()
    ax.set_xlabel("target relative error η*")
    ax.set_ylabel(f"predicted speedup (eq. 14), N_c = {n_slices}")
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    path = Path(path)
    try:
        if staging is None:
            atomic_write(path, lambda handle: fig.savefig(handle, format="png"))
        else:
            staging.write(path, lambda handle: fig.savefig(handle, format="png"))
    finally:
        plt.close(fig)
    return path
