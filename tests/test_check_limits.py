"""`check` (and every run) refuses what cannot work and notes what will not end or will crawl:
nearly coinciding Lagrange nodes, absurd step counts, more workers x threads than cores."""

from __future__ import annotations

import numpy as np
import pytest
from configs import small_rod

from parastokes import cli, config
from parastokes.config import checks
from parastokes.parareal import lagrange_weights, step_weights

BASE = small_rod(rest='[execution]\nexecutor = "processes"\nworkers = 4\n')


def _check(tmp_path, capsys, *overrides: str) -> tuple[int, str]:
    path = tmp_path / "c.toml"
    path.write_text(BASE)
    status = cli.main(["check", str(path), *(f"--set={item}" for item in overrides)])
    captured = capsys.readouterr()
    return status, captured.out + captured.err


def test_nearly_coinciding_nodes_are_refused_with_their_weight_sum(tmp_path, capsys):
    close = "coarse.lagrange.epsilon.nodes=[5.6, 5.6000001]"
    status, text = _check(tmp_path, capsys, close, "coarse.richardson.m=0")
    assert status == cli.ExitCode.CONFIG
    expected = np.abs(lagrange_weights(5.0, [5.6, 5.6000001])).sum()  # in units of σ_f
    assert f"Σ|w_j v_q| = {expected:.3g}" in text and "coarse.max_weight_sum" in text
    status, text = _check(tmp_path, capsys, close, "coarse.richardson.m=0",
                          "coarse.max_weight_sum=1e8")
    assert status == 0 and f"Σ|w| = {expected:.3g}" in text  # forced: reported


def test_the_weight_sum_counts_lagrange_and_richardson(tmp_path):
    _, resolved = config.loads(BASE)
    lagrange = np.abs(lagrange_weights(5.0, [5.6, 5.65])).sum()  # 25
    steps = [resolved.slice_length / n for n in resolved.coarse_steps]
    richardson = np.abs(step_weights(steps, 1)).sum()
    assert resolved.weight_sum == pytest.approx(lagrange * richardson, rel=1e-12)
    assert lagrange == pytest.approx(25.0)


def test_absurd_step_counts_are_refused_and_long_runs_estimated(tmp_path, capsys):
    status, text = _check(tmp_path, capsys, "time.t1=1e22")
    assert status == cli.ExitCode.CONFIG
    assert "fine.dt: 1e+28 fine steps" in text and "years on one core" in text
    status, text = _check(tmp_path, capsys, "time.t1=10000.0")
    assert status == 0
    seconds = checks.estimated_fine_seconds("rk2", 1e10, 21)
    assert seconds > checks.LONG_RUN_SECONDS
    days = f"{seconds / 86400:.3g} days"
    assert f"note: fine.dt: 1e+10 fine steps; the serial fine solution would take about {days}" in (
        text
    )


def test_more_workers_than_cores_gets_a_note_with_what_to_pass(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(checks, "available_cores", lambda: 2)
    status, text = _check(tmp_path, capsys, "execution.workers=40")
    assert status == 0
    assert "40 worker(s) x 1 thread(s) on 2 cores" in text
    assert "--set execution.workers=2" in text
    status, text = _check(tmp_path, capsys, "execution.workers=4", "execution.threads=2")
    assert "--set execution.workers=1 (or execution.threads=1)" in text
    allowed = "execution.allow_oversubscribe=true"
    status, text = _check(tmp_path, capsys, "execution.workers=2", allowed)
    assert status == 0 and "on 2 cores" not in text  # as many workers as cores: no note
