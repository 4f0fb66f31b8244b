"""The speedups of a finished run: eq. 14 measured and theoretical and eq. 15, after each
iteration, and the table printed after a run."""

from __future__ import annotations

from typing import Any

from .. import parareal
from ..parareal.best_serial import HOW_TO_MEASURE, best_known, cache_path
from ..parareal.speedup import schedule_speedups


def run_speedups(
    result: parareal.PararealResult, elapsed: list[float], serial_time: float | None
) -> dict[str, Any]:
    """Eq. 14 measured and theoretical and eq. 15, for the run and after each iteration k."""
    speedups = result.speedup(serial_time)
    values: dict[str, Any] = dict(speedups)
    n = result.n_slices
    g, f = speedups["gamma_G"], speedups["gamma_F"]
    ks = list(range(1, result.iterations + 1))
    models = [schedule_speedups(speedups["schedule"], g, f, k, n) for k in ks]
    values["by_iteration"] = {
        "iterations": ks,
        "measured": [speedups["serial_time"] / t for t in elapsed],
        "theoretical": [theoretical for theoretical, _ in models],
        "bound": [bound for _, bound in models],
    }
    values["n_slices"] = n
    return values


def _setup(speedups: dict[str, Any]) -> str:
    """G's one-off setup, named where it is more than half a G call (summaries written before
    it was measured have none)."""
    setup = speedups.get("coarse_setup", 0.0)
    if setup <= 0.5 * speedups["gamma_G"]:
        return ""
    return f"; G's one-off setup of {setup:.3g} s in its first call left out"


def speedup_table(summary: dict[str, Any]) -> str:
    """The speedup report of a summary (eqs. 14-15), as printed after a run."""
    s = summary["speedup"]
    if s is None:
        return "speedup: no Parareal run"
    source = "estimated as N_c γ_F" if s["serial_time_estimated"] else "measured serial fine run"
    if s.get("schedule") == "pipelined":
        model, limit = "pipelined schedule, simulated, N_c workers", "its critical path"
    else:
        model, limit = "eq. 14 without overhead", "eq. 15"
    lines = [
        f"speedup after K = {summary['iterations']} iterations, N_c = {s['n_slices']} slices, "
        f"{summary['workers']} workers:",
        f"  measured     {s['measured']:8.3f}   (Υ_F = {s['serial_time']:.3f} s, {source}; "
        f"Parareal {summary['timings']['total']:.3f} s)",
        f"  theoretical  {s['theoretical']:8.3f}   ({model}; γ_G/γ_F = {s['gamma_ratio']:.4f}"
        f"{_setup(s)})",
        f"  bound        {s['bound']:8.3f}   ({limit})",
    ]
    return "\n".join(lines)


def against_best_serial(summary: dict[str, Any], config: str | None, key: str) -> str:
    """The speedup report's line against the fastest serial run of the same accuracy: the
    measured and theoretical speedups over F's CPU time over that run's, from the cache beside
    the configuration ``config`` (``parastokes plan``) for the problem ``key``, at the run's
    last error η^K (the cache entry's own target when the run measured none); or the line that
    says none was measured and how to measure it."""
    s = summary["speedup"]
    errors = summary.get("errors") or []
    known = None if config is None else best_known(cache_path(config), key,
                                                   float(errors[-1]) if errors else None)
    if known is None:
        return f"  vs best serial      -      (none measured for this problem: {HOW_TO_MEASURE})"
    return (f"  vs best serial {s['measured'] / known.fine_over:8.3f}   (measured; theoretical "
            f"{s['theoretical'] / known.fine_over:.3f}: against {known.describe()}, the fastest "
            f"serial run reaching η* = {known.target:.3g}, cached in {known.source}; F takes "
            f"{known.fine_over:.3g}x its CPU)")
