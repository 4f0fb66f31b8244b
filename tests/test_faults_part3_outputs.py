"""The third fault campaign (issue 50), runs and outputs: a monitor far above its limit never
silent, ``run --overwrite`` that keeps the old run whole until the new one commits, output sets
committed as one unit and locked per name, touching spheres as a blow-up, ``tune``'s budget and
counts. docs/validation.md, "Faults and bad input", lists them."""

from __future__ import annotations

import json
import resource
import shutil
import signal
from pathlib import Path

import pytest
from test_faults import TINY, finished  # noqa: F401  (the fixture: a finished TINY run)
from test_run_directory import _run

from parastokes import cli
from parastokes.output import rundir
from parastokes.output import trajectory as io
from parastokes.run import serial as serial_module


def _state(directory: Path) -> dict[str, bytes]:
    """The resume state of a run directory, file by file."""
    return {name: (directory / name).read_bytes() for name in rundir.STATE_FILES
            if (directory / name).is_file()}


@pytest.fixture
def interrupted(finished, tmp_path) -> tuple[Path, Path]:  # noqa: F811
    """A copy of the finished TINY run as if interrupted after its last iteration (its resume
    state, no summary): (its configuration, its directory)."""
    path, source = finished
    out = shutil.copytree(source, tmp_path / "out")
    (out / "summary.json").unlink()
    return path, out


# ---- 8: run --overwrite keeps the old run whole until the new one commits ---------------------
def test_an_overwrite_refused_after_the_claim_leaves_the_old_run_resumable(
    interrupted, tmp_path, capsys
):
    path, out = interrupted
    before = _state(out)
    assert {"checkpoint.npz", "reference.npz", "history.npz"} <= set(before)
    # the trajectory's room is checked after the claim: refused under a 1 MB file-size limit
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    resource.setrlimit(resource.RLIMIT_FSIZE, (1_000_000, hard))
    try:
        status = _run(path, "--out", out, "--overwrite", "--set", "output.every=1",
                      "--set", "fine.dt=5e-7")
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
    assert status == cli.ExitCode.CONFIG
    assert "file size limit" in capsys.readouterr().err
    assert _state(out) == before and not (out / rundir.NEXT).exists()
    assert _run(path, "--out", out, "--resume") == 0  # the old run, continued
    assert io.read_summary(out / "summary.json")["iterations"] == 2


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_an_interrupted_overwrite_leaves_the_old_run_resumable(
    interrupted, tmp_path, monkeypatch, capsys, signum
):
    path, out = interrupted
    before = _state(out)
    saved = serial_module.io.save_arrays

    def save_then_signal(target, *args, **kwargs):  # the signal after its first slice is saved
        saved(target, *args, **kwargs)
        signal.raise_signal(signum)

    monkeypatch.setattr(serial_module.io, "save_arrays", save_then_signal)
    status = _run(path, "--out", out, "--overwrite", "--set", "fine.dt=5e-7")
    assert status == 128 + signum
    monkeypatch.undo()
    assert _state(out) == before and not (out / rundir.NEXT).exists()
    assert not (out / "summary.json").exists()
    assert _run(path, "--out", out, "--resume") == 0
    assert io.read_summary(out / "summary.json")["iterations"] == 2


def test_a_completed_overwrite_replaces_the_resume_state(interrupted, tmp_path):
    path, out = interrupted
    before = _state(out)
    assert _run(path, "--out", out, "--overwrite", "--set", "fine.dt=5e-7") == 0
    after = _state(out)
    assert set(after) == set(before) - {"blowup.npz"}
    assert all(after[name] != before[name] for name in after)  # each the new run's
    meta = io.load_arrays(out / "reference.npz")[0]
    assert meta["key"]["fine.dt"] == 5e-7
    assert not (out / rundir.NEXT).exists() and not (out / rundir.STAGING).exists()


def test_a_commit_of_an_overwrite_cut_short_is_completed_by_the_next_claim(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    for name in ("checkpoint.npz", "history.npz", "summary.json"):
        (out / name).write_text("old")
    (out / "checkpoint.solves").mkdir()
    (out / "checkpoint.solves" / "fine-k1-n1.npz").write_text("old")
    with rundir.claim(out, resume=False, overwrite=True) as directory:
        assert directory.state == out / rundir.NEXT
        (directory.state / "reference.npz").write_text("new")  # a serial run: no checkpoint
        (directory.state / "history.npz").write_text("new")
        (directory.staging / "summary.json").write_text("new")
        record = {"files": ["summary.json"], "state": ["history.npz", "reference.npz"]}
        (directory.staging / "COMMIT").write_text(json.dumps(record))
        shutil.rmtree(out / "checkpoint.solves")
        (out / "reference.npz").write_text("half")  # killed between two moves of the state
    with rundir.claim(out, resume=True, overwrite=False):
        pass
    names = sorted(p.name for p in out.iterdir())
    assert names == [rundir.MANIFEST, "history.npz", "reference.npz", "summary.json"]
    assert all((out / n).read_text() == "new" for n in names[1:])
