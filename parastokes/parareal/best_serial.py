"""The fastest serial run of a given accuracy, from measured serial runs: what a speedup of
Parareal is worth against a serial solver chosen for the accuracy Parareal delivers, rather than
against the fine solver F it is built on (the paper's speedups are against F).

The measurements are a JSON file written by ``benchmarks/stiff.py`` (``best_serial.json``,
docs/benchmarks.md, "Speedup against the best serial run"): per case (a fine problem of the
paper: model, T and F), F's scheme and step, and serial runs of other schemes and steps with
their error at T against F (eq. 34) and their CPU time, each beside F's CPU time measured in the
same process (``fine_cpu``), so that the ratio of the two is what counts on a shared machine.
Each case also holds ``problem``, the :func:`fingerprint` of the problem it was measured on (the
model with every parameter, the interval and F, :func:`problem`): :meth:`SerialRuns.check_problem`
refuses a configuration of another problem, even with the same F and T.

The search of ``parastokes plan`` (:mod:`parastokes.planning.baseline`) keeps what it measured in
a cache beside the configuration, ``CONFIG.best_serial.json`` (:func:`cache_path`), one entry
per problem and target (:func:`cached_entries`, :func:`best_known`): run, predict and tune name
the fastest serial run from it when one is known.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..core.files import InputFileError, read_input

__all__ = ["KnownBaseline", "SerialRow", "SerialRuns", "best_known", "cache_path",
           "cached_entries", "fingerprint", "load_serial_runs", "problem"]

#: The advice printed wherever no fastest serial run is known for a problem.
HOW_TO_MEASURE = ("measure it with `parastokes plan CONFIG --cores N --target ETA --out PLAN.toml` "
                  "(cached beside CONFIG) or give measured runs with `predict --serial FILE.json`")


def problem(model: Mapping[str, Any], t0: float, t1: float,
            fine: Mapping[str, Any]) -> dict[str, Any]:
    """What a serial baseline depends on: the body (``model``, its section with every parameter,
    as dumped to JSON), the interval [t0, t1] and F (``fine``: scheme, dt, rtol, atol)."""
    return {"model": dict(model), "t0": float(t0), "t1": float(t1),
            "fine": {k: v for k, v in fine.items() if v is not None}}


def fingerprint(case: Mapping[str, Any]) -> str:
    """A short hash of a :func:`problem` (SHA-256 of its canonical JSON, 16 hex digits): equal
    for the same model, parameters, interval and F, different when any of them changes."""
    text = json.dumps(case, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class SerialRow:
    """One measured serial run: ``scheme`` at step ``dt``, its ``error`` at T against F and F's
    CPU time over its own (``fine_over``; 1 for F itself)."""

    scheme: str
    dt: float
    error: float
    fine_over: float

    def describe(self) -> str:
        return f"{self.scheme} at dt = {self.dt:.3g}"


@dataclass(frozen=True)
class SerialRuns:
    """The measured serial runs of one case: F (``reference``), the others (``rows``) and the
    interval ``t1`` they ran over (from t = 0)."""

    case: str
    t1: float
    reference: SerialRow
    rows: tuple[SerialRow, ...]
    problem: str | None = None  # its fingerprint (None: a file written before it was recorded)
    source: str = ""

    def best(self, target: float) -> SerialRow:
        """The run that reaches ``target`` (error at T at most ``target``) in the least CPU time
        relative to F; F itself when no other run does."""
        reaching = [row for row in self.rows if row.error <= target]
        return max(reaching, key=lambda row: row.fine_over, default=self.reference)

    def check_fine(self, scheme: str, dt: float, t_span: float) -> None:
        """Refuse (ValueError naming both) a configuration whose F or interval is not the one
        these runs were measured against: its speedups would be against another solver."""
        ref = self.reference
        same = (scheme == ref.scheme and math.isclose(dt, ref.dt, rel_tol=1e-9)
                and math.isclose(t_span, self.t1, rel_tol=1e-9))
        if not same:
            raise ValueError(
                f"the serial runs of case {self.case!r} were measured against F = "
                f"{ref.describe()} over T = {self.t1:g}, but the configuration's F is {scheme} at "
                f"dt = {dt:.3g} over T = {t_span:g}: choose the case of this problem (--case) or "
                "measure its serial runs (benchmarks/stiff.py)")

    def check_problem(self, key: str) -> None:
        """Refuse (ValueError) a configuration whose problem (:func:`fingerprint` ``key``) is not
        the one these runs were measured on, or any when the file records none."""
        where = f"case {self.case!r} of {self.source or 'the file'}"
        if self.problem is None:
            raise ValueError(
                f"{where} records no problem fingerprint (a file written before they were "
                "recorded), so it cannot be checked to be this configuration's problem (model, "
                "parameters, T, F): measure it again (benchmarks/stiff.py --parts best_serial "
                f"records it) or {HOW_TO_MEASURE}")
        if self.problem != key:
            raise ValueError(
                f"{where} was measured on another problem (fingerprint {self.problem}; this "
                f"configuration's is {key}): the model, a parameter, T or F differ, so its "
                f"serial runs are not this problem's; choose its case (--case) or "
                f"{HOW_TO_MEASURE}")


def load_serial_runs(path: str | os.PathLike, case: str | None = None) -> SerialRuns:
    """The case ``case`` of the file ``path`` (the only one when ``case`` is None); a ValueError
    names a missing file, case or field."""
    path = Path(path)
    try:
        data: dict[str, Any] = json.loads(read_input(path, "serial runs"))
        cases = data["cases"]
        if not isinstance(cases, dict) or not all(isinstance(e, dict) for e in cases.values()):
            raise TypeError("'cases' is not a table of cases")
    except InputFileError:
        raise
    except (OSError, ValueError, KeyError, TypeError) as error:
        raise ValueError(f"{path}: not a file of measured serial runs ({error})") from None
    if case is None:
        if len(cases) != 1:
            raise ValueError(f"{path} holds the cases {sorted(cases)}: choose one with --case")
        (case,) = cases
    if case not in cases:
        raise ValueError(f"{path} has no case {case!r}; it has {sorted(cases)}")
    entry, where = cases[case], f"{path}, case {case!r}"
    ref = entry.get("reference")
    reference = SerialRow(_field(ref, "scheme", f"{where}, reference"),
                          float(_field(ref, "dt", f"{where}, reference")), 0.0, 1.0)
    rows = entry.get("rows")
    if not isinstance(rows, list):
        raise ValueError(f"{where}: rows must be a list of runs, got {rows!r}; {_REMEDY}")
    runs = []
    for i, row in enumerate(rows):
        scheme, dt, eta, cpu, fine_cpu = (_field(row, key, f"{where}, row {i}")
                                          for key in ("scheme", "dt", "error", "cpu", "fine_cpu"))
        runs.append(SerialRow(scheme, float(dt), float(eta), fine_cpu / cpu))
    return SerialRuns(case, float(_field(entry, "t1", where)), reference, tuple(runs),
                      entry.get("problem"), str(path))


_REMEDY = "measure the runs again (benchmarks/stiff.py --parts best_serial)"


def _field(record: Any, key: str, where: str) -> Any:
    """``record[key]`` of a file of serial runs, checked: a scheme's name for ``scheme``, else a
    finite number, positive (at least 0 for ``error``); a ValueError names ``where`` and the key
    when it is missing or wrong (a corrupt or hand-edited file)."""
    value = record.get(key) if isinstance(record, dict) else None
    if key == "scheme":
        good, wanted = isinstance(value, str) and value != "", "a scheme's name"
    else:
        good = (isinstance(value, int | float) and not isinstance(value, bool)
                and math.isfinite(value) and (value >= 0 if key == "error" else value > 0))
        wanted = "a finite number at least 0" if key == "error" else "a positive finite number"
    if not good:
        raise ValueError(f"{where}: {key} must be {wanted}, got {value!r}; {_REMEDY}")
    return value


def cache_path(config: str | os.PathLike) -> Path:
    """The baseline cache of a configuration file: CONFIG.best_serial.json beside it."""
    path = Path(config)
    return path.with_name(f"{path.stem}.best_serial.json")


def cached_entries(path: str | os.PathLike, key: str) -> list[dict[str, Any]]:
    """The entries of the cache ``path`` measured on the problem of fingerprint ``key`` (none
    when the file does not exist, cannot be read or is not a cache: it is only a cache)."""
    try:
        data = json.loads(read_input(path, "measurements"))
        entries = data["entries"]
        return [e for e in entries.values() if isinstance(e, dict) and e.get("problem") == key]
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return []


@dataclass(frozen=True)
class KnownBaseline:
    """The fastest cached serial run reaching ``target`` (``row``: scheme, dt or rtol, error,
    cpu_seconds over the whole interval), F's CPU time over the same interval measured in the
    same search (``fine_cpu``) and the cache it came from."""

    row: dict[str, Any]
    fine_cpu: float
    target: float
    source: str

    @property
    def fine_over(self) -> float:
        """F's CPU time over the fastest serial run's: a speedup against F divided by this is
        the speedup against the fastest serial run."""
        return self.fine_cpu / float(self.row["cpu_seconds"])

    def describe(self) -> str:
        row = self.row
        step = f"rtol = {row['rtol']:.3g}" if row.get("rtol") is not None else \
            f"dt = {row['dt']:.3g}"
        return (f"{row['scheme']} at {step} (error {row['error']:.3g}, "
                f"{row['cpu_seconds']:.3g} s CPU over T; F {self.fine_cpu:.3g} s)")


def best_known(path: str | os.PathLike, key: str, target: float | None = None
               ) -> KnownBaseline | None:
    """The fastest run of the cache ``path`` on the problem ``key`` whose error at T is at most
    ``target`` (default: each entry's own target), among every entry of that problem; None when
    the cache holds none."""
    best: KnownBaseline | None = None
    for entry in cached_entries(path, key):
        goal = float(entry["target"]) if target is None else target
        fine_cpu = float(entry["fine"]["cpu_seconds"])
        for row in entry.get("rows", []):
            if row.get("error") is None or not row["error"] <= goal:
                continue
            if best is None or row["cpu_seconds"] < best.row["cpu_seconds"]:
                best = KnownBaseline(row, fine_cpu, goal, str(path))
    return best
