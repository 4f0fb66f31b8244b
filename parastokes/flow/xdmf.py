"""Flow fields on disk: an HDF5 file of a structured grid with its XDMF sidecar (ParaView, VisIt).

``write_grid(stem, grid, times, velocities)`` writes ``stem.h5``:

- ``x``, ``y``, ``z``: the node coordinates along each axis; ``time`` (F,);
- ``velocity`` (F, nz, ny, nx, 3) and ``speed`` (F, nz, ny, nx): x fastest;
- attributes ``format = "parastokes.flow"``, ``origin``, ``spacing``, ``shape`` (nx, ny, nz) and
  whatever the caller adds (the run, the frames, whether u∞ is included);

and ``stem.xdmf``: a temporal collection of F grids, each a ``3DRectMesh`` (``VXVYVZ`` geometry:
the three axes by name, so no axis-order convention is involved) with the node-centred
``velocity`` (Vector) and ``speed`` (Scalar). ParaView opens the ``.xdmf`` as is (the XDMF3 reader):
Stream Tracer and Glyph work on it directly. Both files are written to temporary names and then
renamed (:class:`parastokes.core.files.Staging`), so a reader never sees half a file, and a full
disk or a file-size limit is a :class:`~parastokes.core.files.FileWriteError` naming the file.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from ..core.files import Staging, check_input, staged
from ..output.trajectory import new_hdf5
from .grids import Grid

__all__ = ["FORMAT", "read_grid", "suffixed", "write_grid"]

FORMAT = "parastokes.flow"


def _item(parent: ET.Element, h5name: str, path: str, shape: tuple[int, ...]) -> ET.Element:
    item = ET.SubElement(parent, "DataItem", Dimensions=" ".join(map(str, shape)),
                         NumberType="Float", Precision="8", Format="HDF")
    item.text = f"{h5name}:/{path}"
    return item


def _frame(parent: ET.Element, h5name: str, path: str, shape: tuple[int, ...], i: int,
           frames: int) -> None:
    """Frame ``i`` of the dataset ``path`` of shape (frames, *shape) as a hyperslab."""
    rank = len(shape) + 1
    slab = ET.SubElement(parent, "DataItem", ItemType="HyperSlab", Type="HyperSlab",
                         Dimensions=" ".join(map(str, shape)))
    select = ET.SubElement(slab, "DataItem", Dimensions=f"3 {rank}", Format="XML")
    select.text = " ".join(map(str, [i, *[0] * (rank - 1), *[1] * rank, 1, *shape]))
    _item(slab, h5name, path, (frames, *shape))


def _xdmf(h5name: str, grid: Grid, times: np.ndarray) -> str:
    nx, ny, nz = grid.shape
    dims = (nz, ny, nx)
    root = ET.Element("Xdmf", Version="3.0")
    domain = ET.SubElement(root, "Domain")
    series = ET.SubElement(domain, "Grid", Name="flow", GridType="Collection",
                           CollectionType="Temporal")
    for i, t in enumerate(times):
        step = ET.SubElement(series, "Grid", Name=f"flow_{i}", GridType="Uniform")
        ET.SubElement(step, "Time", Value=repr(float(t)))
        ET.SubElement(step, "Topology", TopologyType="3DRectMesh",
                      Dimensions=" ".join(map(str, dims)))
        geometry = ET.SubElement(step, "Geometry", GeometryType="VXVYVZ")
        for axis, n in zip("xyz", grid.shape, strict=True):
            _item(geometry, h5name, axis, (n,))
        velocity = ET.SubElement(step, "Attribute", Name="velocity", AttributeType="Vector",
                                 Center="Node")
        _frame(velocity, h5name, "velocity", (*dims, 3), i, len(times))
        speed = ET.SubElement(step, "Attribute", Name="speed", AttributeType="Scalar",
                              Center="Node")
        _frame(speed, h5name, "speed", dims, i, len(times))
    ET.indent(root)
    return ('<?xml version="1.0" ?>\n<!DOCTYPE Xdmf SYSTEM "Xdmf.dtd" []>\n'
            + ET.tostring(root, encoding="unicode") + "\n")


def suffixed(stem: Path, suffix: str) -> Path:
    """``stem`` + ``suffix`` (a stem may hold dots: ``flow_mean_0.01-0.02``)."""
    return stem.with_name(stem.name + suffix)


def write_grid(stem: str | os.PathLike, grid: Grid, times: np.ndarray, velocities: np.ndarray,
               attrs: Mapping[str, Any] | None = None,
               staging: Staging | None = None) -> tuple[Path, Path]:
    """Write ``stem.h5`` and ``stem.xdmf`` (module text): ``velocities`` (F, points, 3) at the
    grid's points at ``times`` (F,); returns the two paths. Through ``staging`` (moved into
    place when it commits), else moved into place at once."""
    if staging is None:
        with staged() as own:
            return write_grid(stem, grid, times, velocities, attrs, own)
    stem = Path(stem)
    times = np.atleast_1d(np.asarray(times, dtype=float))
    nx, ny, nz = grid.shape
    fields = np.asarray(velocities, dtype=float).reshape(len(times), nz, ny, nx, 3)
    h5_path, xdmf_path = suffixed(stem, ".h5"), suffixed(stem, ".xdmf")
    with new_hdf5(staging, h5_path) as f:
        f.attrs["format"] = FORMAT
        f.attrs["origin"] = np.asarray(grid.origin)
        f.attrs["spacing"] = np.asarray(grid.spacing)
        f.attrs["shape"] = np.asarray(grid.shape)
        for key, value in (attrs or {}).items():
            f.attrs[key] = value
        for axis, values in zip("xyz", grid.axes(), strict=True):
            f.create_dataset(axis, data=values)
        f.create_dataset("time", data=times)
        f.create_dataset("velocity", data=fields)
        f.create_dataset("speed", data=np.linalg.norm(fields, axis=-1))
    text = _xdmf(h5_path.name, grid, times).encode()
    staging.write(xdmf_path, lambda handle: handle.write(text))
    return h5_path, xdmf_path


def read_grid(path: str | os.PathLike) -> tuple[Grid, np.ndarray, np.ndarray]:
    """The grid, times (F,) and velocities (F, nz, ny, nx, 3) of a file of :func:`write_grid`."""
    path = Path(path) if Path(path).suffix == ".h5" else suffixed(Path(path), ".h5")
    check_input(path, "flow")  # (h5py opens it by name: a pipe would block it)
    with h5py.File(path, "r", locking=False) as f:
        if f.attrs.get("format") != FORMAT:
            raise ValueError(f"{path}: not a parastokes flow file")
        grid = Grid.of(f.attrs["origin"], f.attrs["spacing"], f.attrs["shape"])
        return grid, f["time"][()], f["velocity"][()]
