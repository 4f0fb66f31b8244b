"""The ``parastokes`` command: run, demo, check, predict, plot, resume, exit codes."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from configs import small_rod

from parastokes import cli, config, parareal
from parastokes import run as runner
from parastokes.cli import console as console_module
from parastokes.output import trajectory as io
from parastokes.parallel import TaskError

ROOT = Path(__file__).resolve().parents[1]
FIXED_KEYS = {
    "config",
    "iterations",
    "increments",
    "errors",
    "timings",
    "speedup",
    "final_positions",
}
FIGURES = ("error_decay", "speedup_vs_error", "speedup_by_iteration", "structure")

# A small rod problem run in-process (serial executor): a few seconds.
TINY = 'title = "tiny rod"\n' + small_rod(
    parareal="max_iterations = 3",
    rest='[execution]\nexecutor = "serial"\n[output]\nformats = ["png"]\n',
)


def relative(x: np.ndarray, base: np.ndarray) -> float:
    """Eq. 34, written out independently of parastokes.parareal.metrics."""
    return float(np.max(np.linalg.norm(x - base, axis=1) / np.linalg.norm(base, axis=1)))


@pytest.fixture(scope="module")
def tiny_runs(tmp_path_factory):
    """Two runs of TINY (4 and 2 slices), serial + Parareal."""
    root = tmp_path_factory.mktemp("tiny")
    path = root / "tiny.toml"
    path.write_text(TINY)
    outs = []
    for n in (4, 2):
        out = root / f"n{n}"
        assert (
            cli.main(["run", str(path), "--out", str(out), "-q", "--set", f"parareal.n_slices={n}"])
            == 0
        )
        outs.append(out)
    return path, outs


def test_run_both_reports_errors_that_match_the_saved_states(tiny_runs):
    _, (out, _) = tiny_runs
    summary = io.read_summary(out / "summary.json")
    assert FIXED_KEYS <= set(summary)
    assert summary["iterations"] == 3
    with h5py.File(out / "trajectory.h5", "r") as f:
        serial_final = f["serial/rod_0/positions"][-1]
        parareal_final = f["parareal/rod_0/positions"][-1]
        finals = f["parareal_history/final_positions"][()]
        saved_errors = f["parareal_history/errors"][()]
        saved_increments = f["parareal_history/increments"][()]
    errors = [relative(x, serial_final) for x in finals]
    np.testing.assert_allclose(summary["errors"], errors, rtol=1e-12)
    np.testing.assert_allclose(saved_errors, errors, rtol=1e-12)
    increments = [relative(finals[k - 1], finals[k]) for k in (1, 2)]  # eta~^2, eta~^3
    np.testing.assert_allclose(summary["increments"][1:], increments, rtol=1e-12)
    np.testing.assert_array_equal(saved_increments, summary["increments"])
    np.testing.assert_array_equal(np.asarray(summary["final_positions"]), parareal_final)
    np.testing.assert_array_equal(finals[-1], parareal_final)
    assert summary["errors"][-1] < summary["errors"][0]  # Parareal converges to F


def test_run_reports_the_speedup_model(tiny_runs):
    _, (out, _) = tiny_runs
    summary = io.read_summary(out / "summary.json")
    s = summary["speedup"]
    assert s["serial_time_estimated"] is False
    assert s["serial_time"] == summary["timings"]["serial_fine"] > 0
    assert s["measured"] == pytest.approx(s["serial_time"] / summary["timings"]["total"])
    assert s["theoretical"] == pytest.approx(parareal.speedup(s["gamma_G"], s["gamma_F"], 3, 4))
    assert s["bound"] == pytest.approx(parareal.speedup_bound(s["gamma_ratio"], 3, 4))
    assert s["by_iteration"]["iterations"] == [1, 2, 3]
    assert summary["config"]["resolved"]["n_auxiliary"] == 4
    assert summary["monitor"]["max"] < summary["monitor"]["limit"]


def test_plot_redraws_and_compares_runs(tiny_runs, tmp_path):
    _, (first, second) = tiny_runs
    for name in FIGURES:
        (first / f"{name}.png").unlink()
    assert cli.main(["plot", str(first), "--formats", "png", "-q"]) == 0
    assert all((first / f"{name}.png").exists() for name in FIGURES)
    assert cli.main(["plot", str(first), str(second), "--out", str(tmp_path), "-q"]) == 0
    for name in ("error_decay", "speedup_vs_error", "speedup_by_iteration", "scaling"):
        assert (tmp_path / f"{name}.png").exists() and (tmp_path / f"{name}.pdf").exists()


def check_demo_output(out: Path, n_frames: int) -> dict:
    summary = io.read_summary(out / "summary.json")
    assert FIXED_KEYS <= set(summary)
    assert {"measured", "theoretical", "bound"} <= set(summary["speedup"])
    assert np.asarray(summary["final_positions"]).shape == (61, 3)
    assert len(summary["errors"]) == summary["iterations"] == len(summary["increments"])
    with h5py.File(out / "trajectory.h5", "r") as f:
        for run in ("serial", "parareal"):
            assert f[f"{run}/rod_0/positions"].shape == (n_frames, 61, 3)
            assert f[f"{run}/time"][-1] == pytest.approx(summary["final_time"])
        history = f["parareal_history"]
        np.testing.assert_array_equal(history["increments"][()], summary["increments"])
        np.testing.assert_array_equal(f["parareal/rod_0/positions"][-1], summary["final_positions"])
        assert f.attrs["execution.workers"] == 2
    assert (out / "trajectory.xdmf").read_text().count("trajectory.h5:/") > 0
    for name in FIGURES:
        for fmt in ("png", "pdf"):
            assert (out / f"{name}.{fmt}").stat().st_size > 1000
    cfg, _ = config.load(out / "config.toml")
    assert cfg.model.n_points == 61
    saved = {k: v for k, v in summary["config"].items() if k != "resolved"}
    assert cfg.model_dump(mode="json") == saved  # the file reproduces the run, --set included
    return summary


def test_demo_writes_summary_trajectory_and_figures(tmp_path, capsys):
    """The demo as shipped, over a shorter time (same code paths, 2 process workers)."""
    out = tmp_path / "demo"
    status = cli.main(
        ["demo", "--out", str(out), "--set", "time.t1=0.004", "--set", "parareal.tol=0"]
    )
    assert status == 0
    printed = capsys.readouterr().out
    assert "increment η̃^k" in printed and "theoretical" in printed  # table and speedup report
    summary = check_demo_output(out, n_frames=3)
    assert summary["workers"] == 2
    assert summary["iterations"] == 2
    assert summary["errors"][-1] == 0.0  # k = N: Parareal equals the serial fine solution
    # a resume of another configuration is refused and leaves the demo's config.toml as it was
    # (regression: the new file was written before the check)
    written = (out / "config.toml").read_text()
    status = cli.main(["demo", "--out", str(out), "--resume", "-q", "--set", "time.t1=0.004",
                       "--set", "coarse.dt_ratio=8"])
    assert status == cli.ExitCode.CONFIG
    assert (out / "config.toml").read_text() == written


@pytest.mark.slow
def test_full_demo(tmp_path):
    out = tmp_path / "demo"
    assert cli.main(["demo", "--out", str(out), "-q"]) == 0
    summary = check_demo_output(out, n_frames=3)
    # one iteration reaches the tolerance, with a speedup > 1 possible on two cores (eq. 14)
    assert summary["iterations"] == 1
    assert summary["errors"][-1] < 1e-4
    assert summary["speedup"]["theoretical"] > 1.5


RESUMABLE = TINY.replace("n_points = 21\nlength = 4.0", "n_points = 41\nlength = 8.0").replace(
    "t1 = 0.002", "t1 = 0.004"
)


def test_interrupted_run_resumes_from_its_checkpoint(tmp_path, capsys):
    path = tmp_path / "run.toml"
    path.write_text(RESUMABLE)
    out = tmp_path / "out"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    command = [sys.executable, "-m", "parastokes", "run", str(path), "--out", str(out), "-q"]
    # SIGINT at its default in the child, even when this suite runs with it ignored (a background
    # job of a shell without job control), so that Python installs its KeyboardInterrupt handler
    process = subprocess.Popen(command, env=env, stderr=subprocess.PIPE, text=True,
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 300
    while not (out / runner.HISTORY).exists() and process.poll() is None:
        assert time.monotonic() < deadline
        time.sleep(0.02)
    process.send_signal(signal.SIGINT)
    _, stderr = process.communicate(timeout=300)
    assert process.returncode == cli.ExitCode.INTERRUPTED, stderr
    assert "--resume" in stderr
    assert (out / runner.CHECKPOINT).exists() and not (out / "summary.json").exists()
    _, history = io.load_arrays(out / runner.HISTORY)
    done = len(history["elapsed"])  # the iterations checkpointed before the interrupt
    assert done >= 1

    capsys.readouterr()
    assert cli.main(["run", str(path), "--out", str(out), "--resume"]) == 0
    printed = capsys.readouterr().out
    # the resume computed neither the serial solution nor the iterations it had checkpointed
    assert "serial fine solution reloaded from reference.npz" in printed
    rows = [int(line.split()[0]) for line in printed.splitlines()
            if line.split() and line.split()[0].isdigit() and len(line.split()) == 4]
    assert rows == list(range(done + 1, 4))
    resumed = io.read_summary(out / "summary.json")
    assert cli.main(["run", str(path), "--out", str(tmp_path / "again"), "-q"]) == 0
    fresh = io.read_summary(tmp_path / "again" / "summary.json")
    assert resumed["iterations"] == fresh["iterations"] == 3
    assert resumed["final_positions"] == fresh["final_positions"]  # bit for bit
    assert resumed["errors"] == fresh["errors"]
    assert resumed["increments"] == fresh["increments"]


def test_resume_refuses_another_configuration(tiny_runs, capsys):
    path, (out, _) = tiny_runs
    status = cli.main(
        ["run", str(path), "--out", str(out), "--resume", "--set", "coarse.dt_ratio=5"]
    )
    assert status == cli.ExitCode.CONFIG
    assert "coarse.dt_ratio" in capsys.readouterr().err  # the differing key is named

def test_bad_configuration_exits_2_naming_the_key(tmp_path, capsys):
    path = tmp_path / "bad.toml"
    path.write_text(TINY.replace("n_slices = 4", "n_slices = 4\ntoll = 1e-8"))
    assert cli.main(["run", str(path), "--out", str(tmp_path / "o")]) == cli.ExitCode.CONFIG
    assert "parareal.toll: unknown key (did you mean 'tol'?)" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()  # nothing ran
    good = tmp_path / "good.toml"
    good.write_text(TINY)
    assert cli.main(["check", str(good)]) == 0
    assert cli.main(["check", str(good), str(path)]) == cli.ExitCode.CONFIG


def test_blow_up_exits_3(tmp_path, capsys):
    path = tmp_path / "blow.toml"
    text = TINY.replace("dt = 1e-6", 'dt = 5e-4\nscheme = "euler"').replace(
        "t1 = 0.002", "t1 = 0.01"
    )
    path.write_text(text.replace("dt_ratio = 10", "dt_ratio = 1") + '[run]\nmode = "serial"\n')
    out = tmp_path / "o"
    assert cli.main(["run", str(path), "--out", str(out)]) == cli.ExitCode.BLOWUP
    err = capsys.readouterr().err
    assert "blow-up at t=" in err
    assert "the fine solver F (euler) in slice 1 of the serial fine run blew up" in err
    assert "reduce fine.dt (now 0.0005)" in err and str(out / runner.BLOWUP) in err
    meta, arrays = io.load_arrays(out / runner.BLOWUP)
    assert meta["step"] >= 0 and np.isfinite(arrays["last_state"]).all()


@pytest.mark.parametrize(
    ("error", "code"),
    [
        (TaskError("fine solve of slice 2 in iteration 1", RuntimeError("boom")), 4),
        (KeyboardInterrupt(), 130),
        (ZeroDivisionError(), 1),
    ],
)
def test_failures_map_to_documented_exit_codes(tiny_runs, tmp_path, monkeypatch, error, code):
    def fail(*args, **kwargs):
        raise error

    monkeypatch.setattr(runner, "execute", fail)
    path, _ = tiny_runs
    assert cli.main(["run", str(path), "--out", str(tmp_path), "-q"]) == code


def table_rows(text: str) -> list[list[str]]:
    """The rows of predict's table (the lines after its header, which starts with N_c)."""
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if line.split()[:1] == ["N_c"]) + 1
    return [line.split() for line in lines[start:] if line.split()[0].isdigit()]


def test_predict_prints_eq_14_for_each_core_count(tiny_runs, capsys):
    path, (out, _) = tiny_runs
    assert (
        cli.main(
            ["predict", str(path), "--cores", "4", "40", "--ratio", "0.05", "--iterations", "2"]
        )
        == 0
    )
    rows = table_rows(capsys.readouterr().out)
    for (n, theory, bound), row in zip(parareal.predict(0.05, 2, [4, 40]), rows, strict=True):
        assert [int(row[0]), float(row[3]), float(row[4])] == [n, round(theory, 3), round(bound, 3)]
    assert cli.main(["predict", str(path), "--cores", "8", "--measured", str(out)]) == 0
    # the run's γ_G is a whole coarse step: N_G auxiliary solves in ceil(N_G / W) rounds on its
    # W workers; predict takes one auxiliary solve from it (regression: it took the whole step
    # for one, and counted the rounds again)
    summary = io.read_summary(out / "summary.json")
    n_aux, workers = summary["config"]["resolved"]["n_auxiliary"], summary["workers"] or 1
    one = summary["speedup"]["gamma_ratio"] / math.ceil(n_aux / workers)
    text = capsys.readouterr().out
    assert f"one auxiliary solve: {one:.4g}; N_G = {n_aux}" in text
    alpha = float(table_rows(text)[0][2])
    assert alpha == pytest.approx(math.ceil(n_aux / 8) * one, abs=1e-4)
    assert cli.main(["predict", str(path), "--cores", "8"]) == 0
    assert "estimated" in capsys.readouterr().out


def test_usage_errors_exit_2(tiny_runs, capsys):
    with pytest.raises(SystemExit) as info:
        cli.main(["run"])
    assert info.value.code == 2
    path, _ = tiny_runs
    assert cli.main(["predict", str(path), "--cores", "0"]) == cli.ExitCode.CONFIG
    assert "--cores must be at least 1" in capsys.readouterr().err


def test_help_documents_every_exit_code(capsys):
    with pytest.raises(SystemExit):
        cli.main(["--help"])
    text = " ".join(capsys.readouterr().out.split())
    for code in cli.ExitCode:
        assert f"{int(code)} " in text
    assert "143 terminated (SIGTERM)" in text


def test_demo_configuration_file_keeps_the_overrides():
    overrides = [
        "parareal.n_slices=4",
        "coarse.lagrange.epsilon.nodes=[5.5, 5.6]",
        "fine.scheme=rk4",  # a bare word: a string
    ]
    written, _ = config.loads(cli.demo_text(overrides))
    expected, _ = config.loads(config.DEMO, overrides=overrides)
    assert written == expected
    assert cli.demo_text([]) == config.DEMO  # without --set: the annotated file


def test_progress_moves_inside_a_slice_by_the_expected_time(monkeypatch, capsys):
    clock = iter([100.0, 130.0, 190.0])  # start, end of slice 1, end of slice 2
    monkeypatch.setattr(console_module.time, "monotonic", lambda: next(clock))
    console = cli.Console(quiet=False)
    console.start("serial", 4)
    assert console.progress(150.0) == 0.0  # no estimate yet: whole slices only
    console.expect(100.0)  # the estimate of one slice, before any is timed
    assert console.progress(125.0) == pytest.approx(0.25)
    assert console.progress(1e6) == pytest.approx(0.99)  # never a slice that is not done
    console.advance()  # slice 1 took 30 s: the mean replaces the estimate
    assert console.progress(145.0) == pytest.approx(1.5)
    console.advance()  # slices took 30 and 60 s: 45 s each on average
    assert console.progress(190.0 + 9.0) == pytest.approx(2.2)
    console.finish()
    assert "serial fine run over 4 slices" in capsys.readouterr().out


def test_predict_against_the_fastest_serial_run_of_the_same_accuracy(tiny_runs, tmp_path, capsys):
    path, (out, _) = tiny_runs
    runs = {"cases": {"tiny": {
        "t1": 0.002, "reference": {"scheme": "rk2", "dt": 1e-6, "cpu": 10.0},
        "rows": [{"scheme": "rk2", "dt": 4e-6, "error": 1e-7, "cpu": 2.5, "fine_cpu": 10.0},
                 {"scheme": "euler", "dt": 2e-6, "error": 1e-4, "cpu": 1.0, "fine_cpu": 10.0}]}}}
    runs["cases"]["tiny"]["problem"] = config.problem_key(config.load(path)[0])
    serial = tmp_path / "serial.json"
    serial.write_text(json.dumps(runs))
    base = ["predict", str(path), "--cores", "4", "--ratio", "0.05", "--iterations", "2",
            "--serial", str(serial)]

    def last_row(target: str) -> tuple[str, float, float]:
        assert cli.main([*base, "--target", target]) == 0
        text = capsys.readouterr().out
        row = text.splitlines()[-1].split()
        return text, float(row[3]), float(row[-1])

    text, speedup, against = last_row("1e-6")  # RK2 at 4x the step reaches it at 4x less CPU
    assert "rk2 at dt = 4e-06 (error 1e-07), 4x less CPU than F" in text
    assert against == pytest.approx(speedup / 4, abs=1e-3)
    text, speedup, against = last_row("1e-3")  # Euler reaches a loose target at 10x less
    assert "euler at dt = 2e-06" in text and against == pytest.approx(speedup / 10, abs=1e-3)
    text, speedup, against = last_row("1e-9")  # no faster run reaches it: F itself
    assert "F itself" in text and against == speedup
    # the default target is the measured run's last error η^K
    assert cli.main(["predict", str(path), "--cores", "4", "--serial", str(serial),
                     "--measured", str(out)]) == 0
    eta = io.read_summary(out / "summary.json")["errors"][-1]
    assert f"reaching η* = {eta:.3g}" in capsys.readouterr().out
    # a configuration of another F is refused: its speedups are against another solver
    assert cli.main([*base, "--target", "1e-6", "--set", "fine.dt=2e-6"]) == cli.ExitCode.CONFIG
    assert "measured against F = rk2 at dt = 1e-06 over T = 0.002" in capsys.readouterr().err
    assert cli.main(["predict", str(path), "--cores", "4", "--case", "tiny"]) == 2
    assert "--case goes with --serial" in capsys.readouterr().err
