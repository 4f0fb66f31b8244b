"""Work-precision diagrams (error at T against CPU, log-log) from the measured JSON of
``benchmarks/stiff.py`` and ``benchmarks/adaptive.py`` (docs/benchmarks.md, "Work-precision
diagrams (round 5)"). Measures nothing: it only plots the rows those scripts wrote.

Run from the repository root::

    PYTHONPATH=. python benchmarks/work_precision.py

It also prints, per ``auto`` run, the cheapest fixed-step run of the same problem reaching its
error and auto's CPU over that run's (:func:`auto_against_fixed`).

Writes ``docs/figures/stiff/work_precision_{rod301,rod601,rod1201,vesicle}.png``. The CPU axis
is each run's CPU time over that of RK2 just below forward Euler's limit measured in the same
process (the entry ``rk2`` of ``adaptive.py``'s files; the RK2 row of largest step in the files of
``stiff.py``), so that files measured in different processes share one axis.
"""

from __future__ import annotations

import json
import math
import pathlib
import textwrap
from typing import Any

from parastokes import integrate

OUT = pathlib.Path(__file__).resolve().parents[1] / "docs" / "figures" / "stiff"

#: The families, in legend order, with their matplotlib line styles.
FAMILIES = {"fixed explicit": "--s", "fixed implicit": "-o", "adaptive": ":^", "auto": "-*"}

#: Per problem: the JSON files that hold its runs, the title, and the commands behind them.
PROBLEMS: dict[str, tuple[tuple[str, ...], str, str]] = {
    "rod301": (("short_rod301.json", "adaptive_rod301.json"),
               "rod M = 301, ε = 1 μm, above the wall, T = 0.005 s",
               "file 1: benchmarks/stiff.py --parts short; file 2: benchmarks/adaptive.py"),
    "rod601": (("short_rod601.json", "adaptive_rod601.json"),
               "rod M = 601, ε = 0.5 μm, above the wall, T = 0.005 s",
               "file 1: benchmarks/stiff.py --parts short; "
               "file 2: benchmarks/adaptive.py --problem rod601"),
    "rod1201": (("short_rod1201.json", "adaptive_rod1201.json"),
                "rod M = 1201, ε = 0.25 μm, above the wall, T = 2.5e-4 s",
                "file 1: benchmarks/stiff.py --parts short1201; "
                "file 2: benchmarks/adaptive.py --problem rod1201"),
    "vesicle": (("vesicle.json", "adaptive_vesicle.json"),
                "vesicle, 642 points, shear 0.1, κ = 0.1, T = 10",
                "file 1: benchmarks/stiff.py --parts vesicle; "
                "file 2: benchmarks/adaptive.py --problem vesicle"),
}


def explicit_cpu(data: dict[str, Any]) -> float:
    """CPU time of the explicit run every ratio of one file is taken against: the ``rk2`` entry
    of ``adaptive.py``'s file, else the RK2 row of largest step (the one at the limit)."""
    if "rk2" in data:
        return float(data["rk2"]["cpu"])
    rk2 = [r for r in data["rows"] if r["scheme"] == "rk2" and r.get("dt") is not None]
    if not rk2:
        raise ValueError("no RK2 row to take CPU ratios against")
    return float(max(rk2, key=lambda r: r["dt"])["cpu"])


def family(row: dict[str, Any]) -> str:
    """The family of one measured run: ``auto``, ``adaptive`` (a tolerance, no fixed step),
    or fixed explicit/implicit (by ``integrate.SCHEMES[name].implicit``)."""
    if row["scheme"] == "auto":
        return "auto"
    if row.get("rtol") is not None:
        return "adaptive"
    return "fixed implicit" if integrate.SCHEMES[row["scheme"]].implicit else "fixed explicit"


def series(files: list[dict[str, Any]]) -> dict[str, dict[str, list[tuple[float, float]]]]:
    """``{family: {label: [(cpu ratio, error at T), ...]}}`` over the finite, positive errors of
    the rows of ``files`` (blown-up runs and errors that round to zero are left out), each
    from the largest error to the smallest (coarse step or tolerance first). The label is the
    scheme, with the Jacobian refresh when it is not 5, and the file's number (from 1) when an
    earlier file already holds the same family and label."""
    out: dict[str, dict[str, list[tuple[float, float]]]] = {f: {} for f in FAMILIES}
    for index, data in enumerate(files):
        base = explicit_cpu(data)
        seen: set[tuple[str, str]] = set()
        for row in data["rows"]:
            if not (math.isfinite(row["error"]) and row["error"] > 0):
                continue
            fam = family(row)
            label = row["scheme"]
            if fam == "fixed implicit" and row.get("refresh", 5) != 5:
                label += f", J every {row['refresh']}"
            if (fam, label) not in seen and label in out[fam]:
                label += f" (file {index + 1})"
            seen.add((fam, label))
            out[fam].setdefault(label, []).append((row["cpu"] / base, row["error"]))
    for fam in out.values():
        for points in fam.values():
            points.sort(key=lambda p: -p[1])
    return out


def _fixed_runs(files: list[dict[str, Any]]) -> list[tuple[float, float, str]]:
    """``(cpu ratio, error, "SCHEME at DT s")`` of every fixed-step run of ``files`` with a
    finite, positive error (``adaptive.py``'s ``rk2`` entry included)."""
    out = []
    for data in files:
        base = explicit_cpu(data)
        rows = data["rows"] + ([dict(data["rk2"], scheme="rk2")] if "rk2" in data else [])
        out += [(r["cpu"] / base, r["error"], f"{r['scheme']} at {r['dt']:g} s") for r in rows
                if family(r).startswith("fixed") and math.isfinite(r["error"]) and r["error"] > 0]
    return out


def auto_against_fixed(files: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per ``auto`` run of ``files``: its rtol, error, CPU ratio, the cheapest fixed-step run
    (by CPU ratio) whose error is at most auto's (None where none is), auto's CPU over that
    run's and its error over its rtol: the target's "within 1.3x of the best fixed choice,
    error within 3x of the tolerance"."""
    fixed = _fixed_runs(files)
    out = []
    for data in files:
        base = explicit_cpu(data)
        for r in data["rows"]:
            if r["scheme"] != "auto":
                continue
            cpu = r["cpu"] / base
            best = min((f for f in fixed if f[1] <= r["error"]), default=None)
            out.append({"rtol": r["rtol"], "error": r["error"], "cpu": cpu,
                        "best": best and best[2], "best_cpu": best and best[0],
                        "over_best": best and cpu / best[0],
                        "error_over_rtol": r["error"] / r["rtol"]})
    return out


def skipped(files: list[dict[str, Any]]) -> list[str]:
    """``"SCHEME at rtol R"`` for each run the files record as not run (``adaptive.py``'s
    ``skipped``: its predicted CPU time was above the cap)."""
    return [f"{s['scheme']} at rtol {s['rtol']:g}" for data in files
            for s in data.get("skipped", [])]


def draw(name: str) -> pathlib.Path:
    """The diagram of problem ``name`` of :data:`PROBLEMS`, saved as a PNG; returns its path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    files, title, command = PROBLEMS[name]
    data = [json.loads((OUT / f).read_text()) for f in files]
    fig, ax = plt.subplots(figsize=(7.5, 5.2))
    colors = iter(plt.get_cmap("tab20").colors * 2)
    for fam, style in FAMILIES.items():
        for label, points in series(data)[fam].items():
            ax.loglog(*zip(*points, strict=True), style, label=f"{fam}: {label}",
                      color="black" if fam == "auto" else next(colors),
                      markersize=10 if fam == "auto" else 6)
    label = "CPU time / RK2 at the explicit limit (same process)"
    if skipped(data):
        label += "\n" + textwrap.fill("not run (predicted CPU above the cap): "
                                      + ", ".join(skipped(data)), 110)
    ax.set_xlabel(label, fontsize=9)
    ax.set_ylabel("error at T (relative)")
    ax.set_title(f"{title}\n{command}", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    path = OUT / f"work_precision_{name}.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def main() -> int:
    for name, (files, _, _) in PROBLEMS.items():
        print(draw(name))
        for a in auto_against_fixed([json.loads((OUT / f).read_text()) for f in files]):
            best = (f"{a['best']} ({a['best_cpu']:.3g}): {a['over_best']:.2f}x" if a["best"]
                    else "no fixed run reaches it")
            print(f"  auto rtol {a['rtol']:g}: error {a['error']:.2g} "
                  f"({a['error_over_rtol']:.2g} x rtol), CPU {a['cpu']:.3g}; best fixed {best}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
