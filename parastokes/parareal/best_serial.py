"""The fastest serial run of a given accuracy, from measured serial runs: what a speedup of
Parareal is worth against a serial solver chosen for the accuracy Parareal delivers, rather than
against the fine solver F it is built on (the paper's speedups are against F).

The measurements are a JSON file written by ``benchmarks/stiff.py`` (``best_serial.json``,
docs/benchmarks.md, "Speedup against the best serial run"): per case (a fine problem of the
paper: model, T and F), F's scheme and step, and serial runs of other schemes and steps with
their error at T against F (eq. 34) and their CPU time, each beside F's CPU time measured in the
same process (``fine_cpu``), so that the ratio of the two is what counts on a shared machine.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..core.files import InputFileError, read_input

__all__ = ["SerialRow", "SerialRuns", "load_serial_runs"]


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
        scheme, dt, error, cpu, fine_cpu = (_field(row, key, f"{where}, row {i}")
                                            for key in ("scheme", "dt", "error", "cpu", "fine_cpu"))
        runs.append(SerialRow(scheme, float(dt), float(error), fine_cpu / cpu))
    return SerialRuns(case, float(_field(entry, "t1", where)), reference, tuple(runs))


_REMEDY = "measure the runs again (benchmarks/stiff.py --parts best_serial)"


def _field(record: Any, key: str, where: str) -> Any:
    """``record[key]`` of a file of serial runs, checked: a scheme's name for ``scheme``, else a
    finite number, positive (at least 0 for ``error``); a ValueError names ``where`` and the key
    when it is missing or wrong (a corrupt or hand-edited file)."""
    value = record.get(key) if isinstance(record, dict) else None
    if key == "scheme":
        good, wanted = isinstance(value, str) and value != "", "a scheme's name"
    else:
        number = isinstance(value, int | float) and not isinstance(value, bool)
        good = number and math.isfinite(value) and (value >= 0 if key == "error" else value > 0)
        wanted = "a finite number at least 0" if key == "error" else "a positive finite number"
    if not good:
        raise ValueError(f"{where}: {key} must be {wanted}, got {value!r}; {_REMEDY}")
    return value
