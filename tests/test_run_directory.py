"""An output directory is owned by one run: lock, no silent overwrite, results replaced whole,
resume only of the same configuration, `--out` problems found before any work."""

from __future__ import annotations

import json
import os
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from configs import small_rod
from mpi_scripts.launch import SKIP_REASON, mpiexec
from test_io import rod_layout

from parastokes import cli
from parastokes import run as runner
from parastokes.output import rundir
from parastokes.output import trajectory as io
from parastokes.run import execution as execute_module

ROOT = Path(__file__).resolve().parents[1]
ENV = {**os.environ, "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1"}

# A small rod problem run in-process (serial executor): a few seconds.
TINY = 'title = "tiny rod"\n' + small_rod(
    parareal="max_iterations = 2",
    rest='[execution]\nexecutor = "serial"\n[output]\nformats = ["png"]\n',
)
# Long enough (several seconds) for a second run to start while it runs.
LONGER = TINY.replace("n_points = 21\nlength = 4.0", "n_points = 41\nlength = 8.0").replace(
    "t1 = 0.002", "t1 = 0.008"
)

# The serial fine run blows up (forward Euler far beyond its stable step).
BLOWING_UP = (
    TINY.replace("dt = 1e-6", 'dt = 5e-4\nscheme = "euler"')
    .replace("t1 = 0.002", "t1 = 0.01")
    .replace("dt_ratio = 10", "dt_ratio = 1")
    + '[run]\nmode = "serial"\n'
)


def _config(tmp_path: Path, text: str = TINY, name: str = "run.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _run(*args: str) -> int:
    return cli.main(["run", *map(str, args), "-q"])


@pytest.fixture(scope="module")
def finished(tmp_path_factory) -> tuple[Path, Path]:
    """A finished TINY run: (its configuration, its directory)."""
    root = tmp_path_factory.mktemp("finished")
    path = _config(root)
    assert _run(path, "--out", root / "out") == 0
    return path, root / "out"


def _snapshot(directory: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in directory.iterdir() if p.is_file()}


def test_a_second_run_is_refused_and_the_first_one_is_intact(tmp_path, capsys):
    path = _config(tmp_path, LONGER)
    out = tmp_path / "shared"
    command = [sys.executable, "-m", "parastokes", "run", str(path), "--out", str(out), "-q"]
    first = subprocess.Popen(command, env=ENV, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 300
    while not (out / rundir.LOCK).exists():
        assert first.poll() is None and time.monotonic() < deadline
        time.sleep(0.02)
    assert _run(path, "--out", out) == cli.ExitCode.CONFIG
    message = capsys.readouterr().err
    assert f"PID {first.pid}" in message and socket.gethostname() in message
    assert _run(path, "--out", out, "--overwrite") == cli.ExitCode.CONFIG  # even so
    _, stderr = first.communicate(timeout=600)
    assert first.returncode == 0, stderr
    assert not (out / rundir.LOCK).exists()

    assert _run(path, "--out", tmp_path / "alone") == 0
    shared = io.read_summary(out / "summary.json")
    alone = io.read_summary(tmp_path / "alone" / "summary.json")
    assert shared["final_positions"] == alone["final_positions"]  # bit for bit
    assert shared["errors"] == alone["errors"]
    with h5py.File(out / "trajectory.h5") as f:
        segments = f["bodies/rod_0/connectivity"][()]
    np.testing.assert_array_equal(segments[:, 1] - segments[:, 0], 1)  # ParaView draws the rod
    assert segments[-1, 1] == 40


def test_a_stale_lock_is_taken_over_and_a_foreign_host_named(tmp_path, capsys):
    path = _config(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    lock = {"pid": dead.pid, "host": socket.gethostname(), "time": "then"}
    (out / rundir.LOCK).write_text(json.dumps(lock))
    assert _run(path, "--out", out) == 0  # that process is gone: the lock was stale
    assert not (out / rundir.LOCK).exists()

    (out / rundir.LOCK).write_text(json.dumps({**lock, "host": "node-17"}))
    assert _run(path, "--out", out, "--overwrite") == cli.ExitCode.CONFIG
    message = capsys.readouterr().err
    assert "node-17" in message and str(out / rundir.LOCK) in message


def test_an_empty_lock_left_by_a_killed_writer_is_taken_over(tmp_path):
    # regression: such a lock was never stale, every later claim waited and was refused
    out = tmp_path / "out"
    out.mkdir()
    lock = out / rundir.LOCK
    lock.write_text("")
    then = time.time() - 60
    os.utime(lock, (then, then))
    with rundir.claim(out, resume=False, overwrite=False):
        assert json.loads(lock.read_text())["pid"] == os.getpid()
    assert not lock.exists()


def test_a_finished_run_is_kept_without_overwrite(finished, tmp_path, capsys):
    path, source = finished
    out = tmp_path / "out"
    shutil.copytree(source, out)
    before = _snapshot(out)
    assert _run(path, "--out", out) == cli.ExitCode.CONFIG
    err = capsys.readouterr().err
    assert "finished run" in err and "--overwrite" in err
    assert _snapshot(out) == before


def test_overwrite_replaces_results_whole_and_removes_stale_figures(finished, tmp_path):
    path, source = finished
    out = tmp_path / "out"
    shutil.copytree(source, out)
    assert (out / "structure.png").exists()
    old = _snapshot(out)
    blows_up = _config(tmp_path, BLOWING_UP, "blow.toml")
    # a run that blows up: the old results stay complete, the last good state is saved
    assert _run(blows_up, "--out", out, "--overwrite") == cli.ExitCode.BLOWUP
    for name in ("summary.json", "trajectory.h5", "trajectory.xdmf", "structure.png"):
        assert (out / name).read_bytes() == old[name]
    meta, arrays = io.load_arrays(out / runner.BLOWUP)
    assert "fine solver" in meta["where"] and np.isfinite(arrays["last_state"]).all()
    # a run that completes: new results, and no figure of the old run left over
    assert _run(path, "--out", out, "--overwrite", "--set", "output.figures=false") == 0
    assert not list(out.glob("*.png")) and not (out / runner.BLOWUP).exists()
    assert io.read_summary(out / "summary.json")["config"]["output"]["figures"] is False
    assert not (out / rundir.STAGING).exists()


def test_figures_that_plot_added_are_results_the_next_overwrite_replaces(finished, tmp_path):
    # regression: `plot DIR`'s pdfs stayed beside the next run's results, a mixture of two runs
    path, source = finished
    out = tmp_path / "out"
    shutil.copytree(source, out)
    assert cli.main(["plot", str(out), "--formats", "pdf", "-q"]) == 0
    assert list(out.glob("*.pdf")) and not (out / rundir.LOCK).exists()
    assert _run(path, "--out", out, "--overwrite", "--set", "output.figures=false") == 0
    assert not list(out.glob("*.pdf")) and not list(out.glob("*.png"))


def test_plot_waits_for_no_run_it_would_mix_with(finished, tmp_path, capsys):
    _, source = finished
    out = tmp_path / "out"
    shutil.copytree(source, out)
    with rundir.claim(out, resume=True, overwrite=False):  # a run holds the directory
        assert cli.main(["plot", str(out), "-q"]) == cli.ExitCode.CONFIG
    assert "is in use by another parastokes process" in capsys.readouterr().err


def test_interrupted_and_foreign_directories_are_refused(finished, tmp_path, capsys):
    path, source = finished
    interrupted = tmp_path / "interrupted"
    shutil.copytree(source, interrupted)
    (interrupted / "summary.json").unlink()
    assert _run(path, "--out", interrupted) == cli.ExitCode.CONFIG
    assert "--resume" in capsys.readouterr().err
    foreign = tmp_path / "home"
    foreign.mkdir()
    (foreign / "thesis.tex").write_text("precious")
    assert _run(path, "--out", foreign) == cli.ExitCode.CONFIG
    assert "thesis.tex" in capsys.readouterr().err
    assert [p.name for p in foreign.iterdir()] == ["thesis.tex"]


def test_resume_with_a_changed_key_is_refused_naming_it(finished, tmp_path, capsys):
    path, source = finished
    out = tmp_path / "out"
    shutil.copytree(source, out)
    (out / "summary.json").unlink()  # as if interrupted after the last iteration
    before = _snapshot(out)
    assert _run(path, "--out", out, "--resume", "--set", "coarse.dt_ratio=12") == 2
    err = capsys.readouterr().err
    assert "coarse.dt_ratio: 12.0 now, 10.0 in the run to resume" in err
    assert _snapshot(out) == before
    # what only says when to stop may change: one more iteration continues the checkpoint
    assert _run(path, "--out", out, "--resume", "--set", "parareal.max_iterations=3") == 0
    assert io.read_summary(out / "summary.json")["iterations"] == 3


def test_a_reference_serves_every_run_of_its_fine_problem_and_no_other(finished, tmp_path, capsys):
    """reference.npz is keyed by the fine problem only (runner.fine_identity): a run with another
    coarse solver reuses it (same serial solution, no fine run), a run with another fine step
    refuses it naming the key."""
    path, source = finished
    out = tmp_path / "other_coarse"
    out.mkdir()
    shutil.copy(source / runner.REFERENCE, out / runner.REFERENCE)
    assert cli.main(["run", str(path), "--out", str(out), "--resume",
                     "--set", "coarse.dt_ratio=12"]) == 0
    assert "serial fine solution reloaded from reference.npz" in capsys.readouterr().out
    assert len(io.read_summary(out / "summary.json")["errors"]) >= 1  # η^k against it
    assert np.array_equal(io.load_arrays(out / runner.REFERENCE)[1]["states"],
                          io.load_arrays(source / runner.REFERENCE)[1]["states"])
    other = tmp_path / "other_fine"
    other.mkdir()
    shutil.copy(source / runner.REFERENCE, other / runner.REFERENCE)
    assert _run(path, "--out", other, "--resume", "--set", "fine.dt=5e-7") == 2
    assert "fine.dt: 5e-07 now" in capsys.readouterr().err


def test_a_commit_cut_short_is_completed_by_the_next_claim(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "summary.json").write_text("old")
    (out / "error_decay.png").write_text("old figure")
    with rundir.claim(out, resume=False, overwrite=True) as directory:
        (directory.staging / "summary.json").write_text("new")
        (directory.staging / "trajectory.h5").write_text("new")
        text = json.dumps({"files": ["summary.json", "trajectory.h5"]})
        (directory.staging / "COMMIT").write_text(text)
        os.replace(directory.staging / "summary.json", out / "summary.json")  # killed here
    with rundir.claim(out, resume=True, overwrite=False):
        pass
    names = sorted(p.name for p in out.iterdir())
    assert names == [rundir.MANIFEST, "summary.json", "trajectory.h5"]
    assert (out / "trajectory.h5").read_text() == "new"


def test_a_damaged_commit_record_is_named(tmp_path, capsys):
    # regression: a bare JSONDecodeError at every later claim
    path = _config(tmp_path)
    out = tmp_path / "out"
    (out / rundir.STAGING).mkdir(parents=True)
    (out / rundir.STAGING / "COMMIT").write_text("{trunc")
    assert _run(path, "--out", out, "--resume") == cli.ExitCode.CONFIG
    err = capsys.readouterr().err
    assert "the record of an interrupted commit cannot be read" in err and "COMMIT" in err


@pytest.mark.parametrize("case", ["file", "under_a_file", "unwritable"])
def test_bad_out_fails_before_any_work(tmp_path, monkeypatch, capsys, case):
    if case == "unwritable" and os.geteuid() == 0:
        pytest.skip("root writes anywhere")

    def no_work(*args, **kwargs):
        raise AssertionError("work started")

    monkeypatch.setattr(execute_module, "preflight", no_work)
    path = _config(tmp_path, TINY + "trajectory = false\n")
    blocker = tmp_path / "blocker"
    blocker.write_text("a file")
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    out = {"file": blocker, "under_a_file": blocker / "out", "unwritable": locked / "out"}[case]
    assert _run(path, "--out", out) == cli.ExitCode.CONFIG
    err = capsys.readouterr().err
    assert str(out) in err and "unexpected" not in err


def test_an_mpi_launch_without_the_futures_launcher_is_refused(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("PMI_SIZE", "3")
    monkeypatch.setenv("PMI_RANK", "0")
    path = _config(tmp_path)
    assert _run(path, "--out", tmp_path / "out") == cli.ExitCode.CONFIG
    assert f"mpiexec -n 3 python -m mpi4py.futures -m parastokes run {path}" in (
        capsys.readouterr().err
    )
    assert not (tmp_path / "out").exists()
    monkeypatch.setenv("PMI_RANK", "2")  # the other ranks exit quietly
    assert _run(path, "--out", tmp_path / "out") == cli.ExitCode.CONFIG
    assert capsys.readouterr().err == ""


def test_dense_output_adds_frames_inside_the_slices(tmp_path):
    serial = TINY + '[run]\nmode = "serial"\n'
    path = _config(tmp_path, serial.replace("[output]", "[output]\nfigures = false"))
    steps = 2000 // 2  # fine steps per slice: T = 2e-3, τ_f = 1e-6, 2 slices
    dense = ["--set", "parareal.n_slices=2", "--set", f"output.every={steps // 4}"]
    assert _run(path, "--out", tmp_path / "dense", *dense) == 0
    assert _run(path, "--out", tmp_path / "fine", "--set", "parareal.n_slices=8") == 0
    assert _run(path, "--out", tmp_path / "bad", "--set", "output.every=3") == 2
    a = io.read_trajectory(tmp_path / "dense" / "trajectory.h5")
    b = io.read_trajectory(tmp_path / "fine" / "trajectory.h5")
    np.testing.assert_allclose(a["time"], np.linspace(0.0, 0.002, 9), rtol=1e-12)
    np.testing.assert_allclose(a["time"], b["time"], rtol=1e-12)
    # the same solution at the same times (8 slices: one solve per quarter slice), to round-off
    pa, pb = a["bodies"]["rod_0"]["positions"], b["bodies"]["rod_0"]["positions"]
    np.testing.assert_allclose(pa, pb, rtol=0, atol=1e-12 * np.abs(pb).max())
    assert not np.array_equal(pa[1], pa[0])  # frames inside a slice are new states
    boundaries = io.load_arrays(tmp_path / "dense" / runner.REFERENCE)[1]["states"]
    np.testing.assert_array_equal(pa[::4], boundaries[:, :, :3])  # the run's own states, exact


@pytest.mark.mpi
@pytest.mark.skipif(SKIP_REASON is not None, reason=str(SKIP_REASON))
def test_a_real_mpi_launch_without_the_futures_launcher_is_refused_once(tmp_path):
    path = _config(tmp_path)
    out = tmp_path / "out"
    run = mpiexec(["-m", "parastokes", "run", str(path), "--out", str(out)], ranks=2)
    assert run.returncode == cli.ExitCode.CONFIG, run.stderr
    assert run.stderr.count("launched as 2 MPI processes without the futures launcher") == 1
    assert f"mpiexec -n 2 python -m mpi4py.futures -m parastokes run {path}" in run.stderr
    assert not out.exists()


def test_trajectories_need_no_hdf5_file_locking(tmp_path):
    """The directory's own lock keeps other runs out, so the writer takes no HDF5 lock (file
    systems without locking work): another handle can open the file while it is written."""
    path = tmp_path / "trajectory.h5"
    with io.TrajectoryWriter(path, rod_layout(1, 3), config={}) as writer:
        writer.append("serial", 0.0, np.zeros((3, 12)))
        opened = f"h5py.File({str(path)!r}, 'r', locking=True)"
        reader = f"import h5py; print({opened}['serial/time'].shape)"
        other = subprocess.run([sys.executable, "-c", reader], capture_output=True, text=True)
        assert other.stdout.strip() == "(1,)", other.stderr  # refused if the writer held a lock


def test_the_kept_solves_are_resume_state(tmp_path):
    """checkpoint.solves/ is the run's own (not foreign), and --overwrite discards it when the
    new run commits (not before: a new run cut short leaves the old one resumable)."""
    out = tmp_path / "out"
    (out / "checkpoint.solves").mkdir(parents=True)
    (out / "checkpoint.solves" / "fine-k2-n3.npz").write_text("a kept solve")
    found = rundir.RunDirectory(out).entries()
    assert found["state"] == ["checkpoint.solves"] and found["foreign"] == []
    with pytest.raises(rundir.RunDirectoryError, match="--resume"):  # an interrupted run's
        with rundir.claim(out, resume=False, overwrite=False):
            pass
    with rundir.claim(out, resume=False, overwrite=True):
        pass
    assert (out / "checkpoint.solves" / "fine-k2-n3.npz").exists()
    with rundir.claim(out, resume=False, overwrite=True) as directory:
        directory.commit()
    assert not (out / "checkpoint.solves").exists()


def test_resume_in_an_empty_directory_says_it_starts_afresh(tmp_path, capsys):
    # a mistyped --out with --resume used to start a fresh run without a word
    path = _config(tmp_path)
    out = tmp_path / "typo"
    assert cli.main(["run", str(path), "--out", str(out), "--resume"]) == 0
    assert f"--resume: {out} holds no run to continue; starting afresh" in capsys.readouterr().out
