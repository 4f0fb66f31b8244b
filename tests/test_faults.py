"""The fault campaign of issue #32 as regression tests: full disks and descriptor limits, numerical
failures inside Parareal, advice on blow-ups, unbounded input, `tune --out` and `predict` abuse,
`plot` during a cut-short commit, `--resume` of a finished run with a stricter stopping rule, and
the smaller ones (a BOM, SIGTERM outside a run, orphan temporary files, scripts without the
`__main__` guard). docs/validation.md, "Hardening: the fault campaign", lists them."""

from __future__ import annotations

import errno
import os
import resource
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from configs import small_rod
from test_run_directory import _config, _run

from parastokes import cli
from parastokes import run as runner
from parastokes.core import files
from parastokes.output import rundir
from parastokes.output import trajectory as io

ROOT = Path(__file__).resolve().parents[1]
ENV = {**os.environ, "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1"}

# A small rod problem run in-process (serial executor): a few seconds; its trajectory.h5 is about
# 75 kB, every other file under 40 kB.
TINY = 'title = "tiny rod"\n' + small_rod(
    parareal="max_iterations = 2",
    rest='[execution]\nexecutor = "serial"\n[output]\nfigures = false\n',
)


def _command(*args: str, limit: int | None = None, **kwargs) -> subprocess.CompletedProcess:
    """``python -m parastokes ARGS`` in a subprocess, its file size limited to ``limit`` bytes."""

    def limited() -> None:
        if limit is not None:
            resource.setrlimit(resource.RLIMIT_FSIZE, (limit, resource.RLIM_INFINITY))

    return subprocess.run(
        [sys.executable, "-m", "parastokes", *map(str, args)], env=ENV, capture_output=True,
        text=True, preexec_fn=limited, timeout=300, **kwargs,
    )


def _bounded_memory() -> None:
    """A subprocess's address space limited to 2 GiB: an attack that grows without bound (in a
    regression) ends in a MemoryError there instead of taking the test machine's memory."""
    resource.setrlimit(resource.RLIMIT_AS, (2 << 30, resource.RLIM_INFINITY))


@pytest.fixture(scope="module")
def finished(tmp_path_factory) -> tuple[Path, Path]:
    """A finished TINY run (2 iterations): (its configuration, its directory)."""
    root = tmp_path_factory.mktemp("finished")
    path = _config(root, TINY)
    assert _run(path, "--out", root / "out") == 0
    return path, root / "out"


def _copy(source: Path, target: Path) -> Path:
    import shutil

    shutil.copytree(source, target)
    return target


# ---- 5: a full disk while trajectory.h5 is written -------------------------------------------
def test_a_file_size_limit_below_the_trajectory_is_exit_2_naming_it(finished, tmp_path):
    path, source = finished
    out = _copy(source, tmp_path / "out")
    checkpoint = (out / runner.CHECKPOINT).read_bytes()
    trajectory = (out / runner.TRAJECTORY).read_bytes()
    # --resume of a finished run only writes its results again: the trajectory (75 kB) exceeds
    # the limit, the checkpoint and the summary do not; refused before its frames are written
    done = _command("run", path, "--out", out, "--resume", "-q", limit=30_000)
    assert done.returncode == 2, done.stderr  # (was 139: a segmentation fault in h5py)
    assert "Segmentation" not in done.stderr and "Traceback" not in done.stderr
    assert f"cannot write {out / rundir.STAGING / runner.TRAJECTORY}: its 10 frames need at " \
           "least" in done.stderr and "but the file size limit is 0.03 MB" in done.stderr
    assert (out / runner.CHECKPOINT).read_bytes() == checkpoint  # the checkpoint is intact
    assert (out / runner.TRAJECTORY).read_bytes() == trajectory  # the old results are kept
    assert not (out / rundir.LOCK).exists() and not (out / rundir.STAGING).exists()


def test_a_disk_that_fills_while_the_trajectory_is_written_is_exit_2_naming_it(
    finished, tmp_path, monkeypatch, capsys
):
    path, source = finished
    out = _copy(source, tmp_path / "out")
    checkpoint = (out / runner.CHECKPOINT).read_bytes()
    write = files.GuardedFile.write

    def filling(self, data):  # the disk is full past 30 kB (after the check for room)
        if self.tell() + memoryview(data).nbytes > 30_000 and self.failed is None:
            self.failed = OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return write(self, data)

    monkeypatch.setattr(files.GuardedFile, "write", filling)
    assert _run(path, "--out", out, "--resume") == cli.ExitCode.CONFIG
    err = capsys.readouterr().err
    assert f"cannot write {out / rundir.STAGING / runner.TRAJECTORY}: No space left on device " \
           "(the file system is full" in err
    assert (out / runner.CHECKPOINT).read_bytes() == checkpoint
    assert not (out / rundir.LOCK).exists() and not (out / rundir.STAGING).exists()


def test_the_trajectory_writer_survives_a_failed_write_and_names_the_file(tmp_path):
    from test_io import rod_layout, rod_state

    path = tmp_path / "trajectory.h5"
    script = f"""
import sys
sys.path.insert(0, {str(ROOT / 'tests')!r})
from test_io import rod_layout, rod_state
from parastokes import io
from parastokes.core.files import FileWriteError
writer = io.TrajectoryWriter({str(path)!r}, rod_layout(1, 50), config={{}})
try:
    for i in range(1000):
        writer.append("serial", float(i), rod_state(1, 50, 0.0))
except FileWriteError as error:
    print("raised:", error)
try:
    writer.close()
except FileWriteError as error:
    print("closed:", error)
"""

    def limited() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (60_000, resource.RLIM_INFINITY))

    done = subprocess.run([sys.executable, "-c", script], env=ENV, capture_output=True,
                          text=True, preexec_fn=limited, timeout=120)
    assert done.returncode == 0, done.stderr  # (h5py alone: -11, a segmentation fault)
    assert f"raised: cannot write {path}: File too large" in done.stdout
    assert not path.exists()  # the damaged file is removed
    with io.TrajectoryWriter(path, rod_layout(1, 3), config={}) as writer:  # (unlimited: fine)
        writer.append("serial", 0.0, rod_state(1, 3, 0.0))
    assert io.read_trajectory(path)["time"].tolist() == [0.0]


@pytest.mark.parametrize("number", [errno.ENOSPC, errno.EMFILE])
def test_every_atomic_write_names_its_file_and_the_cause(tmp_path, monkeypatch, number):
    def failing(*args, **kwargs):
        raise OSError(number, os.strerror(number))

    monkeypatch.setattr(os, "fsync", failing)
    target = tmp_path / "summary.json"
    with pytest.raises(files.FileWriteError) as caught:
        io.write_summary(target, {"a": 1})
    text = str(caught.value)
    assert text.startswith(f"cannot write {target}: {os.strerror(number)}")
    assert ("file system is full" if number == errno.ENOSPC else "ulimit -n") in text
    assert cli.exit_code(caught.value) == cli.ExitCode.CONFIG
    assert list(tmp_path.iterdir()) == []  # no temporary file left


# ---- 6, 7: numerical failures inside Parareal; advice on blow-ups ----------------------------
# The rod starts 0.001 above the wall (ε = 1): the first corrections make a frame singular.
AT_THE_WALL = TINY.replace("length = 4.0", "length = 4.0\nheight = 0.001").replace(
    "lagrange = { epsilon = [5.6, 5.65] }\nrichardson = { m = 1, r = 0.83 }\n", ""
) + '[run]\nmode = "parareal"\n'
# The rod starts 0.5 above the wall and is drawn to it at t = 0.00213 whatever the step.
TO_THE_WALL = TINY.replace("length = 4.0", "length = 4.0\nheight = 0.5").replace(
    "t1 = 0.002", "t1 = 0.0024"
) + '[run]\nmode = "serial"\n'


@pytest.mark.parametrize("schedule", ["standard", "pipelined"])
def test_a_correction_that_breaks_the_state_is_a_blow_up_naming_slice_and_iteration(
    tmp_path, capsys, schedule
):
    path = _config(tmp_path, AT_THE_WALL)
    if schedule == "pipelined":  # (one [parareal] table)
        path.write_text(AT_THE_WALL.replace("max_iterations = 2",
                                            'max_iterations = 2\nschedule = "pipelined"'))
    out = tmp_path / "out"
    assert _run(path, "--out", out) == cli.ExitCode.BLOWUP
    err = capsys.readouterr().err
    assert "the correction (eq. 11) of slice 2 in iteration 1 (Parareal) blew up" in err
    assert "a frame is singular" in err
    meta, arrays = io.load_arrays(out / runner.BLOWUP)
    assert meta["where"].startswith("the correction") and np.isfinite(arrays["last_state"]).all()
    assert "reduce" not in err and "a body is at the wall" in err  # 7: the step is not the cause


def test_a_blow_up_at_the_wall_at_the_same_time_for_every_step_says_so(tmp_path, capsys):
    path = _config(tmp_path, TO_THE_WALL)
    out = tmp_path / "out"
    assert _run(path, "--out", out) == cli.ExitCode.BLOWUP
    first = capsys.readouterr().err
    assert "a body is at the wall" in first and "reduce fine.dt" not in first
    assert _run(path, "--out", out, "--overwrite", "--set", "fine.dt=5e-7") == cli.ExitCode.BLOWUP
    second = capsys.readouterr().err
    assert "the time does not move with the step" in second
    assert "with a step of 1e-06 (now t = 0.00213" in second


# ---- 10: unbounded input ---------------------------------------------------------------------
def test_a_device_or_a_huge_file_is_not_read_as_a_configuration(tmp_path, capsys):
    based = _config(tmp_path, 'base = "/dev/zero"\n' + TINY, "based.toml")
    huge = tmp_path / "huge.toml"
    huge.write_text("# " + "x" * (2 << 20) + "\n" + TINY)
    assert cli.main(["check", str(huge)]) == cli.ExitCode.CONFIG
    assert "larger than 1 MiB" in capsys.readouterr().err

    # (were /dev/zero read whole: a MemoryError past 2 GiB, not the machine's memory)
    done = subprocess.run([sys.executable, "-m", "parastokes", "check", "/dev/zero", str(based)],
                          env=ENV, capture_output=True, text=True, preexec_fn=_bounded_memory,
                          timeout=120)
    assert done.returncode == cli.ExitCode.CONFIG, done.stderr
    assert done.stderr.count("not a regular file") == 2


def test_a_value_nested_5000_deep_is_a_configuration_error(tmp_path, capsys):
    path = _config(tmp_path, TINY)
    deep = "[" * 5000 + "]" * 5000
    assert cli.main(["check", str(path), "--set", f"coarse.lagrange={deep}"]) == 2
    assert "coarse.lagrange: arrays or tables nested more than 32 deep" in capsys.readouterr().err
    nested = _config(tmp_path, TINY + f"[tune]\nx = {deep}\n", "nested.toml")
    assert cli.main(["check", str(nested)]) == 2


def test_a_problem_that_cannot_fit_in_memory_is_refused_by_check_and_run(tmp_path, capsys,
                                                                          monkeypatch):
    from parastokes.config import checks

    path = _config(tmp_path, TINY.replace("n_points = 21", "n_points = 100000000"))
    monkeypatch.setattr(checks, "physical_memory", lambda: 16.0 * 2**30)

    def allocate(*args, **kwargs):  # (were it not refused: no 10 GB state on the test machine)
        raise AssertionError("the run was not refused before its states were allocated")

    monkeypatch.setattr(runner, "execute", allocate)
    assert cli.main(["check", str(path)]) == cli.ExitCode.CONFIG
    assert _run(path, "--out", tmp_path / "out") == cli.ExitCode.CONFIG
    err = capsys.readouterr().err
    assert err.count("model.n_points: 100000000 points: the run's states alone need more than "
                     "53.6 GiB, and this machine has 16 GiB") == 2
    assert not (tmp_path / "out").exists()  # refused before the directory is made


def test_out_of_memory_in_a_run_is_exit_2_with_one_line(capsys, monkeypatch):
    def fail(*args, **kwargs):
        raise MemoryError()

    monkeypatch.setattr(runner, "execute", fail)
    assert cli.main(["demo", "--out", "unused", "-q"]) == cli.ExitCode.CONFIG
    assert capsys.readouterr().err.splitlines() == [  # (was a second line under "error: ")
        "error: out of memory (MemoryError): use fewer points, slices or workers, or a machine "
        "with more memory"]


# ---- 11: plot during a commit cut short; 14: orphan temporary files --------------------------
def test_plot_completes_a_commit_cut_short_before_drawing(finished, tmp_path):
    path, source = finished
    new = tmp_path / "new"
    assert _run(path, "--out", new, "--set", "parareal.max_iterations=1") == 0
    out = _copy(source, tmp_path / "out")
    staging = out / rundir.STAGING
    staging.mkdir()
    names = ["summary.json", "trajectory.h5", "trajectory.xdmf"]
    for name in names:
        (staging / name).write_bytes((new / name).read_bytes())
    rundir._write_names(staging / "COMMIT", names)
    os.replace(staging / "summary.json", out / "summary.json")  # killed here
    orphan = out / f"{rundir.MANIFEST}.999999999.tmp"  # killed while writing the manifest
    orphan.write_text("{")
    assert cli.main(["plot", str(out), "-q", "--formats", "png"]) == 0
    assert not staging.exists() and not orphan.exists()
    for name in names:  # the new results whole, and the figures drawn from them
        assert (out / name).read_bytes() == (new / name).read_bytes()
    assert io.read_history(out / "trajectory.h5")["increments"].shape == (1,)


# ---- 12: --resume of a finished run with a stricter stopping rule ----------------------------
@pytest.mark.parametrize("change", ["parareal.max_iterations=1", "parareal.tol=1"])
def test_resume_that_would_have_stopped_earlier_is_refused_saying_why(finished, tmp_path, capsys,
                                                                     change):
    path, source = finished
    out = _copy(source, tmp_path / "out")
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    assert _run(path, "--out", out, "--resume", "--set", change) == cli.ExitCode.CONFIG
    err = capsys.readouterr().err
    assert f"{change.split('=')[0]}:" in err and "has done 2 iterations" in err
    assert "cannot stop earlier" in err and "--overwrite" in err
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == before
    # a rule that the stored iterate does not pass still resumes (no new iteration is needed)
    assert _run(path, "--out", out, "--resume", "--set", "parareal.max_iterations=2") == 0


# ---- 14: the smaller ones ----------------------------------------------------------------------
def test_a_configuration_with_a_utf8_bom_is_read(tmp_path, capsys):
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf" + TINY.encode())
    assert cli.main(["check", str(path)]) == 0


@pytest.mark.parametrize("command", ["check", "predict"])
def test_sigterm_outside_a_run_does_not_advise_resume(tmp_path, command):
    path = _config(tmp_path, TINY)
    extra = ["--cores", "4"] if command == "predict" else []
    slow = tmp_path / "slow.py"  # the command, held at its start until SIGTERM arrives
    slow.write_text(
        "import sys, time\nfrom parastokes import cli\n"
        "from parastokes import config\n"
        "loading = config.load\n"
        "def load(*a, **k):\n    print('ready', flush=True)\n    time.sleep(60)\n"
        "config.load = load\n"
        "if __name__ == '__main__':\n    sys.exit(cli.main(sys.argv[1:]))\n"
    )
    process = subprocess.Popen([sys.executable, str(slow), command, str(path), *extra], env=ENV,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert process.stdout.readline().strip() == "ready"
    process.send_signal(signal.SIGTERM)
    _, err = process.communicate(timeout=30)
    assert process.returncode == 143
    assert "terminated (SIGTERM); no run was in progress" in err and "--resume" not in err


def test_a_script_without_the_main_guard_is_told_so_in_one_line(tmp_path):
    script = tmp_path / "unguarded.py"
    script.write_text("from parastokes.parallel import ProcessExecutor\nProcessExecutor(1)\n")
    done = subprocess.run([sys.executable, str(script)], env=ENV, capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 1
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith("RuntimeError: starting the worker processes failed")
    assert f'If {script} starts the run, put its code under `if __name__ == "__main__":`' in last


# ---- 8: tune --out never overwrites other files ----------------------------------------------
@pytest.mark.parametrize("name", ["summary.json", "x.json", "d.png", "existing.toml", "adir"])
def test_tune_out_is_checked_before_the_search(finished, tmp_path, capsys, name):
    path, source = finished
    out = _copy(source, tmp_path / "run")  # a finished run's directory
    (out / "existing.toml").write_text("kept")
    (out / "adir").mkdir()
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    code = cli.main(["tune", str(path), "--cores", "4", "--target", "1e-6", "--out",
                     str(out / name), "-q"])
    assert code == cli.ExitCode.CONFIG
    err = capsys.readouterr().err
    reason = {"summary.json": "must not end in .json", "x.json": "must not end in .json",
              "d.png": "must not end in .png", "existing.toml": "already exist",
              "adir": "is a directory"}[name]
    assert reason in err
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == before


def test_tune_outputs_are_three_distinct_new_files_unless_overwrite(tmp_path):
    from parastokes.tuning.command import outputs

    toml, record, figure = outputs(tmp_path / "sub" / "t.toml", overwrite=False)
    assert (toml.name, record.name, figure.name) == ("t.toml", "t.json", "t.png")
    assert not toml.parent.exists()  # checked only: the claim makes it (rundir.claim_files)
    toml.parent.mkdir()
    record.write_text("{}")
    assert outputs(toml, overwrite=True) == (toml, record, figure)
    with pytest.raises(ValueError, match=r"t\.json already exist"):
        outputs(toml, overwrite=False)


# ---- 9: predict at any core count --------------------------------------------------------------
def test_predict_beyond_the_simulated_size_gives_the_closed_formulas_at_once(finished):
    from parastokes.parareal import predict_schedules, schedule_model

    path, _ = finished
    # (was: 24 GB until the kernel killed it; here a MemoryError past 2 GiB)
    done = subprocess.run(
        [sys.executable, "-m", "parastokes", "predict", str(path), "--cores", "4", "1000000000"],
        env=ENV, capture_output=True, text=True, preexec_fn=_bounded_memory, timeout=300,
    )
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    big = next(line for line in lines if line.split()[0] == "1000000000").split()
    assert big[6] == "-" and big[8] == "-" and float(big[7]) == pytest.approx(20.0, rel=1e-3)
    assert "not simulated for N_c = 1000000000" in lines[-1]
    small = next(line for line in lines if line.split()[0] == "4").split()
    (row,) = predict_schedules(float(small[2]), 2, [4], 4)  # (W = 4 >= N_G: one round)
    assert float(small[6]) == pytest.approx(row["standard"], abs=1e-3)
    assert schedule_model.simulated_tasks(10**9, 2, 4) > schedule_model.MAX_SIMULATED_TASKS


def test_a_checkout_in_the_current_directory_that_shadows_the_installed_package_is_named(
    tmp_path,
):
    checkout, installed = tmp_path / "parastokes", tmp_path / "site" / "parastokes"
    note = cli.shadowing_note(checkout, tmp_path, installed)
    assert note is not None and f"running the parastokes of {checkout}" in note
    assert str(installed) in note
    assert cli.shadowing_note(checkout, tmp_path / "elsewhere", installed) is None
    assert cli.shadowing_note(checkout, tmp_path, None) is None  # nothing installed: no note
    assert cli.shadowing_note(installed, installed.parent, installed) is None


def test_too_many_open_files_while_reading_is_not_called_damage(tmp_path, monkeypatch):
    path = tmp_path / "a.npz"
    files.write_npz(path, {}, x=np.zeros(2))

    def exhausted(*args, **kwargs):
        raise OSError(errno.EMFILE, os.strerror(errno.EMFILE))

    monkeypatch.setattr(np, "load", exhausted)
    with pytest.raises(files.FileWriteError, match=f"cannot read {path}: Too many open files"):
        files.read_npz(path)


@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")
@pytest.mark.parametrize("signum, code", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_a_sigterm_lost_in_a_finalizer_still_stops_the_run_before_its_results_move(
        tmp_path, monkeypatch, capsys, signum, code):
    """SIGTERM (or Ctrl-C) delivered while a finalizer runs (the garbage collector's work, at any
    moment) is printed as "Exception ignored" and dropped by Python; the run went on and exited
    0 with its results in place. The handler's record makes the next safe point raise it again."""
    import weakref

    from parastokes.run import execution

    frames = execution.append_frames

    def lost_then_frames(*args, **kwargs):
        class Garbage:
            pass

        def collected():  # the handler runs inside this finalizer: its exception is ignored
            os.kill(os.getpid(), signum)
            for _ in range(10_000):
                pass

        thing = Garbage()
        weakref.finalize(thing, collected)
        del thing
        return frames(*args, **kwargs)

    monkeypatch.setattr(execution, "append_frames", lost_then_frames)
    # Python's own Ctrl-C handler, even when this suite runs with SIGINT ignored (a background
    # job of a shell without job control), which the command leaves as it is
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    path = _config(tmp_path, TINY)
    try:
        assert _run(path, "--out", tmp_path / "out") == code
    finally:
        signal.signal(signal.SIGINT, previous)
    assert not (tmp_path / "out" / "summary.json").exists()
    assert "Exception ignored" not in capsys.readouterr().err  # no traceback of the first raise
