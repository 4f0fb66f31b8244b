"""Output files: summary.json, trajectory.h5 (reopened and checked) and its XDMF sidecar."""

from __future__ import annotations

import dataclasses
import json
import math
import xml.etree.ElementTree as ET

import h5py
import numpy as np
import pytest

from parastokes.core import files
from parastokes.output import trajectory as io
from parastokes.registry import kinds as registry

CONFIG = {"model": {"kind": "rod", "epsilon": 5.0, "shear": [0.6, 0.6, 0.6]}, "title": "t"}


def rod_layout(n_rods: int, m: int) -> list[registry.BodyLayout]:
    """The rod kind's layout of ``n_rods`` rods of ``m`` nodes."""
    kind = registry.get("rod")
    return kind.layout(kind.section(kind="rod", n_rods=n_rods, n_points=m), None, True, None)


def rod_state(n_rods: int, m: int, shift: float) -> np.ndarray:
    rng = np.random.default_rng(int(shift * 10))
    return rng.normal(size=(n_rods * m, 12)) + shift


def test_summary_is_strict_json_with_numpy_values(tmp_path):
    path = tmp_path / "summary.json"
    io.write_summary(
        path, {"a": np.float64(1.5), "b": np.arange(3), "c": [math.nan, math.inf], "d": None}
    )
    text = path.read_text()
    assert "NaN" not in text and "Infinity" not in text
    assert json.loads(text) == {"a": 1.5, "b": [0, 1, 2], "c": [None, None], "d": None}
    # read back as a run's summary only with a run's keys
    with pytest.raises(files.CorruptFileError, match="not a complete parastokes summary"):
        io.read_summary(path)
    io.write_summary(path, dict.fromkeys(io.SUMMARY_KEYS, np.arange(2)))
    assert io.read_summary(path)["timings"] == [0, 1]


def test_arrays_round_trip_with_metadata(tmp_path):
    states = np.random.default_rng(0).normal(size=(3, 4, 12))
    io.save_arrays(tmp_path / "x.npz", {"key": "abc", "wall_time": 1.25}, states=states)
    meta, arrays = io.load_arrays(tmp_path / "x.npz")
    assert meta == {"key": "abc", "wall_time": 1.25}
    np.testing.assert_array_equal(arrays["states"], states)
    assert not list(tmp_path.glob("*.tmp"))  # the temporary file was renamed


def write_rods(path, n_frames=3):
    states = [rod_state(2, 5, float(i)) for i in range(n_frames)]
    with io.TrajectoryWriter(path, rod_layout(2, 5), config=CONFIG) as writer:
        for i, state in enumerate(states):
            writer.append("serial", 0.1 * i, state)
            writer.append("parareal", 0.1 * i, state + 1)
        writer.write_history(
            io.HistoryRecord(
                increments=[1e-3, 1e-5],
                errors=None,
                final_positions=[states[-1][:, :3], states[-1][:, :3] * 2],
                elapsed=[1.0, 2.0],
                timings={"serial_sweeps": [0.1, 0.2, 0.3], "parallel_sweeps": [0.5, 0.6]},
            )
        )
    return states


def test_rod_trajectory_round_trip(tmp_path):
    path = tmp_path / "trajectory.h5"
    states = write_rods(path)
    with h5py.File(path, "r") as f:
        assert f.attrs["format"] == io.FORMAT
        assert json.loads(f.attrs["config"]) == CONFIG
        assert f.attrs["model.epsilon"] == 5.0  # every parameter as its own attribute
        np.testing.assert_array_equal(f.attrs["model.shear"], [0.6, 0.6, 0.6])
        positions = f["serial/rod_1/positions"]
        assert positions.shape == (3, 5, 3)
        assert positions.maxshape == (None, 5, 3)  # extendible
        np.testing.assert_array_equal(positions[2], states[2][5:, :3])
        np.testing.assert_array_equal(f["serial/rod_0/D3"][1], states[1][:5, 9:12])
        np.testing.assert_array_equal(
            f["bodies/rod_0/connectivity"][()], [[0, 1], [1, 2], [2, 3], [3, 4]]
        )
    data = io.read_trajectory(path)
    assert data["run"] == "parareal"  # the default when present
    np.testing.assert_array_equal(data["time"], [0.0, 0.1, 0.2])
    np.testing.assert_array_equal(data["bodies"]["rod_0"]["positions"][0], states[0][:5, :3] + 1)
    history = io.read_history(path)
    assert history["has_errors"] is False
    assert np.isnan(history["errors"]).all()
    np.testing.assert_array_equal(history["increments"], [1e-3, 1e-5])
    np.testing.assert_array_equal(history["final_positions"][1], states[-1][:, :3] * 2)
    np.testing.assert_array_equal(history["parallel_sweeps"], [0.5, 0.6])
    assert history["timings"]["serial_sweeps"] == [0.1, 0.2, 0.3]


def test_reading_a_missing_run_fails_clearly(tmp_path):
    path = tmp_path / "trajectory.h5"
    with io.TrajectoryWriter(path, rod_layout(1, 3), config={}) as writer:
        writer.append("serial", 0.0, rod_state(1, 3, 0.0))
    assert io.read_trajectory(path)["run"] == "serial"
    assert io.read_history(path) is None
    with pytest.raises(ValueError, match="no run 'parareal'"):
        io.read_trajectory(path, "parareal")
    with pytest.raises(ValueError, match="run must be one of"):
        writer = io.TrajectoryWriter(tmp_path / "b.h5", rod_layout(1, 3), config={})
        writer.append("other", 0.0, rod_state(1, 3, 0.0))


@pytest.mark.parametrize("names", [("a", "a"), ("time",), ("a/b",), ("",)])
def test_layout_names_that_cannot_be_written_are_refused_before_the_file(tmp_path, names):
    layouts = [dataclasses.replace(rod_layout(1, 3)[0], name=name) for name in names]
    with pytest.raises(ValueError, match="cannot be written"):
        io.TrajectoryWriter(tmp_path / "t.h5", layouts, config={})
    assert not (tmp_path / "t.h5").exists()


def check_xdmf(xdmf_path, h5_path) -> ET.Element:
    """Every HDF5 reference of the XDMF file exists with the stated dimensions."""
    root = ET.parse(xdmf_path).getroot()
    with h5py.File(h5_path, "r") as f:
        items = [d for d in root.iter("DataItem") if d.get("Format") == "HDF"]
        assert items
        for item in items:
            name, _, dataset = item.text.strip().partition(":")
            assert name == h5_path.name
            dims = tuple(int(v) for v in item.get("Dimensions").split())
            assert f[dataset].shape == dims
            assert int(item.get("Precision")) == f[dataset].dtype.itemsize
    return root


def test_xdmf_sidecar_describes_rods(tmp_path):
    path = tmp_path / "trajectory.h5"
    write_rods(path)
    xdmf = io.write_xdmf(path)
    assert xdmf == tmp_path / "trajectory.xdmf"
    root = check_xdmf(xdmf, path)
    series = root.findall("Domain/Grid")
    assert [g.get("Name") for g in series] == ["parareal", "serial"]
    assert all(g.get("CollectionType") == "Temporal" for g in series)
    steps = series[0].findall("Grid")
    assert [float(s.find("Time").get("Value")) for s in steps] == [0.0, 0.1, 0.2]
    rod = steps[2].find("Grid")
    assert rod.find("Topology").get("TopologyType") == "Polyline"
    slab = rod.find("Geometry/DataItem")
    assert slab.get("ItemType") == "HyperSlab"
    assert slab.find("DataItem").text.split()[0] == "2"  # frame index of the third time step
    assert {a.get("Name") for a in rod.findall("Attribute")} == {"D1", "D2", "D3"}


def test_vesicle_trajectory_and_xdmf(tmp_path):
    verts = np.random.default_rng(1).normal(size=(6, 3))
    tris = np.array([[0, 1, 2], [2, 3, 4], [3, 4, 5]])
    path = tmp_path / "trajectory.h5"
    mask = np.array([0, 1, 0, 0, 1, 0], dtype=np.int32)
    layout = registry.BodyLayout(
        "vesicle_0", "vesicle", 0, 6, "Triangle", tris, marks={"tracked": mask}
    )
    with io.TrajectoryWriter(path, [layout], config={}) as writer:
        writer.append("parareal", 0.0, verts)
        writer.append("parareal", 1.0, verts * 2)
    data = io.read_trajectory(path)
    body = data["bodies"]["vesicle_0"]
    np.testing.assert_array_equal(body["connectivity"], tris)
    np.testing.assert_array_equal(np.flatnonzero(body["tracked"]), [1, 4])
    np.testing.assert_array_equal(body["positions"][1], verts * 2)
    assert "D1" not in body
    root = check_xdmf(io.write_xdmf(path), path)
    grid = root.find("Domain/Grid/Grid/Grid")
    assert grid.find("Topology").get("TopologyType") == "Triangle"
    assert grid.find("Topology").get("NumberOfElements") == "3"
    assert grid.find("Attribute").get("Name") == "tracked"


def _read_with_vtk(xdmf_path):
    """Every time step of the XDMF file as read by VTK's XDMF reader (the one ParaView uses for
    XDMF 2 files): a list of (time, [(points, n_cells, point-array names) per body])."""
    xdmf2 = pytest.importorskip("vtkmodules.vtkIOXdmf2", reason="VTK (pip install vtk) not found")
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkCommonExecutionModel import vtkStreamingDemandDrivenPipeline

    reader = xdmf2.vtkXdmfReader()
    reader.SetFileName(str(xdmf_path))
    reader.UpdateInformation()
    times = reader.GetOutputInformation(0).Get(vtkStreamingDemandDrivenPipeline.TIME_STEPS())
    frames = []
    for t in times:
        reader.UpdateTimeStep(t)
        series = reader.GetOutputDataObject(0).GetBlock(0)  # the first temporal collection
        bodies = []
        for i in range(series.GetNumberOfBlocks()):
            grid = series.GetBlock(i)
            data = grid.GetPointData()
            names = {data.GetArrayName(k) for k in range(data.GetNumberOfArrays())}
            points = vtk_to_numpy(grid.GetPoints().GetData())
            bodies.append((points, grid.GetNumberOfCells(), names))
        frames.append((t, bodies))
    return frames


def test_vtk_reads_the_xdmf_sidecar_as_paraview_would(tmp_path):
    path = tmp_path / "trajectory.h5"
    states = write_rods(path)
    frames = _read_with_vtk(io.write_xdmf(path))
    assert [t for t, _ in frames] == pytest.approx([0.0, 0.1, 0.2])
    for (_, bodies), state in zip(frames, states, strict=True):
        assert len(bodies) == 2
        for rod, (points, n_cells, names) in enumerate(bodies):
            np.testing.assert_array_equal(points, state[rod * 5 : (rod + 1) * 5, :3] + 1)
            assert n_cells == 4  # a polyline of 5 nodes
            assert names == {"D1", "D2", "D3"}
