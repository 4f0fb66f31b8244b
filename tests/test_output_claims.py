"""Every command that writes (flow, movie, tune, plot) claims its files the way a run claims its
directory (parastokes.output.rundir.claim_files over parastokes.core.files.Staging): checked before
any work, never onto a run's own files, not while a run holds the directory, written to a temporary
file and moved into place whole, so that an interrupt, a full disk or a failing encoder leaves the
previous file intact and no partial one (issue 39; docs/validation.md, "Faults and bad input").
"""

from __future__ import annotations

import errno
import os
import resource
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from test_flow import scene_run  # noqa: F401  (the fixture: a scene's run directory of 5 frames)

from parastokes import flow
from parastokes.cli import main
from parastokes.core import files
from parastokes.flow.grids import grid_for
from parastokes.output import rundir

ROOT = Path(__file__).resolve().parents[1]
ENV = {**os.environ, "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1"}


#: The summary of a serial run (no Parareal, so no figures but the bodies').
SUMMARY = {"config": {}, "mode": "serial", "iterations": 0, "increments": [], "errors": None,
           "timings": {}, "speedup": None, "workers": None, "final_positions": []}


@pytest.fixture
def run_dir(scene_run, tmp_path) -> Path:  # noqa: F811
    """A copy of the scene's run directory (with a summary: a finished run's), to write into."""
    import json

    out = Path(shutil.copytree(scene_run[0], tmp_path / "run"))
    (out / "summary.json").write_text(json.dumps(SUMMARY))
    return out


def _keep_frames(path: Path, count: int) -> None:
    """Cut every dataset of the serial run of the trajectory ``path`` to its first frames."""
    with h5py.File(path, "a") as f:
        names: list[str] = []
        f["serial"].visit(lambda name: names.append(name))
        for name in names:
            item = f["serial"][name]
            if isinstance(item, h5py.Dataset):
                data = item[()][:count]
                del f["serial"][name]
                f["serial"][name] = data


def _files(directory: Path) -> dict[str, bytes]:
    """The files of ``directory`` (but a run's lock) and their bytes."""
    return {p.name: p.read_bytes() for p in sorted(directory.iterdir())
            if p.is_file() and p.name != rundir.LOCK}


def _command(*args: object, limit: int | None = None, env: dict | None = None,
             **kwargs) -> subprocess.Popen:
    """``python -m parastokes ARGS`` started in a subprocess (file size limited to ``limit``
    bytes)."""

    def limited() -> None:
        # SIGINT at its default in the child, even when this suite runs with it ignored (a
        # background job of a shell without job control): Ctrl-C must reach the command
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        if limit is not None:
            resource.setrlimit(resource.RLIMIT_FSIZE, (limit, resource.RLIM_INFINITY))

    return subprocess.Popen([sys.executable, "-m", "parastokes", *map(str, args)],
                            env=env or ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, preexec_fn=limited, **kwargs)


def _finish(process: subprocess.Popen) -> tuple[int, str]:
    _, err = process.communicate(timeout=300)
    return process.returncode, err


def _fake_ffmpeg(tmp_path: Path, body: str) -> dict[str, str]:
    """The environment in which imageio-ffmpeg's ffmpeg is the shell script ``body`` (its last
    argument, ``$out``, is the file to write)."""
    script = tmp_path / "ffmpeg"
    script.write_text('#!/bin/bash\nout="${@: -1}"\n' + body + "\n")
    script.chmod(0o755)
    return {**ENV, "IMAGEIO_FFMPEG_EXE": str(script)}


# ---- the mechanism -----------------------------------------------------------------------------
def test_staged_files_move_into_place_together_and_a_failure_leaves_the_old_ones(tmp_path):
    a, b = tmp_path / "a.txt", tmp_path / "b.bin"
    a.write_text("old a")
    with pytest.raises(RuntimeError, match="encoder"), files.staged() as staging:
        staging.write(a, lambda handle: handle.write(b"new a"))
        assert a.read_text() == "old a"  # (nothing in place before the end)
        raise RuntimeError("encoder failed")
    assert a.read_text() == "old a" and sorted(p.name for p in tmp_path.iterdir()) == ["a.txt"]
    with pytest.raises(files.FileWriteError, match=f"cannot write {b}: the writer produced"):
        with files.staged() as staging:
            staging.write(a, lambda handle: handle.write(b"new a"))
            staging.temporary(b)  # a writer that names its file, and never creates it
    assert a.read_text() == "old a" and sorted(p.name for p in tmp_path.iterdir()) == ["a.txt"]
    with files.staged() as staging:
        staging.write(a, lambda handle: handle.write(b"new a"))
        staging.temporary(b).write_bytes(b"\x01")
    assert (a.read_text(), b.read_bytes()) == ("new a", b"\x01")


def test_a_run_file_is_named_and_a_claim_checks_before_anything_is_created(run_dir, tmp_path):
    assert all(rundir.is_run_file(name) for name in (
        "summary.json", "trajectory.h5", "checkpoint.npz", "config.toml", "flow.h5",
        "error_decay.pdf", "structure_rigid.png", rundir.LOCK))
    assert not any(rundir.is_run_file(name) for name in ("flow_frame3.h5", "movie.mp4",
                                                         "notes.txt", "error_decay.txt"))
    with pytest.raises(rundir.RunDirectoryError, match="is a directory"):
        rundir.check_files([run_dir])
    with pytest.raises(rundir.RunDirectoryError, match="already exist"):
        rundir.check_files([run_dir / "trajectory.h5", tmp_path / "new"], overwrite=False,
                           regenerates=["trajectory.h5"])
    with pytest.raises(rundir.RunDirectoryError, match="is a file, not a directory"):
        rundir.check_files([run_dir / "summary.json" / "x.png"])
    assert rundir.check_files([tmp_path / "deep" / "er" / "x.png"])
    assert not (tmp_path / "deep").exists()


# ---- 1: flow --out onto a run's own files ------------------------------------------------------
@pytest.mark.parametrize("stem, name", [
    ("trajectory", "trajectory.h5"), ("flow.h5", "flow.h5"), ("error_decay", "error_decay.png"),
    ("structure_rod", "structure_rod.png"),
])
def test_flow_onto_a_runs_own_files_is_refused_before_any_work(run_dir, capsys, monkeypatch,
                                                               stem, name):
    before = _files(run_dir)

    def computed(*args, **kwargs):
        raise AssertionError("the flow was computed before the output was checked")

    monkeypatch.setattr("parastokes.flow.fields.frames_velocity", computed)
    assert main(["flow", str(run_dir), "--out", str(run_dir / stem), "-q"]) == 2
    err = capsys.readouterr().err
    assert f"{name} is a file of the run in {run_dir}, which no other command replaces" in err
    assert len(err.strip().splitlines()) == 1 and _files(run_dir) == before


def test_tune_and_plot_never_replace_a_runs_files_even_with_overwrite(run_dir, tmp_path, capsys):
    before = _files(run_dir)
    config = tmp_path / "c.toml"
    config.write_text("")  # (not read: the output is refused first)
    assert main(["tune", str(config), "--cores", "4", "--target", "1e-6", "--out",
                 str(run_dir / "summary.toml"), "--overwrite", "-q"]) == 2
    assert "summary.json is a file of the run" in capsys.readouterr().err
    other = Path(shutil.copytree(run_dir, tmp_path / "other"))
    assert main(["plot", str(run_dir), str(other), "--out", str(run_dir), "-q"]) == 2
    assert "error_decay.png is a file of the run" in capsys.readouterr().err
    assert _files(run_dir) == before


# ---- 3: a file-size limit while flow writes ----------------------------------------------------
def test_flow_under_a_file_size_limit_is_exit_2_naming_the_file_and_keeps_the_old_one(
    run_dir, tmp_path
):
    out = tmp_path / "f"
    assert main(["flow", str(run_dir), "--resolution", "6", "--out", str(out), "-q"]) == 0
    old = _files(tmp_path)
    code, err = _finish(_command("flow", run_dir, "--resolution", "60", "--out", out, "-q",
                                 limit=5 * 1024))
    assert code == 2, err  # (was 139: a segmentation fault in h5py, and a .tmp left)
    assert f"cannot write {out}.h5: File too large" in err and "Traceback" not in err
    assert _files(tmp_path) == old  # the previous flow whole, no temporary file


def test_a_failed_write_of_a_flow_grid_removes_its_temporary_file(tmp_path, monkeypatch):
    write = files.GuardedFile.write

    def full(self, data):  # the disk is full past 2 kB
        if self.tell() + memoryview(data).nbytes > 2048 and self.failed is None:
            self.failed = OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return write(self, data)

    monkeypatch.setattr(files.GuardedFile, "write", full)
    grid = grid_for(np.array([[0.0, 1.0], [0.0, 1.0], [0.0, 1.0]]), (20, 20, 20))
    with pytest.raises(files.FileWriteError, match=f"cannot write {tmp_path / 'g.h5'}: No space"):
        flow.write_grid(tmp_path / "g", grid, np.zeros(1), np.zeros((1, 8000, 3)))
    assert list(tmp_path.iterdir()) == []


# ---- 7: flow on a directory a run holds ---------------------------------------------------------
@pytest.mark.parametrize("where", ["into the run", "elsewhere"])
def test_flow_and_movie_on_a_directory_a_run_holds_are_refused_before_any_work(
    run_dir, tmp_path, capsys, monkeypatch, where
):
    def computed(*args, **kwargs):
        raise AssertionError("computed while a run holds the directory")

    monkeypatch.setattr("parastokes.flow.run.load_run", computed)
    before = _files(run_dir)
    out = [] if where == "into the run" else ["--out", str(tmp_path / "f")]
    with rundir.locked(run_dir):  # a run in progress there (this process: alive)
        assert main(["flow", str(run_dir), *out, "-q"]) == 2
        assert "is in use by another parastokes process" in capsys.readouterr().err
        assert main(["movie", str(run_dir), "--out", str(tmp_path / "m.gif"), "-q"]) == 2
        assert "is in use by another parastokes process" in capsys.readouterr().err
        assert _files(run_dir) == before
    assert not (tmp_path / "f.h5").exists() and not (tmp_path / "m.gif").exists()


def test_flow_into_a_run_directory_lists_its_files_with_the_results(run_dir):
    assert main(["flow", str(run_dir), "--frame", "1", "--resolution", "6", "-q"]) == 0
    import json

    listed = json.loads((run_dir / rundir.MANIFEST).read_text())["files"]
    assert {"flow_frame1.h5", "flow_frame1.xdmf", "flow_frame1.png"} <= set(listed)
    assert not (run_dir / rundir.LOCK).exists()
    # again: its own earlier output is replaced (it is not one of the run's files)
    assert main(["flow", str(run_dir), "--frame", "1", "--resolution", "7", "-q"]) == 0
    assert max(flow.read_grid(run_dir / "flow_frame1.h5")[0].shape) == 7


# ---- 8: a damaged trajectory ---------------------------------------------------------------------
@pytest.mark.parametrize("damage", ["positions deleted", "time short", "NaN", "no frames"])
def test_a_damaged_trajectory_is_named_by_flow_movie_and_plot(run_dir, tmp_path, capsys, damage):
    with h5py.File(run_dir / "trajectory.h5", "a") as f:
        if damage == "positions deleted":
            del f["serial/rod/positions"]
        elif damage == "time short":
            times = f["serial/time"][()]
            del f["serial/time"]
            f["serial/time"] = times[:3]
        elif damage == "NaN":
            f["serial/vesicle/positions"][2, 5, 1] = np.nan
        else:
            del f["serial"]
    reason = {"positions deleted": "body 'rod' lacks its positions",
              "time short": "body 'rod': D1 has shape (5, 11, 3), not one row per point for "
                            "each of the 3 frames",
              "NaN": "body 'vesicle': positions is not finite in frame 2",
              "no frames": "holds no frames"}[damage]
    for argv in (["flow", str(run_dir), "--out", str(tmp_path / "f")],
                 ["movie", str(run_dir), "--out", str(tmp_path / "m.gif")],
                 ["plot", str(run_dir)]):
        assert main([*argv, "-q"]) == 2
        err = capsys.readouterr().err
        assert f"{run_dir / 'trajectory.h5'}: " in err and reason in err, err
        assert "Traceback" not in err and len(err.strip().splitlines()) == 1


# ---- 13: a plane or box beyond floating point ---------------------------------------------------
@pytest.mark.parametrize("argv, fix", [
    (["--plane", "z=1e300"], "--plane 'z=1e300': beyond ±1e+30 μm"),
    (["--plane", "y=0", "--box", "-1", "1", "-1", "1", "0", "1e300"], "--box: 1e+300 is beyond"),
    (["--resolution", "100000"], "each from 2 to 4096"),
    (["--dpi", "100000"], "--dpi 100000: give 1 to 1000"),
])
def test_a_grid_the_flow_cannot_be_computed_on_is_refused(run_dir, capsys, argv, fix):
    before = _files(run_dir)
    assert main(["flow", str(run_dir), *argv]) == 2
    err = capsys.readouterr().err
    assert fix in err and len(err.strip().splitlines()) == 1
    assert _files(run_dir) == before


def test_a_box_with_negative_exponents_is_read(run_dir, tmp_path):
    out = tmp_path / "b"
    assert main(["flow", str(run_dir), "--plane", "y=0", "--box", "-1e1", "1e1", "-1", "1",
                 "0", "8", "--resolution", "5", "--out", str(out), "-q"]) == 0
    grid = flow.read_grid(out.with_suffix(".h5"))[0]
    assert grid.origin[0] == -10.0 and grid.shape == (5, 1, 3)


# ---- 5: movies ----------------------------------------------------------------------------------
def test_sigint_while_a_movie_is_written_keeps_the_previous_one(run_dir, tmp_path):
    movie = tmp_path / "m.mp4"
    movie.write_bytes(b"the previous movie")
    # an encoder that starts writing, then takes its time
    env = _fake_ffmpeg(tmp_path, 'echo partial > "$out"\nsleep 60')
    process = _command("movie", run_dir, "--out", movie, "--size", "160x120", env=env)
    deadline = time.monotonic() + 120
    while not list(tmp_path.glob("m.mp4.*.tmp")) and time.monotonic() < deadline:
        time.sleep(0.05)
    process.send_signal(signal.SIGINT)
    code, err = _finish(process)
    assert code == 130, err
    assert "interrupted" in err and "previous ones kept" in err
    assert movie.read_bytes() == b"the previous movie"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ffmpeg", "m.mp4", "run"]


@pytest.mark.parametrize("encoder, reason", [
    ("cat > /dev/null", "the encoder ended without writing the movie"),
    ('echo "Unknown encoder libx264" >&2\nexit 1',
     "the encoder ffmpeg failed (exit status 1): Unknown encoder libx264"),
    ("head -c 100 > /dev/null\nprintf '\\0\\0\\0\\x10ftypisom\\0\\0\\0\\0\\0\\0\\0\\x08mdat' > "
     '"$out"', "the encoder left an incomplete MP4 (24 bytes, no index)"),
])
def test_an_encoder_that_fails_or_writes_nothing_is_exit_2_and_keeps_the_old_movie(
    run_dir, tmp_path, encoder, reason
):
    movie = tmp_path / "m.mp4"
    movie.write_bytes(b"the previous movie")
    code, err = _finish(_command("movie", run_dir, "--out", movie, "--size", "160x120", "-q",
                                 env=_fake_ffmpeg(tmp_path, encoder)))
    assert code == 2, err  # (was 0, with no movie or one that cannot be opened)
    assert f"error: cannot write {movie}: {reason}" in err and "Broken pipe" not in err
    assert movie.read_bytes() == b"the previous movie" and not list(tmp_path.glob("*.tmp"))


def test_a_movie_under_a_file_size_limit_is_exit_2_and_keeps_the_old_one(run_dir, tmp_path):
    pytest.importorskip("imageio_ffmpeg")
    movie = tmp_path / "m.mp4"
    movie.write_bytes(b"the previous movie")
    code, err = _finish(_command("movie", run_dir, "--out", movie, "--size", "640x480", "-q",
                                 limit=3 * 1024))
    assert code == 2, err  # (was 0: an MP4 without its index, which ffmpeg cannot open)
    assert f"cannot write {movie}: File too large" in err
    assert movie.read_bytes() == b"the previous movie" and not list(tmp_path.glob("*.tmp"))


def test_a_movie_needs_two_frames_and_a_size_it_can_draw(run_dir, tmp_path, capsys):
    _keep_frames(run_dir / "trajectory.h5", 1)
    assert main(["movie", str(run_dir), "--out", str(tmp_path / "m.gif")]) == 2
    assert "the run saved 1 frame(s): a movie needs at least 2" in capsys.readouterr().err
    assert main(["movie", str(run_dir), "--size", "0x0"]) == 2
    err = capsys.readouterr().err
    assert "--size 0x0: give WxH in pixels" in err and "--resolution" not in err


def test_without_imageio_ffmpeg_the_missing_package_is_named(run_dir, tmp_path, capsys,
                                                             monkeypatch):
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)  # (an import of it fails)
    assert main(["movie", str(run_dir), "--out", str(tmp_path / "m.mp4")]) == 2
    err = capsys.readouterr().err
    assert "MP4 needs the ffmpeg of imageio-ffmpeg (pip install 'parastokes[movie]')" in err
    assert "missing None" not in err and f"--out {tmp_path / 'm.gif'}" in err


def test_a_flow_that_is_not_finite_at_some_node_is_refused_naming_it():
    from parastokes.flow.command import _finite

    grid = grid_for(np.array([[0.0, 1.0], [0.0, 1.0], [0.0, 1.0]]), (3, 3, 2))
    values = np.zeros((2, 18, 3))
    _finite(values, grid)
    values[1, 4, 2] = np.nan  # the second frame, node 4: (0.5, 0.5, 0)
    with pytest.raises(ValueError, match=r"not finite at 1 of 18 nodes \(the first at "
                                         r"\[0\.5 0\.5 0\. \]\)"):
        _finite(values, grid)
