"""SIGTERM and SIGHUP stop a run like Ctrl-C; nothing of a run outlives its manager, even SIGKILL;
an interrupted serial fine run resumes to the bit."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from configs import small_rod

from parastokes import cli
from parastokes import run as runner
from parastokes.output import trajectory as io

ROOT = Path(__file__).resolve().parents[1]
ENV = {**os.environ, "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1"}

# Parareal on two worker processes, long enough (tens of seconds) to be killed mid-run.
POOLED = small_rod(
    model="",
    parareal="max_iterations = 2",
    rest='[execution]\nexecutor = "processes"\nworkers = 2\n[run]\nmode = "parareal"\n',
).replace("n_slices = 4", "n_slices = 2").replace("richardson = { m = 1, r = 0.83 }", "")
POOLED = POOLED.replace("n_points = 21\nlength = 4.0", "n_points = 41\nlength = 8.0").replace(
    "t1 = 0.002", "t1 = 0.2"
)
# The serial fine run alone, in 8 slices of a fraction of a second each.
SERIAL = small_rod(rest='[run]\nmode = "serial"\n[output]\nfigures = false\n').replace(
    "n_slices = 4", "n_slices = 8"
).replace("n_points = 21\nlength = 4.0", "n_points = 41\nlength = 8.0").replace(
    "t1 = 0.002", "t1 = 0.02"
)


def _stat(pid: int) -> list[str] | None:
    """Fields of /proc/PID/stat after the command name; None once the process is gone."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None


def _descendants(pid: int) -> dict[int, str]:
    """Every process below ``pid``, with its start time (to tell a reused PID)."""
    parents = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit() and (fields := _stat(int(entry.name))) is not None:
            parents[int(entry.name)] = (int(fields[1]), fields[19])
    found, frontier = {}, [pid]
    while frontier:
        parent = frontier.pop()
        for child, (ppid, started) in parents.items():
            if ppid == parent and child not in found:
                found[child] = started
                frontier.append(child)
    return found


def _running(processes: dict[int, str]) -> list[int]:
    """Those of ``processes`` still running (not exited, not a zombie, not a reused PID)."""
    alive = []
    for pid, started in processes.items():
        fields = _stat(pid)
        if fields is not None and fields[0] != "Z" and fields[19] == started:
            alive.append(pid)
    return alive


def _start(tmp_path: Path, text: str) -> tuple[subprocess.Popen, Path]:
    path = tmp_path / "run.toml"
    path.write_text(text)
    out = tmp_path / "out"
    command = [sys.executable, "-m", "parastokes", "run", str(path), "--out", str(out), "-q"]
    return subprocess.Popen(command, env=ENV, stderr=subprocess.PIPE, text=True), out


def _wait_until(manager: subprocess.Popen, ready) -> None:
    """Wait (at most 5 min) until ``ready()``, the manager still running."""
    deadline = time.monotonic() + 300
    while not ready():
        assert manager.poll() is None and time.monotonic() < deadline, manager.stderr.read()
        time.sleep(0.02)


def _signal_during_the_serial_run(tmp_path: Path, signum: int) -> tuple[subprocess.Popen, str]:
    """Start SERIAL, send ``signum`` once its first slice is saved; the manager and its stderr."""
    manager, out = _start(tmp_path, SERIAL)
    _wait_until(manager, (out / runner.REFERENCE).exists)
    manager.send_signal(signum)
    return manager, manager.communicate(timeout=60)[1]


pytestmark = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGKILL])
def test_nothing_of_the_run_outlives_its_manager(tmp_path, signum):
    manager, out = _start(tmp_path, POOLED)
    _wait_until(manager, lambda: len(_descendants(manager.pid)) >= 4)  # forkserver, 2 workers,
    _wait_until(manager, (out / runner.CHECKPOINT).exists)  # tracker; busy with iteration 1
    processes = _descendants(manager.pid)
    manager.send_signal(signum)
    _, stderr = manager.communicate(timeout=60)
    deadline = time.monotonic() + 10
    while _running(processes) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert _running(processes) == []
    if signum == signal.SIGTERM:
        assert manager.returncode == cli.ExitCode.TERMINATED == 143
        assert "terminated (SIGTERM)" in stderr and "--resume" in stderr
        assert "leaked" not in stderr and "Traceback" not in stderr
        assert not (out / "summary.json").exists()


def test_sighup_is_handled_like_ctrl_c(tmp_path):
    manager, stderr = _signal_during_the_serial_run(tmp_path, signal.SIGHUP)
    assert manager.returncode == cli.ExitCode.HANGUP == 129
    assert "hung up (SIGHUP)" in stderr


def test_an_interrupted_serial_fine_run_resumes_bit_for_bit(tmp_path):
    manager, stderr = _signal_during_the_serial_run(tmp_path, signal.SIGTERM)
    assert manager.returncode == 143, stderr
    out = tmp_path / "out"
    meta, _ = io.load_arrays(out / runner.REFERENCE)
    assert 1 <= meta["done"] < 8  # the slices computed before the signal are kept

    path = tmp_path / "run.toml"
    assert cli.main(["run", str(path), "--out", str(out), "--resume", "-q"]) == 0
    assert cli.main(["run", str(path), "--out", str(tmp_path / "whole"), "-q"]) == 0
    resumed = io.read_summary(out / "summary.json")
    whole = io.read_summary(tmp_path / "whole" / "summary.json")
    assert resumed["final_positions"] == whole["final_positions"]
    _, a = io.load_arrays(out / runner.REFERENCE)
    _, b = io.load_arrays(tmp_path / "whole" / runner.REFERENCE)
    assert a["states"].tobytes() == b["states"].tobytes()  # every slice boundary, bit for bit
