"""The third fault campaign (issue 50), runs and outputs: a monitor far above its limit never
silent, ``run --overwrite`` that keeps the old run whole until the new one commits, output sets
committed as one unit and locked per name, touching spheres as a blow-up, ``tune``'s budget and
counts. docs/validation.md, "Faults and bad input", lists them."""

from __future__ import annotations

import errno
import json
import os
import resource
import shutil
import signal
from pathlib import Path

import pytest
from configs import small_rod
from test_faults import TINY, finished  # noqa: F401  (the fixture: a finished TINY run)
from test_flow import scene_run  # noqa: F401  (run_dir's fixture)
from test_output_claims import run_dir  # noqa: F401  (the fixture: a scene run, to write into)
from test_run_directory import _config, _run

from parastokes import cli
from parastokes.core import files
from parastokes.output import rundir
from parastokes.output import trajectory as io
from parastokes.run import execution
from parastokes.run import serial as serial_module
from parastokes.tuning.report import table


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


def _signal_after_the_first_slice(monkeypatch, signum: int) -> None:
    """Deliver ``signum`` to this process once the serial fine run has saved its first slice."""
    saved = serial_module.io.save_arrays

    def save_then_signal(target, *args, **kwargs):
        saved(target, *args, **kwargs)
        signal.raise_signal(signum)

    monkeypatch.setattr(serial_module.io, "save_arrays", save_then_signal)


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
    _signal_after_the_first_slice(monkeypatch, signum)
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


# ---- 9: output sets committed as one unit, and locked per name -------------------------------
def _grid_shapes(stem: Path) -> tuple[str, str]:
    """The grid's shape (nz ny nx) in ``stem.h5`` and in the ``stem.xdmf`` beside it."""
    import re

    import h5py

    with h5py.File(stem.with_suffix(".h5"), "r") as f:
        shape = " ".join(map(str, f.attrs["shape"][::-1]))
    text = stem.with_suffix(".xdmf").read_text()
    return shape, re.search(r'TopologyType="3DRectMesh" Dimensions="([\d ]+)"', text).group(1)


def test_a_flow_interrupted_between_its_two_renames_is_one_grid(run_dir, tmp_path,  # noqa: F811
                                                                 monkeypatch):
    out = tmp_path / "f"
    assert cli.main(["flow", str(run_dir), "--resolution", "4", "--out", str(out), "-q"]) == 0
    old = _grid_shapes(out)
    real, moved = os.replace, []

    def interrupted(source, target):  # Ctrl-C after the first file of the set is in place
        if Path(target).parent == tmp_path and Path(target).suffix in (".h5", ".xdmf"):
            moved.append(target)
            if len(moved) == 2:
                signal.raise_signal(signal.SIGINT)
        real(source, target)

    monkeypatch.setattr(os, "replace", interrupted)
    status = cli.main(["flow", str(run_dir), "--resolution", "5", "--out", str(out), "-q"])
    monkeypatch.undo()
    assert status == cli.ExitCode.INTERRUPTED
    new = _grid_shapes(out)
    assert new[0] == new[1] != old[0]  # the new set whole (its moves completed at once)
    assert not list(tmp_path.glob("*.tmp")) and not list(tmp_path.glob(".*.commit"))


def test_a_set_whose_moves_fail_midway_is_completed_by_the_next_access(tmp_path, monkeypatch):
    first, second = tmp_path / "a.toml", tmp_path / "a.json"
    files.commit_set({first: b"old toml", second: b"old json"})
    real, calls = os.replace, []

    def failing(source, target):  # every move after the set's first fails (the disk went away)
        if str(target) in (str(first), str(second)):
            calls.append(target)
            if len(calls) > 1:
                raise OSError(errno.EIO, "Input/output error")
        real(source, target)

    monkeypatch.setattr(os, "replace", failing)
    with pytest.raises(files.FileWriteError, match=r"a\.json"):
        files.commit_set({first: b"new toml", second: lambda h: h.write(b"new json")})
    assert (first.read_bytes(), second.read_bytes()) == (b"new toml", b"old json")  # a mixture
    monkeypatch.undo()
    assert files.recover_sets(tmp_path) == [second]  # ... until the next access
    assert (first.read_bytes(), second.read_bytes()) == (b"new toml", b"new json")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json", "a.toml"]


def test_a_set_interrupted_before_its_moves_stays_the_old_one(tmp_path):
    first, second = tmp_path / "a.toml", tmp_path / "a.json"
    files.commit_set({first: b"old toml", second: b"old json"})

    def stopped(handle):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        files.commit_set({first: b"new toml", second: stopped})
    assert (first.read_bytes(), second.read_bytes()) == (b"old toml", b"old json")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json", "a.toml"]


def test_two_commands_writing_one_output_name_are_locked_against_each_other(
    run_dir, tmp_path, capsys  # noqa: F811
):
    out = tmp_path / "outs" / "f"
    with files.hold_names([out.with_suffix(".xdmf")]):  # a first command, alive, writing it
        status = cli.main(["flow", str(run_dir), "--resolution", "6", "--out", str(out), "-q"])
        assert status == cli.ExitCode.CONFIG
        err = capsys.readouterr().err
        assert f"{out.with_suffix('.xdmf')} is being written by" in err and f"PID {os.getpid()}" \
            in err
        with pytest.raises(files.OutputInUse):
            files.commit_set({out.with_suffix(".xdmf"): b"x"})
    assert not list(out.parent.iterdir())  # nothing written, no lock left
    assert cli.main(["flow", str(run_dir), "--resolution", "4", "--out", str(out), "-q"]) == 0
    assert sorted(p.name for p in out.parent.iterdir()) == ["f.h5", "f.png", "f.xdmf"]


# ---- 7: a monitor above its limit at the end is never silent, and may be fatal ----------------
#: A rod by lieuler at a step far too large: its length changes by 7.9 % (limit 1 %) by t = 0.03.
STRETCHED = small_rod(rest='[execution]\nexecutor = "serial"\n[output]\nfigures = false\n'
                           'trajectory = false\n[run]\nmode = "serial"\n').replace(
    "dt = 1e-6", 'dt = 5e-3\nscheme = "lieuler"').replace("t1 = 0.002", "t1 = 0.04").replace(
    "dt_ratio = 10", "dt_ratio = 1").replace("richardson = { m = 1, r = 0.83 }", "")
ALARM = ("the stability monitor reached 0.0794 at t = 0.03, 7.94 times its limit 0.01 (a rod's "
         "length, a vesicle's area changed that much)")


def test_a_run_ending_above_its_monitor_limit_warns_on_stderr_and_in_the_summary(tmp_path, capsys):
    path = _config(tmp_path, STRETCHED)
    assert _run(path, "--out", tmp_path / "out") == 0
    err = capsys.readouterr().err
    assert f"warning: {ALARM}" in err  # (even with -q)
    # (low) without -q: the results listed are those written (no trajectory, no figures here)
    assert cli.main(["run", str(path), "--out", str(tmp_path / "out"), "--overwrite"]) == 0
    assert f"results in {tmp_path / 'out'}/ (summary.json)\n" in capsys.readouterr().out
    summary = io.read_summary(tmp_path / "out" / "summary.json")
    assert any(ALARM in w for w in summary["warnings"])
    assert summary["monitor"]["time"] == pytest.approx(0.03)


@pytest.mark.parametrize("how", [["--monitor-fatal"], ["--set", "output.monitor_fatal=true"]])
def test_a_monitor_above_its_limit_is_fatal_when_asked(tmp_path, capsys, how):
    path = _config(tmp_path, STRETCHED)
    out = tmp_path / "out"
    assert _run(path, "--out", out, *how) == cli.ExitCode.BLOWUP
    err = capsys.readouterr().err
    assert f"error: {ALARM}" in err and f"the results are in {out}" in err
    assert any(ALARM in w for w in io.read_summary(out / "summary.json")["warnings"])


def test_the_monitor_warning_starts_just_above_the_limit():
    monitor = {"max": 0.01, "time": 0.5, "final": 0.0, "limit": 0.01}
    assert execution.monitor_warning(monitor) is None  # at the limit: within it
    above = execution.monitor_warning({**monitor, "max": 0.0125})
    assert above is not None and "0.0125 at t = 0.5, 1.25 times its limit 0.01" in above
    assert execution.monitor_warning({**monitor, "max": float("nan")}) is not None


# ---- 10: spheres that touch mid-run are a blow-up naming them, with the repulsion advised ----
def _sphere_body(name: str, x: float, push: float) -> str:
    return (f'[[bodies]]\nname = "{name}"\nkind = "rigid"\nshape = "sphere"\nradius = 1.0\n'
            f"n_points = 42\nposition = [{x}, 0.0, 0.0]\nforce = [{push}, 0.0, 0.0]\n")


#: Two spheres pushed together (a gap of 0.6 radii closing at about 4 radii per unit time).
TOUCHING = ('title = "two spheres pushed together"\n[scene]\nviscosity = 0.05305164769729845\n'
            "wall = false\n" + _sphere_body("left", 0.0, 10.0) + _sphere_body("right", 2.6, -10.0)
            + '[time]\nt1 = 0.2\n[fine]\nscheme = "rk2"\ndt = 0.01\n[coarse]\nscheme = "euler"\n'
            'dt_ratio = 2\n[parareal]\nn_slices = 2\n[run]\nmode = "serial"\n[execution]\n'
            'executor = "serial"\n[output]\nfigures = false\n')


def test_spheres_that_touch_mid_run_are_a_blow_up_naming_them_and_the_repulsion(tmp_path,
                                                                                 capsys):
    out = tmp_path / "out"
    assert _run(_config(tmp_path, TOUCHING), "--out", out) == cli.ExitCode.BLOWUP
    err = capsys.readouterr().err
    assert "left and right overlap or touch" in err and "blew up at t = 0.13" in err
    assert "enable [scene] repulsion" in err
    meta, arrays = io.load_arrays(out / "blowup.npz")
    assert meta["t"] == pytest.approx(0.13) and arrays["last_state"].shape[0] == 2 * 43
    # at the start the same contact is a configuration error, before any work
    apart = TOUCHING.replace("position = [2.6,", "position = [1.9,")
    assert _run(_config(tmp_path, apart, "apart.toml"), "--out", tmp_path / "o2") == 2
    assert "left and right overlap" in capsys.readouterr().err


# ---- 12: tune's budget inside implicit step-limit searches, its counts, TUNED.toml -----------
def _tune_rod():
    from parastokes import integrate, models

    rod = models.rod_swimmer(n_points=21, length=4.0, epsilon=1.0)
    return integrate.Propagator(rod, "rk2", 1e-6)


@pytest.fixture(scope="module")
def budgeted():
    """A search with implicit candidates (ros2, plain and at nodes of ε) under a budget of the
    baseline's trial runs and half a run more, on a clock that charges one per trial run of a
    step-limit search: (its result, the trial runs of the baseline alone, those of the
    search)."""
    from parastokes import tuning
    from parastokes.integrate import stability as integrate

    ticks = [0.0]
    worst = integrate._worst_monitor

    def charged(*args, **kwargs):
        ticks[0] += 1.0
        return worst(*args, **kwargs)

    patch = pytest.MonkeyPatch()
    patch.setattr(integrate, "_worst_monitor", charged)
    try:
        run = dict(t0=0.0, t1=8e-3, n_slices=4, cores=4, target=1e-6, clock=lambda: ticks[0])
        plain = tuning.Space(schemes=("euler",), parameters=(), richardson=(0,),
                             step_fractions=(1.0,))
        tuning.tune(_tune_rod(), space=plain, budget=1e6, **run)
        alone, ticks[0] = ticks[0], 0.0
        space = tuning.Space(schemes=("euler", "ros2"), parameters=("epsilon",), reach=(1,),
                             nodes=(2, 3), richardson=(0,), step_fractions=(1.0,),
                             max_weight=20.0)
        result = tuning.tune(_tune_rod(), space=space, budget=alone + 0.5, **run)
    finally:
        patch.undo()
    return result, alone, ticks[0]


def test_tune_keeps_its_budget_inside_the_step_limit_search_of_implicit_candidates(budgeted):
    result, alone, spent = budgeted
    assert result.report["search"]["stopped"] == "budget"
    # the baseline's bisection, then the one trial run that began within the budget: the first
    # implicit candidate's run at the fine step; its bisection stopped before the next
    assert spent == alone + 1
    implicit = next(c for c in result.candidates if c.settings.scheme == "ros2")
    assert implicit.status == "not reached" and implicit.step_limit is None
    assert result.chosen is result.baseline and result.baseline.status == "accepted"


def test_tunes_counts_add_up(budgeted):
    result, _, _ = budgeted
    search, rows = result.report["search"], result.report["candidates"]
    counts = search["counts"]
    assert sum(counts.values()) == search["total"] == len(rows) == len(result.candidates)
    assert counts == {s: sum(r["status"] == s for r in rows) for s in counts}
    assert search["weighed_out"] == 2  # (the 3-node candidates: Σ|w v| = 49 > 20)
    assert search["ordered"] + search["weighed_out"] + 1 == search["total"]  # + the baseline
    line = table(result.report).splitlines()[-1]
    assert line.startswith(f"(* chosen, b baseline) {len(rows)} candidates with the baseline: ")
    assert sum(int(part.split()[0]) for part in line.split(": ")[1].split(", ")) == len(rows)


def test_a_winning_baseline_carries_the_star():
    report = {"chosen": None, "baseline": {}, "candidates": [], "problem": {"slice_length": 1e-2}}
    row = {"label": "euler", "dt": 1e-4, "dt_ratio": 100.0, "n_auxiliary": 1, "status": "accepted",
           "stability": {"spectral_radius": None}, "pilot": {"eta1": 1e-5, "contraction": 0.1},
           "predicted": {"iterations": 2, "gamma_ratio": 0.01, "speedup": 1.5}}
    other = {**row, "label": "euler, ε 2 nodes", "predicted": {**row["predicted"], "speedup": 1.2}}
    report |= {"chosen": row, "baseline": row, "candidates": [row, other]}
    lines = table(report).splitlines()
    assert lines[1].startswith("*b euler") and lines[2].startswith("   euler, ε")
    report["chosen"] = other
    lines = table(report).splitlines()
    assert lines[1].startswith(" b euler") and lines[2].startswith("*  euler, ε")


def test_the_repeated_step_limit_warning_is_held_back_and_counted(caplog):
    from parastokes.integrate import stability as integrate
    from parastokes.tuning.search import _HeldBack

    held = _HeldBack()
    integrate.log.addFilter(held)
    try:
        for _ in range(3):
            integrate.log.warning("largest_stable_step: dt_hi=%g is stable; the limit lies "
                                  "above it", 1e-3)
        integrate.log.warning("another warning")
    finally:
        integrate.log.removeFilter(held)
    assert held.count == 3
    assert [r.getMessage() for r in caplog.records] == ["another warning"]


def test_a_budget_stops_a_step_limit_bisection_between_its_trial_runs(monkeypatch):
    from parastokes.integrate import stability as integrate

    runs, asked = [], [0]
    monkeypatch.setattr(integrate, "is_stable", lambda *a, **k: runs.append(a[2]) or False)
    monkeypatch.setattr(integrate, "_worst_monitor", lambda *a, **k: 0.0)

    class Spent(Exception):
        pass

    def stop():
        asked[0] += 1
        if asked[0] > 3:
            raise Spent

    rod = _tune_rod().system
    with pytest.raises(Spent):
        integrate.largest_stable_step(rod, "ros2", 1e-3, 1e-6, 5e-4, relative=True, stop=stop)
    assert len(runs) == 2  # the physical run at dt_lo, then dt_hi and one midpoint: 3 asked


def test_tuned_toml_says_it_was_tuned_and_records_every_flag(budgeted):
    from parastokes.cli.parser import parser
    from parastokes.tuning.command import command_line
    from parastokes.tuning.report import config_text

    args = parser().parse_args([
        "tune", "rod.toml", "--cores", "4", "--target", "1e-6", "--out", "T.toml", "--budget",
        "1", "--schemes", "euler", "ros2", "--parameters", "--pilot-slices", "2", "--exhaustive",
        "--set", "fine.dt=1e-6"])
    command = command_line(args)
    assert command == ("parastokes tune rod.toml --cores 4 --target 1e-06 --budget 1 --schemes "
                       "euler ros2 --parameters --pilot-slices 2 --exhaustive --set fine.dt=1e-6")
    result, _, _ = budgeted
    config = {"title": "small rod", "parareal": {"n_slices": 2}, "execution": {}}
    text = config_text(config, result, 4, "rod.toml", command)
    import tomllib

    assert tomllib.loads(text)["title"] == "tuned from rod.toml for 4 cores, η* = 1e-06: small rod"
    assert text.startswith(f"# Tuned by `{command}`: ")


# ---- the low items -------------------------------------------------------------------------
def test_a_signal_after_the_results_are_in_place_says_they_are_complete(finished, tmp_path,  # noqa: F811
                                                                        monkeypatch, capsys):
    path, _ = finished
    out = tmp_path / "out"
    commit = rundir.RunDirectory.commit

    def then_interrupted(self):
        names = commit(self)
        signal.raise_signal(signal.SIGINT)
        return names

    monkeypatch.setattr(rundir.RunDirectory, "commit", then_interrupted)
    assert _run(path, "--out", out) == cli.ExitCode.INTERRUPTED
    err = capsys.readouterr().err
    assert (f"interrupted after the command had completed: the run's results are complete in "
            f"{out} (summary.json, trajectory.h5, trajectory.xdmf)") in err
    assert "--resume" not in err and (out / "summary.json").exists()


def test_a_refused_demo_writes_no_configuration_and_does_not_say_so(finished, tmp_path,  # noqa: F811
                                                                    capsys):
    out = shutil.copytree(finished[1], tmp_path / "out")
    assert cli.main(["demo", "--out", str(out)]) == cli.ExitCode.CONFIG
    assert "config.toml" not in capsys.readouterr().out
    assert not (out / "config.toml").exists()


def test_an_interrupted_demo_overwrite_keeps_the_edited_configuration(finished, tmp_path,  # noqa: F811
                                                                      monkeypatch):
    out = shutil.copytree(finished[1], tmp_path / "out")
    (out / "config.toml").write_text("# edited by hand\n")
    _signal_after_the_first_slice(monkeypatch, signal.SIGINT)
    assert cli.main(["demo", "--out", str(out), "--overwrite", "-q", "--set",
                     "execution.executor=serial", "--set", "execution.workers=1"]) == \
        cli.ExitCode.INTERRUPTED
    assert (out / "config.toml").read_text() == "# edited by hand\n"


def test_a_lock_names_the_command_that_holds_it(run_dir, tmp_path, capsys):  # noqa: F811
    import socket

    from parastokes.core import locks

    pid = os.getpid()
    record = {"pid": pid, "host": socket.gethostname(), "started": locks.process_start(pid),
              "time": "2026-01-01 00:00:00",
              "command": "/usr/local/bin/parastokes movie RUN --out m.gif"}
    (run_dir / rundir.LOCK).write_text(json.dumps(record))
    assert cli.main(["flow", str(run_dir), "--out", str(tmp_path / "f"), "-q"]) == 2
    err = capsys.readouterr().err
    assert f"is in use by `parastokes movie` (PID {pid} on host" in err
    record["command"] = "/x/parastokes/__main__.py tune c.toml"  # (python -m parastokes)
    assert locks.holder(record).startswith("`parastokes tune` (PID")
    record["command"] = "python -m pytest tests"
    assert locks.holder(record).startswith("another parastokes process (PID")


def test_the_movie_panels_labels_sit_beside_their_axes(scene_run):  # noqa: F811
    from matplotlib.figure import Figure

    from parastokes import flow
    from parastokes.flow.movie import _bodies_limits, draw_bodies_frame, render_frame

    run = flow.load_run(scene_run[0])
    limits = _bodies_limits(run)
    limits[0], limits[2] = (-6.0, 8.0), (4.0, 6.2)  # flat panels: a wide x range (a long rod)
    fig = Figure(figsize=(8, 6), dpi=100, layout="constrained")
    draw_bodies_frame(fig, run, 2, limits)
    render_frame(fig)
    renderer = fig.canvas.get_renderer()
    for ax in fig.axes:
        box, label = ax.get_window_extent(), ax.yaxis.label.get_window_extent(renderer)
        ticks = max(t.get_window_extent(renderer).width for t in ax.get_yticklabels())
        assert box.y0 <= label.y0 and label.y1 <= box.y1  # not hanging above or below it
        assert 0 < box.x0 - label.x1 <= ticks + 20  # just left of its tick labels
