"""A coarse-solver family of a user's own (tests/coarse_family.py, no edit to the package):
found by ``[coarse] kind = "module:Class"``, checked, run with Parareal and used by ``predict``;
and the built-in family is still the default of a ``[coarse]`` table without ``kind``."""

from __future__ import annotations

import numpy as np
import pytest

from parastokes import cli, config
from parastokes.coarse.extrapolated import Extrapolated
from parastokes.output import trajectory as io
from parastokes.registry import coarse as registry

# A 21-node rod, 4 slices; G: one forward-Euler solver at Θ⁰ with τ_c = 5 τ_f (tests/coarse_family).
PLAIN = """
title = "tiny rod, a plain coarse solver of a user's family"
[model]
kind = "rod"
n_points = 21
length = 4.0
[time]
t1 = 0.002
[fine]
dt = 1e-6
[coarse]
kind = "tests.coarse_family:Plain"
dt_ratio = 5
[parareal]
n_slices = 4
max_iterations = 4
[execution]
executor = "serial"
[output]
figures = false
"""


def test_a_coarse_section_without_kind_is_the_extrapolated_family():
    cfg, resolved = config.loads(PLAIN.replace('kind = "tests.coarse_family:Plain"\n', ""))
    assert type(cfg.coarse) is Extrapolated and cfg.coarse.kind == "extrapolated"
    assert resolved.coarse_steps == [100] and resolved.n_auxiliary == 1
    assert registry.get("extrapolated") is Extrapolated


def test_the_users_family_is_found_and_resolved(tmp_path, capsys):
    path = tmp_path / "plain.toml"
    path.write_text(PLAIN)
    assert cli.main(["check", str(path)]) == 0
    assert "τ_c = 5e-06 (5 τ_f), N_G = 1" in capsys.readouterr().out
    cfg, resolved = config.load(path)
    assert type(cfg.coarse).__name__ == "Plain"
    assert resolved.coarse_dt == resolved.coarse_base_dt == pytest.approx(5e-6)
    assert resolved.coarse_steps == [100] and resolved.coarse_points == 21
    assert cli.estimated_gamma_ratio(cfg, resolved, 4) == pytest.approx(0.2)


def test_the_users_family_reports_bad_keys_by_their_coarse_path(tmp_path):
    with pytest.raises(config.ConfigError) as caught:
        config.loads(PLAIN, overrides=["coarse.dt_ratoi=3"])
    assert "coarse.dt_ratoi: unknown key (did you mean 'dt_ratio'?)" in str(caught.value)
    with pytest.raises(config.ConfigError) as caught:
        config.loads(PLAIN, overrides=["coarse.dt_ratio=1000"])  # its own rule, in resolve
    assert caught.value.paths == ["coarse.dt_ratio"]
    with pytest.raises(config.ConfigError) as caught:
        config.loads(PLAIN, overrides=['coarse.kind="tests.coarse_family:Nothing"'])
    assert caught.value.paths == ["coarse.kind"]


def test_parareal_with_the_users_family_reaches_the_fine_solution(tmp_path):
    """Parareal is exact after N_c iterations whatever G is (Algorithm 1): with the user's plain
    G the error decreases and the 4th iterate equals the serial fine solution to round-off."""
    path = tmp_path / "plain.toml"
    path.write_text(PLAIN)
    out = tmp_path / "run"
    assert cli.main(["run", str(path), "--out", str(out), "-q"]) == 0
    summary = io.read_summary(out / "summary.json")
    assert summary["config"]["coarse"] == {"kind": "tests.coarse_family:Plain",
                                           "scheme": "euler", "dt_ratio": 5.0}
    errors = np.asarray(summary["errors"])
    assert len(errors) == 4
    assert errors[0] > 1e-11 and np.all(np.diff(errors) < 0)  # measured: 2.6e-10 ... 0
    assert errors[-1] < 1e-14
