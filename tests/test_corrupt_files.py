"""Every file the package reads back, damaged or foreign, gives exit status 2 and a message that
names it, never an "unexpected error"."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from configs import small_rod

from parastokes import cli
from parastokes import run as runner
from parastokes.core import files
from parastokes.output import trajectory as io
from parastokes.parareal import checkpoint as ckpt

TINY = small_rod(
    parareal="max_iterations = 2",
    rest='[execution]\nexecutor = "serial"\n[output]\nformats = ["png"]\n',
)


@pytest.fixture(scope="module")
def finished(tmp_path_factory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp("finished")
    path = root / "run.toml"
    path.write_text(TINY)
    assert cli.main(["run", str(path), "--out", str(root / "out"), "-q"]) == 0
    return path, root / "out"


DAMAGE = {
    "truncated": lambda data: data[: len(data) // 2],
    "garbage": lambda data: b"not what parastokes wrote\n" * 3,
    "empty": lambda data: b"",
    # valid JSON that is not a whole summary (regression: KeyErrors, exit status 1)
    "foreign": lambda data: b'{"speedup": {"measured": 1.0}, "increments": [0.1]}',
}


def _damaged(source: Path, tmp_path: Path, name: str, how: str) -> Path:
    out = tmp_path / "out"
    shutil.copytree(source, out)
    target = out / name
    target.write_bytes(DAMAGE[how](target.read_bytes()))
    return out


def _assert_named(capsys, path: Path) -> None:
    err = capsys.readouterr().err
    assert str(path) in err and "unexpected" not in err and "allow_pickle" not in err, err


@pytest.mark.parametrize("how", sorted(DAMAGE))
@pytest.mark.parametrize("name", [runner.CHECKPOINT, runner.HISTORY, runner.REFERENCE])
def test_a_damaged_resume_file_is_named(finished, tmp_path, capsys, name, how):
    path, source = finished
    out = _damaged(source, tmp_path, name, how)
    status = cli.main(["run", str(path), "--out", str(out), "--resume", "-q"])
    assert status == cli.ExitCode.CONFIG
    _assert_named(capsys, out / name)


@pytest.mark.parametrize("how", sorted(DAMAGE))
@pytest.mark.parametrize("name", ["summary.json", "trajectory.h5"])
def test_a_damaged_result_is_named_by_plot_and_predict(finished, tmp_path, capsys, name, how):
    path, source = finished
    out = _damaged(source, tmp_path, name, how)
    assert cli.main(["plot", str(out), "-q"]) == cli.ExitCode.CONFIG
    _assert_named(capsys, out / name)
    if name == "summary.json":
        command = ["predict", str(path), "--cores", "4", "--measured", str(out)]
        assert cli.main(command) == cli.ExitCode.CONFIG
        _assert_named(capsys, out / name)


def test_a_foreign_array_file_and_an_old_checkpoint_are_named(tmp_path):
    foreign = tmp_path / "foreign.npz"
    np.savez(foreign, x=np.arange(3))
    with pytest.raises(files.CorruptFileError, match=r"foreign\.npz"):
        io.load_arrays(foreign)
    old = tmp_path / "old.npz"  # the first checkpoint format: a digest for a key
    meta = json.dumps({"format": 1, "key": "abc", "iteration": 0})
    np.savez(old, meta=np.array(meta), states=np.zeros((2, 1)), coarse_values=np.zeros((1, 1)))
    with pytest.raises(files.CorruptFileError, match=r"old\.npz.*version"):
        ckpt.load(old, {})


def test_a_gap_in_the_history_is_drawn_as_a_missing_bar(finished, tmp_path, capsys):
    """An interrupt between an iteration's checkpoint and its history entry leaves a gap (nan,
    null in the summary); the resumed run completes and draws its figures (regression: the
    figure raised a TypeError on None and the run's results were dropped)."""
    path, source = finished
    out = tmp_path / "out"
    shutil.copytree(source, out)
    meta, arrays = io.load_arrays(out / runner.HISTORY)
    io.save_arrays(out / runner.HISTORY, meta, **{k: v[:1] for k, v in arrays.items()})
    command = ["run", str(path), "--out", str(out), "--resume", "-q",
               "--set", "parareal.max_iterations=3"]
    assert cli.main(command) == cli.ExitCode.OK, capsys.readouterr().err
    measured = io.read_summary(out / "summary.json")["speedup"]["by_iteration"]["measured"]
    assert measured[0] is not None and measured[1] is None and measured[2] is not None
    assert (out / "speedup_by_iteration.png").stat().st_size > 0
