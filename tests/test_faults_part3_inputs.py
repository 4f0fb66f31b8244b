"""The third fault campaign (issue 50), its inputs: every file the package reads goes through one
bounded reader (parastokes.core.files.read_input / open_input / check_input: a regular file, a
size cap per kind, refused in one line before it is opened), a MemoryError is a one-line error,
a trajectory that lacks a body's frames or pose is named, the documented `predict` command prints
the documented numbers, `predict`'s values and files of serial runs are checked, and stale
temporary files of a destination are removed when it is written again. docs/validation.md,
"Faults and bad input: the second campaign", lists them."""

from __future__ import annotations

import json
import math
import os
import re
import resource
import shlex
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from configs import SERIAL_SOLVERS
from documented import check as check_documented
from documented import registry

from parastokes import cli, config
from parastokes.core import files, signals
from parastokes.output import trajectory as io

ROOT = Path(__file__).resolve().parents[1]
ENV = {**os.environ, "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1"}
SERIAL_RUNS = ROOT / "docs" / "figures" / "stiff" / "best_serial.json"
TABLE4 = [str(ROOT / "experiments" / "table4_g1.toml"), "--cores", "40", "--ratio", "0.0267",
          "--iterations", "1"]


def _bounded_memory() -> None:
    """A subprocess's address space limited to 2 GiB: a read that grows without bound (in a
    regression) ends there instead of taking the test machine's memory."""
    resource.setrlimit(resource.RLIMIT_AS, (2 << 30, resource.RLIM_INFINITY))


def _parastokes(*args: str) -> subprocess.CompletedProcess:
    """``parastokes ARGS`` in a subprocess of bounded memory; a hang fails the test (timeout).
    It runs in tests/, not in the checkout's root: there, with another copy installed (as
    ``.ci/run`` installs it), ``python -m parastokes`` adds a note on stderr (cli.launch)."""
    return subprocess.run([sys.executable, "-m", "parastokes", *args], cwd=ROOT / "tests", env=ENV,
                          capture_output=True, text=True, timeout=90, preexec_fn=_bounded_memory)


@pytest.fixture
def fifo(tmp_path) -> Path:
    path = tmp_path / "pipe.json"
    os.mkfifo(path)
    return path


# ---- the reader --------------------------------------------------------------------------------
@pytest.fixture
def alarm():
    """A read that blocks (a pipe opened for waiting) fails the test after 10 s, not hangs it."""
    def ring(*_):
        raise TimeoutError("the read blocked")

    previous = signal.signal(signal.SIGALRM, ring)
    signal.alarm(10)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, previous)


def test_the_reader_refuses_what_is_not_a_regular_file_before_opening_it(tmp_path, fifo, alarm):
    listening = socket.socket(socket.AF_UNIX)
    listening.bind(str(tmp_path / "s"))
    try:
        for path, kind in ((fifo, "a named pipe (FIFO)"), (Path("/dev/zero"), "a character device"),
                           (tmp_path, "a directory"), (tmp_path / "s", "a socket")):
            for read in (files.read_input, files.check_input):
                with pytest.raises(files.InputFileError) as info:
                    read(path, "serial runs")
                assert str(info.value) == (
                    f"{path}: {kind}, not a regular file; give a file of measured serial runs "
                    "(benchmarks/stiff.py's best_serial.json)")
    finally:
        listening.close()
    with pytest.raises(FileNotFoundError):
        files.read_input(tmp_path / "missing", "configuration")


def test_the_reader_caps_each_kind_at_its_size(tmp_path, monkeypatch):
    monkeypatch.setitem(files.INPUTS, "serial runs", ("a file of measured serial runs", 1000))
    path = tmp_path / "runs.json"
    path.write_bytes(b"x" * 1000)
    assert files.read_input(path, "serial runs") == b"x" * 1000  # at the cap: read
    path.write_bytes(b"x" * 1001)
    with pytest.raises(files.InputFileError, match=r"runs.json: larger than 1000 bytes \(1001 "
                                                    r"bytes\): no serial runs file is that large"):
        files.read_input(path, "serial runs")
    assert files.INPUTS["configuration"][1] == 1 << 20
    # the caps in words, at each unit's boundary
    assert [files._size(n) for n in (1023, 1024, 64 << 20, 1 << 40)] == [
        "1023 bytes", "1 KiB", "64 MiB", "1 TiB"]


def test_a_file_that_grows_while_it_is_read_is_read_to_its_cap_plus_one_byte(monkeypatch):
    """/dev/zero passed off as a regular file of size 0 (as a file that grows after the check
    would be): the read stops one byte past the cap, it does not run on."""
    monkeypatch.setattr(files, "_checked", lambda *_: None)
    monkeypatch.setitem(files.INPUTS, "summary", ("a run's summary.json", 3 << 20))
    chunks: list[int] = []
    monkeypatch.setattr(files, "_CHUNK", 1 << 20)
    honour = signals.honour
    monkeypatch.setattr(signals, "honour", lambda: (chunks.append(1), honour()))
    with pytest.raises(files.InputFileError, match="grew while it was read"):
        files.read_input("/dev/zero", "summary")
    assert len(chunks) == 4  # three chunks of 1 MiB, then the one byte past the cap


def test_a_stop_asked_for_during_a_read_ends_it(tmp_path):
    path = tmp_path / "c.toml"
    path.write_text("x = 1\n")
    signals._pending[:] = [signal.SIGTERM]  # (as if its first raise was lost in a finalizer)
    try:
        with pytest.raises(signals.Terminated):
            files.read_input(path, "configuration")
    finally:
        signals.clear()



def _readers():
    """Every reader of a file the package takes, as (name, call on a path)."""
    from parastokes import flow
    from parastokes.config.placement import read_poses
    from parastokes.flow.movie import check_mp4
    from parastokes.kinds.rigid.shapes import load_points
    from parastokes.output import plots
    from parastokes.parareal.best_serial import load_serial_runs

    return {
        "configuration": config.load, "poses": read_poses, "points": lambda p: load_points(str(p)),
        "serial runs": load_serial_runs, "summary": io.read_summary, "arrays": io.load_arrays,
        "trajectory": io.read_trajectory, "flow": flow.read_grid,
        "measurements": lambda p: plots.draw_benchmark(p, p.parent),
        "movie": lambda p: check_mp4(p, p), "record": files._complete,
    }


def test_every_reader_refuses_a_pipe_at_once_through_the_one_reader(tmp_path, alarm):
    """A named pipe given to any reader is refused by the bounded reader's check (one line
    naming it), never opened for waiting (the alarm fails a read that blocks)."""
    readers = _readers()
    assert set(readers) == set(files.INPUTS)  # (a new kind of input gets its reader here)
    for kind, read in readers.items():
        if kind == "movie":  # (the encoder's own temporary file: an empty one is refused first)
            continue
        pipe = tmp_path / f"{kind.replace(' ', '_')}.h5"
        os.mkfifo(pipe)
        with pytest.raises(ValueError, match=r"a named pipe \(FIFO\), not a regular file; give "
                                             + re.escape(files.INPUTS[kind][0])):
            read(pipe)

def test_a_memory_error_is_one_line_naming_the_cause(capsys, monkeypatch):
    def exhausted(*_args, **_kwargs):
        raise MemoryError()  # (str(MemoryError()) is empty)

    monkeypatch.setattr("parastokes.parareal.best_serial.load_serial_runs", exhausted)
    monkeypatch.chdir(ROOT)
    code = cli.main(["predict", *TABLE4, "--serial", str(SERIAL_RUNS), "--target", "1e-6"])
    assert code == cli.ExitCode.CONFIG
    err = capsys.readouterr().err
    assert err.splitlines() == ["error: out of memory (MemoryError): give smaller files "
                                "(--serial, --measured's summary.json), or a machine with more "
                                "memory"]
    # an error without a message and without a known cause still names its type
    assert cli.report(IsADirectoryError(), cli.Console(quiet=True), "predict") == 2
    assert capsys.readouterr().err.splitlines() == ["error: IsADirectoryError"]


#: Runs predict with the address space limited to what the process holds plus 150 MiB, once the
#: modules it needs are imported and the configuration read (`ulimit -v` without guessing the
#: interpreter's own size).
_LIMITED_PREDICT = """
import resource, sys
from parastokes import cli, config
import parastokes.cli.predict, parastokes.parareal.best_serial
config.load(sys.argv[2])
size = int(next(l for l in open("/proc/self/status") if l.startswith("VmSize")).split()[1])
resource.setrlimit(resource.RLIMIT_AS, (size * 1024 + (150 << 20), resource.RLIM_INFINITY))
sys.exit(cli.main(["predict", sys.argv[2], "--cores", "40", "--ratio", "0.0267",
                   "--serial", sys.argv[1], "--target", "1e-6"]))
"""


def test_out_of_memory_under_a_memory_limit_is_one_line(tmp_path):
    """A file of serial runs under its cap (14 MiB) whose million records need more memory than
    the limit leaves: a real MemoryError, exit 2, one line (was: an empty `error: `)."""
    path = tmp_path / "runs.json"
    path.write_text(json.dumps({"cases": {"x": {"rows": [{"a": i} for i in range(10**6)]}}}))
    done = subprocess.run([sys.executable, "-c", _LIMITED_PREDICT, str(path), TABLE4[0]],
                          cwd=ROOT / "tests", env=ENV,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == cli.ExitCode.CONFIG, done.stderr
    assert done.stderr.splitlines() == ["error: out of memory (MemoryError): give smaller files "
                                        "(--serial, --measured's summary.json), or a machine "
                                        "with more memory"]

# ---- 1, 2: a device or a pipe as --serial or as a suspension's poses -------------------------
@pytest.mark.parametrize("source", ["/dev/zero", "fifo"])
def test_predict_refuses_a_device_or_a_pipe_as_serial_runs_at_once(source, fifo):
    path = str(fifo) if source == "fifo" else source
    started = time.monotonic()
    done = _parastokes("predict", *TABLE4, "--serial", path, "--target", "1e-6")
    assert done.returncode == cli.ExitCode.CONFIG, done.stderr  # (was: 1 GB/s, or blocked)
    kind = "a named pipe (FIFO)" if source == "fifo" else "a character device"
    assert done.stderr.splitlines() == [f"error: {path}: {kind}, not a regular file; give a file "
                                        "of measured serial runs (benchmarks/stiff.py's "
                                        "best_serial.json)"]
    assert time.monotonic() - started < 60


def _poses_config(folder: Path, poses: str) -> Path:
    folder.mkdir(exist_ok=True)
    path = folder / "suspension.toml"
    path.write_text(f'title = "t"\n[scene]\nviscosity = 1.0\nwall = false\n[[suspensions]]\n'
                    f'placement = "file"\nfile = "{poses}"\n[suspensions.body]\nkind = "rigid"\n'
                    f'shape = "sphere"\nradius = 1.0\nn_points = 42\n{SERIAL_SOLVERS}')
    return path


def test_check_refuses_a_device_or_a_pipe_as_poses_at_once(tmp_path, fifo):
    configs = [_poses_config(tmp_path / name, path) for name, path in
               (("device", "/dev/zero"), ("pipe", str(fifo)))]
    done = _parastokes("check", *map(str, configs))
    assert done.returncode == cli.ExitCode.CONFIG, done.stderr  # (was: 1 GB/s, or blocked)
    lines = done.stderr.splitlines()
    assert len(lines) == 4 and all(line.startswith("invalid configuration in ")
                                   for line in lines[::2])
    for issue, (path, kind) in zip(lines[1::2], (("/dev/zero", "a character device"),
                                                 (fifo, "a named pipe (FIFO)")), strict=True):
        assert issue == (f"  suspensions[0].file: {path}: {kind}, not a regular file; give a "
                         "file of suspension poses, one body per line or a .npy array")


def test_poses_are_read_from_the_bytes_of_a_text_or_npy_file(tmp_path):
    """The bounded read feeds both formats (the file's bytes, not its name, reach numpy)."""
    (tmp_path / "p.txt").write_text("0 0 5\n4, 0, 5\n")
    np.save(tmp_path / "p.npy", np.array([[0.0, 0.0, 5.0], [4.0, 0.0, 5.0]]))
    for name in ("p.txt", "p.npy"):
        cfg, _ = config.load(_poses_config(tmp_path, name))
        np.testing.assert_array_equal([b.position for b in cfg.model.bodies],
                                      [[0, 0, 5], [4, 0, 5]])


# ---- 11: a trajectory without a rod's frames or a rigid body's pose ---------------------------
SCENE = """
[scene]
viscosity = 1e-6
wall = false
[[bodies]]
name = "rod"
kind = "rod"
n_points = 11
length = 2.0
wavelength = 2.0
[[bodies]]
name = "ball"
kind = "rigid"
shape = "sphere"
radius = 1.0
n_points = 40
position = [0.0, 3.0, 0.0]
""" + SERIAL_SOLVERS


@pytest.fixture(scope="module")
def rod_and_ball(tmp_path_factory) -> Path:
    """A run directory of a rod and a rigid sphere: two frames of their initial state."""
    cfg, resolved = config.loads(SCENE)
    scene = cfg.model.build(1)
    directory = tmp_path_factory.mktemp("run")
    layout = cfg.model.layout(scene, True, None)
    with io.TrajectoryWriter(directory / "trajectory.h5", layout, rates=scene.rates,
                             config=config.resolved_dict(cfg, resolved)) as writer:
        for t in (0.0, 0.1):
            writer.append("serial", t, scene.initial_state())
    from parastokes.flow import load_run

    np.testing.assert_array_equal(load_run(directory).state(1), scene.initial_state())  # whole
    return directory


@pytest.mark.parametrize("dataset", ["rod/D1", "rod/D3", "ball_center/orientation",
                                     "ball_center/phase"])
def test_flow_names_a_missing_frame_or_pose_dataset(rod_and_ball, tmp_path, capsys, dataset):
    import shutil

    run = Path(shutil.copytree(rod_and_ball, tmp_path / "run"))
    with h5py.File(run / "trajectory.h5", "a") as f:
        del f[f"serial/{dataset}"]
    code = cli.main(["flow", str(run), "--out", str(tmp_path / "g"), "-q"])
    assert code == cli.ExitCode.CONFIG  # (was: a KeyError traceback, exit 1)
    body, name = dataset.split("/")
    assert capsys.readouterr().err.splitlines() == [
        f"error: {run / 'trajectory.h5'}: run 'serial': body {body!r} lacks its {name}; rerun "
        "the run that wrote it"]


# ---- 13: the documented predict commands print the documented numbers -------------------------
def _documented_predict_commands() -> list[tuple[str, str]]:
    """(page, command) of every `parastokes predict` line of README.md and docs/*.md, with its
    continuation lines, whose configuration and files are in the repository (not a run the
    reader makes first, nor a placeholder such as CONFIG.toml)."""
    found = []
    for page in (ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))):
        text = page.read_text().replace("\\\n", " ")
        for line in text.splitlines():
            match = re.search(r"(?:^|\s)parastokes predict\s+(.*?)\s*(?:#.*)?$", line.strip("` "))
            if match is None or "`" in match[1]:
                continue
            words = shlex.split(match[1])
            paths = [words[0]] + [words[i + 1] for i, w in enumerate(words[:-1])
                                  if w in ("--serial", "--measured")]
            if all((ROOT / p).exists() for p in paths):
                found.append((page.name, " ".join(words)))
    return found


def test_every_documented_predict_command_prints_the_documented_numbers(capsys, monkeypatch):
    commands = _documented_predict_commands()
    group = "predict_best_serial"  # (the one documented command with printed numbers)
    pinned = registry()[group]["command"].removeprefix("parastokes predict ")
    assert {page for page, c in commands if c == pinned} == {"benchmarks.md", "parareal.md"}
    monkeypatch.chdir(ROOT)
    for page, command in commands:
        assert cli.main(["predict", *shlex.split(command)]) == 0, (page, command)
        out = capsys.readouterr().out.splitlines()
        if "--serial" not in command:
            continue
        assert command == pinned, f"{page}: `parastokes predict {command}` is not pinned"
        header = next(line for line in out if line.strip().startswith("N_c"))
        names = re.split(r"\s{2,}", header.strip())
        (row,) = [dict(zip(names, line.split(), strict=True)) for line in out
                  if line.split() and line.split()[0] == "40"]
        speedup, against = float(row["speedup (eq. 14)"]), float(row["vs best serial"])
        check_documented(group, "speedup", speedup)
        check_documented(group, "vs_best_serial", against)
        check_documented(group, "fine_over", speedup / against)


# ---- predict's values and files of serial runs ------------------------------------------------
@pytest.mark.parametrize("option, value", [("--target", "inf"), ("--target", "0"),
                                           ("--target", "nan"), ("--ratio", "inf"),
                                           ("--ratio", "-1")])
def test_predict_refuses_a_target_or_ratio_that_is_not_a_positive_number(capsys, monkeypatch,
                                                                         option, value):
    monkeypatch.setattr("parastokes.cli.predict.load",
                        lambda *_: pytest.fail("loaded the configuration first"))
    serial = ["--serial", str(SERIAL_RUNS), "--case", "table4"]
    args = [*TABLE4, *serial, "--target", "1e-6", option, value]
    assert cli.main(["predict", *args]) == cli.ExitCode.CONFIG  # (was: inf accepted)
    assert capsys.readouterr().err.splitlines() == [
        f"error: predict: {option} must be a positive finite number, got {float(value):g}"]


def test_predict_names_a_measured_run_whose_last_error_is_zero(capsys, monkeypatch, tmp_path):
    summary = {"config": {}, "mode": "both", "iterations": 2, "increments": [1.0, 0.0],
               "errors": [1e-6, 0.0], "timings": {}, "speedup": {"gamma_ratio": 0.03},
               "workers": 2, "final_positions": []}
    (tmp_path / "summary.json").write_text(json.dumps(summary))
    monkeypatch.chdir(ROOT)
    args = [*TABLE4[:3], "--serial", str(SERIAL_RUNS), "--case", "table4", "--measured",
            str(tmp_path)]
    assert cli.main(["predict", *args]) == cli.ExitCode.CONFIG
    assert capsys.readouterr().err.splitlines() == [
        f"error: predict: the last error η^K of the run in {tmp_path} is 0, which no serial run "
        "is measured to reach: give --target ETA"]  # (was: "--target must be positive, got 0")


def _runs_file(tmp_path: Path, change) -> Path:
    data = json.loads(SERIAL_RUNS.read_text())
    change(data["cases"]["table4"])
    path = tmp_path / "runs.json"
    path.write_text(json.dumps(data, allow_nan=True))
    return path


def _set(key: str, value, row: int | None = 1):
    def change(case: dict) -> None:
        (case if row is None else case["rows"][row])[key] = value
    return change


@pytest.mark.parametrize("change, where, message", [
    (_set("error", -1.0), "row 1", "error must be a finite number at least 0, got -1.0"),
    (_set("error", math.nan), "row 1", "error must be a finite number at least 0, got nan"),
    (_set("cpu", 0), "row 1", "cpu must be a positive finite number, got 0"),
    (_set("fine_cpu", math.inf), "row 1", "fine_cpu must be a positive finite number, got inf"),
    (_set("dt", "1e-5"), "row 1", "dt must be a positive finite number, got '1e-5'"),
    (_set("dt", True), "row 1", "dt must be a positive finite number, got True"),
    (_set("scheme", ""), "row 1", "scheme must be a scheme's name, got ''"),
    (lambda case: case["rows"][1].pop("error"), "row 1",
     "error must be a finite number at least 0, got None"),
    (_set("t1", -1.0, None), "", "t1 must be a positive finite number, got -1.0"),
    (_set("rows", {"a": 1}, None), "", "rows must be a list of runs, got {'a': 1}"),
    (lambda case: case["reference"].update(dt=0.0), "reference",
     "dt must be a positive finite number, got 0.0"),
])
def test_a_corrupt_row_of_serial_runs_is_named(tmp_path, change, where, message):
    from parastokes.parareal.best_serial import load_serial_runs

    path = _runs_file(tmp_path, change)
    with pytest.raises(ValueError) as info:
        load_serial_runs(path, "table4")
    at = f", {where}" if where else ""
    assert str(info.value) == (f"{path}, case 'table4'{at}: {message}; measure the runs again "
                               "(benchmarks/stiff.py --parts best_serial)")


def test_the_serial_runs_as_measured_are_read_whole():
    from parastokes.parareal.best_serial import load_serial_runs

    runs = load_serial_runs(SERIAL_RUNS, "table4")
    assert (runs.t1, runs.reference.scheme, runs.reference.dt, len(runs.rows)) == (1.0, "rk2",
                                                                                   1e-6, 8)
    rk2 = runs.rows[1]
    assert (rk2.scheme, rk2.dt, rk2.error) == ("rk2", 1.16e-05, 1.2222257619771535e-07)
    assert rk2.fine_over == 1018.1729254000174 / 86.30198184999995


# ---- stale temporary files of a destination -------------------------------------------------
def _dead_pid() -> int:
    process = subprocess.Popen([sys.executable, "-c", "pass"])
    process.wait()
    return process.pid


def test_stale_temporary_files_of_a_destination_are_removed_when_it_is_written(tmp_path):
    target = tmp_path / "flow.h5"
    old = files._STARTED - 60
    dead = files.temporary_name(target, _dead_pid())
    alive = files.temporary_name(target, os.getppid())       # a writer that still runs
    fresh = files.temporary_name(target, _dead_pid() + 10**6)  # written after we started
    other = files.temporary_name(tmp_path / "flow.xdmf", _dead_pid())  # another destination
    for path in (dead, alive, fresh, other):
        path.write_bytes(b"partial")
        os.utime(path, (old, old))
    os.utime(fresh, (files._STARTED + 1, files._STARTED + 1))
    files.atomic_write(target, lambda handle: handle.write(b"new"))
    assert target.read_bytes() == b"new"
    assert not dead.exists()
    assert alive.exists() and fresh.exists() and other.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        ["flow.h5", alive.name, fresh.name, other.name])


# ---- the configuration's smaller ones ---------------------------------------------------------
CLOUD = ROOT / "experiments" / "quick" / "cloud_sediments.toml"
LATTICE = ROOT / "experiments" / "quick" / "suspension_64_spheres.toml"


@pytest.mark.parametrize("path, setting, issue", [
    (LATTICE, "suspensions.0.spacing=[4.0, 4.0]",  # (was: "suspensions[0].body: zip() ...")
     "suspensions[0].spacing: got [4.0, 4.0]; expected lattice: distance between neighbouring "
     "centres (μm), one number or [dx, dy, dz]"),
    (LATTICE, 'suspensions.0.spacing="a"',  # (was two lines, one per member of the union)
     "suspensions[0].spacing: got 'a'; expected lattice: distance between neighbouring centres "
     "(μm), one number or [dx, dy, dz]"),
    (LATTICE, "suspensions.0.spacing=[4.0, -1, 3.0]",  # the list member got furthest: its item
     "suspensions[0].spacing[1]: Input should be greater than 0 (got -1)"),
    (CLOUD, "scene.repulsion={range=1.0, force=1.0, shape=2}",  # (was "known keys: ")
     "scene.repulsion.shape: unknown key (known keys: force, range)"),
])
def test_a_bad_value_is_one_line_naming_its_own_key(capsys, path, setting, issue):
    assert cli.main(["check", str(path), "--set", setting]) == cli.ExitCode.CONFIG
    assert capsys.readouterr().err.splitlines()[1:] == [f"  {issue}"]


def test_an_unknown_key_of_a_table_of_no_schema_gets_no_empty_list_of_keys():
    from pydantic import BaseModel, ConfigDict, ValidationError

    from parastokes.config import errors

    class Loose(BaseModel):
        model_config = ConfigDict(extra="forbid")

    with pytest.raises(ValidationError) as info:
        Loose.model_validate({"x": 1})
    found = errors.from_validation_error(info.value, {"nowhere": {"x": 1}}, "",
                                         ("nowhere", "deeper"))
    assert found.issues == [("nowhere.deeper.x", "unknown key")]


def test_the_repulsion_is_switched_off_from_the_command_line():
    cfg, _ = config.load(CLOUD)
    assert cfg.model.repulsion is not None  # (the file's)
    off, _ = config.load(CLOUD, ["scene.repulsion=false"])  # (was: range and force required)
    assert off.model.repulsion is None and "repulsion" not in off.model.tables()["scene"]
    assert off.model.build(1).repulsion is None



def test_an_rtol_below_round_off_is_refused_by_check_naming_the_key(tmp_path, capsys):
    """The configuration's side of integrate.tolerances' floor (was: accepted, then a numpy
    overflow warning in the run)."""
    from configs import small_rod

    path = tmp_path / "c.toml"
    path.write_text(small_rod(rest="[execution]\nworkers = 4\n").replace(
        "dt = 1e-6", 'dt = 1e-6\nscheme = "ros2"\nrtol = 1e-300'))
    assert cli.main(["check", str(path)]) == cli.ExitCode.CONFIG
    assert capsys.readouterr().err.splitlines()[1:] == [
        "  fine.rtol: 1e-300 is below 2.2e-14 (100 machine epsilons): no step can meet it in "
        "double precision; use a larger rtol"]
