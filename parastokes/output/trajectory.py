"""Results on disk: ``summary.json``, ``trajectory.h5`` with its XDMF sidecar, atomic array files.

``trajectory.h5`` (h5py) holds, for each run that was computed (``parareal`` and/or ``serial``):

- ``/<run>/time``: the frame times, shape (F,);
- ``/<run>/<body>/positions``: one extendible dataset per body, shape (F, M, 3), appended frame by
  frame (a serial run writes as it goes), and the body's node vectors, e.g. a rod's frames ``D1``,
  ``D2``, ``D3`` (F, M, 3), a rigid centre's pose ``orientation`` (F, 1, 4) and ``phase``
  (F, 1, 1), and its motion at the frame, which the state does not hold, from the system's rates
  at the frame: ``velocity`` U and ``angular_velocity`` Ω (F, 1, 3);

and once per file:

- ``/bodies/<body>/connectivity``: the cells of its topology (rods: the M - 1 segments; vesicles:
  the triangles), attributes ``kind``, ``topology`` and ``n_points``; its static marks, e.g.
  ``/bodies/<body>/tracked`` (vesicles): the tracked points of Fig. 11 as a 0/1 mask;
- ``/parareal_history``: per iteration k = 1..K the relative increment η̃^k and true error η^k
  (eq. 34; NaN without a serial reference), the final positions X^k at T_N, the wall time elapsed
  after the iteration, the serial and parallel sweep times, and the full timings as JSON;
- root attributes: the resolved configuration as JSON (``config``) and every parameter as its own
  attribute under its key path (``model.epsilon``, ``resolved.coarse_dt``, ...).

Every file is written atomically (:mod:`parastokes.core.files`); reading a damaged or foreign file
raises :class:`~parastokes.core.files.CorruptFileError` naming it.

``trajectory.xdmf`` describes the same data for ParaView/VisIt (XDMF 3): one temporal collection per
run, one grid per body with the topology of its layout (a Polyline per rod, a Triangle mesh per
vesicle), with the node vectors as attributes. The layout of every body comes from its kind
(:class:`parastokes.registry.kinds.BodyLayout`); this module knows no kind.
"""

from __future__ import annotations

import json
import math
import os
import xml.etree.ElementTree as ET
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from ..core.files import (
    CorruptFileError,
    FileWriteError,
    GuardedFile,
    InputFileError,
    Staging,
    check_input,
    read_input,
    read_npz,
    write_npz,
    write_text,
)
from ..registry.kinds import RESERVED_NAMES, BodyLayout

__all__ = [
    "HistoryRecord",
    "TrajectoryWriter",
    "load_arrays",
    "new_hdf5",
    "read_history",
    "read_summary",
    "read_trajectory",
    "save_arrays",
    "write_summary",
    "write_xdmf",
]

FORMAT = "parastokes.trajectory"
VERSION = 1
RUNS = ("parareal", "serial")


# ---- JSON ------------------------------------------------------------------------------------
def _plain(value: Any) -> Any:
    """JSON-ready copy: numpy scalars and arrays to Python, non-finite floats to None."""
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return _plain(value.item())
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def write_summary(path: str | os.PathLike, summary: Mapping[str, Any],
                  staging: Staging | None = None) -> None:
    """Write ``summary`` as strict JSON (NaN and infinities become null), atomically (through
    ``staging`` when given: in place when it commits)."""
    data = json.dumps(_plain(summary), indent=2, allow_nan=False).encode()
    if staging is None:
        write_text(path, data.decode())
    else:
        staging.write(path, lambda handle: handle.write(data))


#: The keys every run's ``summary.json`` has (docs/design.md); what reads one relies on them.
SUMMARY_KEYS = ("config", "mode", "iterations", "increments", "errors", "timings", "speedup",
                "workers", "final_positions")


def read_summary(path: str | os.PathLike) -> dict[str, Any]:
    """Read a ``summary.json``; :class:`~parastokes.core.files.CorruptFileError` names a damaged
    one."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(
            f"{path} does not exist: is {path.parent} the output directory of a finished run?"
        )
    try:
        summary = json.loads(read_input(path, "summary").decode("utf-8"))
    except InputFileError:
        raise
    except (OSError, ValueError) as error:
        raise CorruptFileError(path, f"not a readable summary ({error})") from None
    if not isinstance(summary, dict):
        raise CorruptFileError(path, "not a parastokes summary (not a JSON object)")
    missing = [key for key in SUMMARY_KEYS if key not in summary]
    if missing:
        raise CorruptFileError(path, f"not a complete parastokes summary (no {', '.join(missing)})")
    return summary


# ---- atomic array files ----------------------------------------------------------------------
def save_arrays(path: str | os.PathLike, meta: Mapping[str, Any], **arrays: np.ndarray) -> None:
    """Write arrays and a JSON-ready ``meta`` dict to an ``.npz`` file atomically."""
    write_npz(path, _plain(meta), **arrays)


def load_arrays(
    path: str | os.PathLike, required: tuple[str, ...] = ()
) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Read a file written by :func:`save_arrays`: ``(meta, arrays)`` (``required`` arrays must be
    there); :class:`~parastokes.core.files.CorruptFileError` names a damaged or foreign file."""
    return read_npz(path, required)


@contextmanager
def _reading(path: str | os.PathLike) -> Iterator[h5py.File]:
    """``path`` opened for reading; a damaged, foreign or incomplete file raises
    :class:`~parastokes.core.files.CorruptFileError` naming it."""
    if not Path(path).exists():
        raise FileNotFoundError(f"{path} does not exist")
    check_input(path, "trajectory")  # (h5py opens it by name: a pipe would block it)
    try:
        with h5py.File(path, "r", locking=False) as f:
            if f.attrs.get("format") != FORMAT:
                raise CorruptFileError(path, "not a parastokes trajectory file")
            yield f
    except CorruptFileError:
        raise
    except (OSError, KeyError, TypeError, json.JSONDecodeError) as error:
        raise CorruptFileError(
            path, f"damaged or incomplete trajectory ({error})", "rerun the run that wrote it"
        ) from None


# ---- HDF5 files ------------------------------------------------------------------------------
@contextmanager
def new_hdf5(staging: Staging, path: str | os.PathLike) -> Iterator[h5py.File]:
    """A new HDF5 file that becomes ``path`` when ``staging`` commits, written to its temporary
    file through a :class:`~parastokes.core.files.GuardedFile`: a full disk or a file-size limit
    raises :class:`~parastokes.core.files.FileWriteError` naming ``path`` when the block ends
    (h5py's own driver would crash the interpreter)."""
    path = Path(path)
    try:
        sink = GuardedFile(staging.temporary(path))
    except FileWriteError as error:
        raise FileWriteError(path, error) from None
    try:
        with h5py.File(sink, "w", locking=False) as f:
            yield f
    finally:
        sink.close()
    if sink.failed is not None:
        raise FileWriteError(path, sink.failed)


def _flat_attributes(prefix: str, value: Any, out: dict[str, Any]) -> None:
    if isinstance(value, Mapping):
        for key, item in value.items():
            _flat_attributes(f"{prefix}.{key}" if prefix else str(key), item, out)
    elif value is None:
        out[prefix] = "none"
    elif isinstance(value, list | tuple):
        if all(isinstance(v, int | float) and not isinstance(v, bool) for v in value):
            out[prefix] = np.asarray(value, dtype=float)
        else:
            out[prefix] = json.dumps(_plain(value))
    else:
        out[prefix] = value


class TrajectoryWriter:
    """Writes ``trajectory.h5``: frames of one or more runs, the history, all parameters.

    ``layout`` gives every body of the state: its rows, node vectors, topology and marks (from its
    kind, :mod:`parastokes.registry.kinds`). ``rates``: the system's ``rates(t, state)``, which
    the node vectors of a body's motion (its layout's ``rate_vectors``, e.g. a rigid body's
    ``velocity`` and ``angular_velocity``) are columns of; evaluated once per frame, and only when
    a body has such vectors (then it is required). Datasets are created on first use and extended
    frame by frame; the file is flushed after every frame, so an interrupted run leaves a readable
    file.
    """

    def __init__(
        self,
        path: str | os.PathLike,
        layout: Sequence[BodyLayout],
        *,
        config: Mapping[str, Any],
        rates: Callable[[float, np.ndarray], np.ndarray] | None = None,
    ) -> None:
        if not layout:
            raise ValueError("layout: need at least one body")
        for body in layout:
            labels = ["positions", *body.vectors, *body.rate_vectors]
            twice = sorted({label for label in labels if labels.count(label) > 1})
            if twice:
                raise ValueError(f"body {body.name!r}: its node vectors {twice} are named twice "
                                 "(positions, vectors and rate_vectors share the body's group)")
        moving = [body.name for body in layout if body.rate_vectors]
        if moving and rates is None:
            raise ValueError(f"bodies {moving} write node vectors of their motion (rate_vectors): "
                             "pass the system's rates, rates=system.rates")
        names = [body.name for body in layout]
        bad = sorted({n for n in names
                      if names.count(n) > 1 or "/" in n or n in RESERVED_NAMES or not n})
        if bad:
            raise ValueError(
                f"body names {bad} cannot be written: each must be distinct, non-empty, without "
                f"'/' and none of {list(RESERVED_NAMES)} (a body's layout is named after it, and "
                "a body of several parts gets '_part' suffixes); rename the body"
            )
        self.path = Path(path)
        self.layout = list(layout)
        self.rates = rates if moving else None
        # the run directory's lock (parastokes.output.rundir) keeps other runs out: HDF5's own file
        # locking, which many cluster file systems do not support, is not needed
        # written through a GuardedFile: a full disk or a file-size limit raises FileWriteError
        # naming the file, where h5py's own driver would crash the interpreter on close
        self._sink = GuardedFile(self.path)
        self.file = h5py.File(self._sink, "w", locking=False)
        try:
            self._header(config)
        except BaseException:
            self.close()
            raise

    def _header(self, config: Mapping[str, Any]) -> None:
        kinds = sorted({body.kind for body in self.layout})
        attrs = self.file.attrs
        attrs["format"] = FORMAT
        attrs["version"] = VERSION
        attrs["kind"] = kinds[0] if len(kinds) == 1 else "scene"
        attrs["config"] = json.dumps(_plain(config))
        flat: dict[str, Any] = {}
        _flat_attributes("", config, flat)
        for key, value in flat.items():
            attrs[key] = value
        for body in self.layout:
            group = self.file.create_group(f"bodies/{body.name}")
            group.attrs["kind"] = body.kind
            group.attrs["topology"] = body.topology
            group.attrs["n_points"] = body.rows
            group.create_dataset("connectivity", data=np.asarray(body.cells, dtype=np.int64))
            for name, mark in body.marks.items():
                group.create_dataset(name, data=np.asarray(mark))
        self._flush()

    def _flush(self) -> None:
        """Flush the file; :class:`~parastokes.core.files.FileWriteError` if a write failed."""
        self._sink.check()
        self.file.flush()
        self._sink.check()

    def __enter__(self) -> TrajectoryWriter:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def close(self) -> None:
        """Close the file; after a failed write, remove it and raise
        :class:`~parastokes.core.files.FileWriteError` (once)."""
        if self.file.id.valid:
            self.file.close()
        self._sink.close()
        if self._sink.failed is not None:
            self.path.unlink(missing_ok=True)
            failed, self._sink.failed = self._sink.failed, None
            raise FileWriteError(self.path, failed)

    def _extend(self, group: h5py.Group, name: str, frame: np.ndarray) -> None:
        if name not in group:
            group.create_dataset(
                name,
                shape=(0, *frame.shape),
                maxshape=(None, *frame.shape),
                chunks=(1, *frame.shape),
                dtype=frame.dtype,
            )
        data = group[name]
        data.resize(data.shape[0] + 1, axis=0)
        data[-1] = frame

    def append(self, run: str, t: float, state: np.ndarray) -> None:
        """Append the frame ``state`` at time ``t`` to run ``run`` (``"parareal"``/``"serial"``)."""
        if run not in RUNS:
            raise ValueError(f"run must be one of {RUNS}, got {run!r}")
        state = np.asarray(state, dtype=float)
        motion = None if self.rates is None else np.asarray(self.rates(float(t), state), float)
        frame: list[tuple[str, dict[str, np.ndarray]]] = []  # (all of it, before any is written)
        for layout in self.layout:
            rows = slice(layout.first, layout.first + layout.rows)
            part = state[rows]
            data = {"positions": np.ascontiguousarray(part[:, :3])}
            for label, columns in layout.vectors.items():
                data[label] = np.ascontiguousarray(part[:, columns])
            for label, columns in layout.rate_vectors.items():
                assert motion is not None  # (required by __init__ when a body has rate_vectors)
                data[label] = _rate_columns(motion, rows, columns, layout.name, label)
            frame.append((layout.name, data))
        group = self.file.require_group(run)
        self._extend(group, "time", np.asarray(float(t)))
        for name, data in frame:
            body = group.require_group(name)
            for label, value in data.items():
                self._extend(body, label, value)
        self._flush()

    def write_history(self, history: HistoryRecord) -> None:
        """Store the Parareal history in ``/parareal_history`` (replacing an earlier one)."""
        if "parareal_history" in self.file:
            del self.file["parareal_history"]
        group = self.file.create_group("parareal_history")
        k = len(history.increments)
        errors = history.errors
        group.create_dataset("iteration", data=np.arange(1, k + 1))
        group.create_dataset("increments", data=np.asarray(history.increments, dtype=float))
        group.create_dataset(
            "errors", data=np.full(k, np.nan) if errors is None else np.asarray(errors, float)
        )
        group.attrs["has_errors"] = errors is not None
        positions = np.asarray(history.final_positions, dtype=float).reshape(k, -1, 3)
        group.create_dataset("final_positions", data=positions)
        group.create_dataset("elapsed", data=np.asarray(history.elapsed, dtype=float))
        for key in ("serial_sweeps", "parallel_sweeps"):
            group.create_dataset(key, data=np.asarray(history.timings.get(key, []), dtype=float))
        group.attrs["timings"] = json.dumps(_plain(history.timings))
        self._flush()


def _rate_columns(rates: np.ndarray, rows: slice, columns: slice, body: str,
                  label: str) -> np.ndarray:
    """``rates[rows, columns]`` (one body's node vector of its motion); ValueError naming it when
    the rates have too few rows or columns."""
    value = rates[rows, columns] if rates.ndim == 2 else None
    if value is None or value.shape != (rows.stop - rows.start, columns.stop - columns.start):
        raise ValueError(f"body {body!r}: its {label} is columns {columns.start}:{columns.stop} "
                         f"of rows {rows.start}:{rows.stop} of the rates, which have shape "
                         f"{rates.shape}")
    return np.ascontiguousarray(value)


@dataclass
class HistoryRecord:
    """The per-iteration record of a Parareal run (k = 1..K), as stored in ``/parareal_history``.

    ``final_positions[k-1]`` are the positions of X^k at T_N; ``elapsed[k-1]`` the wall time from
    the start of the run to the end of iteration k; ``timings`` is ``Timings.to_dict()``.
    """

    increments: Sequence[float]
    errors: Sequence[float] | None
    final_positions: Sequence[np.ndarray]
    elapsed: Sequence[float]
    timings: Mapping[str, Any]


def read_history(path: str | os.PathLike) -> dict[str, Any] | None:
    """The Parareal history of a ``trajectory.h5`` as a dict of arrays (None if there is none)."""
    with _reading(path) as f:
        if "parareal_history" not in f:
            return None
        group = f["parareal_history"]
        out: dict[str, Any] = {key: group[key][()] for key in group}
        out["has_errors"] = bool(group.attrs["has_errors"])
        out["timings"] = json.loads(group.attrs["timings"])
        return out


def read_trajectory(path: str | os.PathLike, run: str | None = None) -> dict[str, Any]:
    """Frames of one run of a ``trajectory.h5``: ``{"run", "kind", "time", "bodies": {name:
    {"kind", "positions", "connectivity", marks ("tracked"), node vectors ("D1"..., a rigid
    centre's "orientation", "phase", "velocity", "angular_velocity")}}, "config"}``.

    ``run`` defaults to ``"parareal"`` when present, else ``"serial"``. A file that lacks a
    dataset, holds no frames, or whose frames disagree with its times or are not finite raises
    :class:`~parastokes.core.files.CorruptFileError` naming what is wrong.
    """
    with _reading(path) as f:
        available = [r for r in RUNS if r in f]
        if not available:
            raise CorruptFileError(path, "holds no frames (no serial or parareal run)",
                                   "rerun the run that wrote it")
        run = run or available[0]
        if run not in f:
            raise ValueError(f"{path} has no run {run!r}; it has {available}")
        bodies = {}
        for name, static in f["bodies"].items():
            body = {key: value[()] for key, value in f[run][name].items()}
            body.update({key: value[()] for key, value in static.items()})
            body["kind"] = str(static.attrs.get("kind", f.attrs["kind"]))
            bodies[name] = body
        data = {
            "run": run,
            "kind": str(f.attrs["kind"]),
            "time": f[run]["time"][()],
            "bodies": bodies,
            "config": json.loads(f.attrs["config"]),
        }
        static_names = {name: set(group) for name, group in f["bodies"].items()}
    _check_frames(path, data, static_names)
    return data


def _check_frames(path: str | os.PathLike, data: dict[str, Any],
                  static: Mapping[str, set[str]]) -> None:
    """:class:`~parastokes.core.files.CorruptFileError` unless every body of ``data`` (one run of a
    trajectory) has finite positions (F, M, 3) and node vectors (F, M, k) for its F finite,
    increasing times, and its connectivity."""
    times = np.asarray(data["time"], dtype=float)
    where = f"run {data['run']!r}"
    problems = []
    if times.ndim != 1 or len(times) == 0:
        problems.append(f"{where} holds no frames (time has shape {times.shape})")
    elif not (np.isfinite(times).all() and np.all(np.diff(times) > 0)):
        problems.append(f"the times of {where} are not finite and increasing")
    for name, body in data["bodies"].items():
        if "positions" not in body or "connectivity" not in body:
            lacking = [k for k in ("positions", "connectivity") if k not in body]
            problems.append(f"body {name!r} lacks its {' and '.join(lacking)}")
            continue
        rows = np.shape(body["positions"])[1:2]
        for key, value in body.items():
            if key in static.get(name, ()) or key == "kind":
                continue
            shape = np.shape(value)
            if len(shape) != 3 or shape[:2] != (len(times), *rows):
                problems.append(f"body {name!r}: {key} has shape {shape}, not one row per point "
                                f"for each of the {len(times)} frames")
            elif not np.isfinite(value).all():
                frame = int(np.argwhere(~np.isfinite(value))[0, 0])
                problems.append(f"body {name!r}: {key} is not finite in frame {frame}")
    if problems:
        raise CorruptFileError(path, "; ".join(problems[:3]), "rerun the run that wrote it")


# ---- XDMF ------------------------------------------------------------------------------------
def _data_item(parent: ET.Element, h5name: str, dataset: h5py.Dataset) -> ET.Element:
    """A DataItem referring to ``dataset`` of the HDF5 file ``h5name``."""
    item = ET.SubElement(
        parent,
        "DataItem",
        Dimensions=" ".join(map(str, dataset.shape)),
        NumberType="Float" if dataset.dtype.kind == "f" else "Int",
        Precision=str(dataset.dtype.itemsize),
        Format="HDF",
    )
    item.text = f"{h5name}:{dataset.name}"
    return item


def _slab(parent: ET.Element, h5name: str, dataset: h5py.Dataset, frame: int) -> None:
    """The frame ``frame`` of an (F, M, 3) dataset as an (M, 3) hyperslab."""
    _, rows, cols = dataset.shape
    slab = ET.SubElement(
        parent, "DataItem", ItemType="HyperSlab", Dimensions=f"{rows} {cols}", Type="HyperSlab"
    )
    select = ET.SubElement(slab, "DataItem", Dimensions="3 3", Format="XML")
    select.text = f"{frame} 0 0 1 1 1 1 {rows} {cols}"
    _data_item(slab, h5name, dataset)


def write_xdmf(h5_path: str | os.PathLike, xdmf_path: str | os.PathLike | None = None) -> Path:
    """Write the XDMF sidecar of a ``trajectory.h5`` (default: same name, ``.xdmf``).

    The sidecar refers to the HDF5 file by its name, so keep the two files side by side.
    """
    h5_path = Path(h5_path)
    xdmf_path = Path(xdmf_path) if xdmf_path is not None else h5_path.with_suffix(".xdmf")
    root = ET.Element("Xdmf", Version="3.0")
    domain = ET.SubElement(root, "Domain")
    h5name = h5_path.name
    with _reading(h5_path) as f:
        for run in (r for r in RUNS if r in f):
            series = ET.SubElement(
                domain, "Grid", Name=run, GridType="Collection", CollectionType="Temporal"
            )
            for i, t in enumerate(f[run]["time"][()]):
                step = ET.SubElement(
                    series,
                    "Grid",
                    Name=f"{run}_{i}",
                    GridType="Collection",
                    CollectionType="Spatial",
                )
                ET.SubElement(step, "Time", Value=repr(float(t)))
                for name, static in f["bodies"].items():
                    _body_grid(step, h5name, name, static, f[run][name], i)
    ET.indent(root)
    text = '<?xml version="1.0" ?>\n<!DOCTYPE Xdmf SYSTEM "Xdmf.dtd" []>\n'
    text += ET.tostring(root, encoding="unicode") + "\n"
    write_text(xdmf_path, text)
    return xdmf_path


def _body_grid(
    parent: ET.Element, h5name: str, name: str, static: h5py.Group, frames: h5py.Group, i: int
) -> None:
    grid = ET.SubElement(parent, "Grid", Name=name, GridType="Uniform")
    cells = static["connectivity"]
    topology = ET.SubElement(
        grid,
        "Topology",
        TopologyType=str(static.attrs["topology"]),
        NumberOfElements=str(cells.shape[0]),
        NodesPerElement=str(cells.shape[1]),
    )
    _data_item(topology, h5name, cells)
    geometry = ET.SubElement(grid, "Geometry", GeometryType="XYZ")
    _slab(geometry, h5name, frames["positions"], i)
    for label in sorted(set(frames) - {"positions"}):
        width = frames[label].shape[-1]  # 3: a vector (a rod's D1); 1: a scalar; 4: a quaternion
        kind = {1: "Scalar", 3: "Vector"}.get(width, "Matrix")
        attribute = ET.SubElement(grid, "Attribute", Name=label, AttributeType=kind, Center="Node")
        _slab(attribute, h5name, frames[label], i)
    for label in sorted(set(static) - {"connectivity"}):
        attribute = ET.SubElement(
            grid, "Attribute", Name=label, AttributeType="Scalar", Center="Node"
        )
        _data_item(attribute, h5name, static[label])
