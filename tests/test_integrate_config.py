"""The adaptive schemes in configs: `check` refuses in one line (exit 2) what cannot work."""

from __future__ import annotations

import numpy as np
import pytest
from configs import small_rod
from test_config import VESICLE

from parastokes import cli, config, integrate
from parastokes.config import ConfigError
from parastokes.output import trajectory as io
from parastokes.run.serial import adaptive_summary


def _issues(*overrides: str) -> dict[str, str]:
    with pytest.raises(ConfigError) as info:
        config.loads(VESICLE, overrides=overrides)
    return dict(info.value.issues)


@pytest.mark.parametrize("section", ["fine", "coarse"])
@pytest.mark.parametrize("pair", ["rk23", "rk45", "auto"])
def test_a_pair_with_a_fixed_step_is_refused_and_with_rtol_accepted(section, pair):
    assert _issues(f'{section}.scheme="{pair}"')[f"{section}.rtol"] == (
        f"required by the scheme '{pair}' (adaptive steps); give rtol, or a fixed-step "
        "scheme such as rk4")
    cfg, _ = config.loads(VESICLE, overrides=[f'{section}.scheme="{pair}"', f"{section}.rtol=1e-4"])
    assert getattr(cfg, section).scheme == pair


def test_check_exits_2_in_one_line(tmp_path, capsys):
    path = tmp_path / "pair.toml"
    path.write_text(VESICLE.replace("dt = 0.01", 'dt = 0.01\nscheme = "rk45"'))
    assert cli.main(["check", str(path)]) == cli.ExitCode.CONFIG
    err = capsys.readouterr().err
    assert "fine.rtol: required by the scheme 'rk45'" in err


def test_the_summary_of_adaptive_fine_solves_adds_their_steps_and_keeps_the_switches():
    a = integrate.RunResult(np.zeros(1), 0.0, 10, 1e-3, n_rejected=2,
                            switches=((0.1, "ros2", "stiff"),),
                            by_scheme=(("rk45", 4, 2), ("ros2", 6, 0)))
    b = integrate.RunResult(np.zeros(1), 0.0, 5, 1e-3, n_rejected=1,
                            switches=((0.3, "ros2", "stiff"), (0.4, "rk45", "not stiff")),
                            by_scheme=(("rk45", 3, 1), ("ros2", 2, 0)))
    assert adaptive_summary([a, b]) == {
        "accepted": 15, "rejected": 3,
        "by_scheme": {"rk45": {"accepted": 7, "rejected": 3},
                      "ros2": {"accepted": 8, "rejected": 0}},
        "switches": [{"t": 0.1, "scheme": "ros2", "reason": "stiff"},
                     {"t": 0.3, "scheme": "ros2", "reason": "stiff"},
                     {"t": 0.4, "scheme": "rk45", "reason": "not stiff"}]}


@pytest.mark.slow
def test_the_summary_of_a_serial_run_reports_the_adaptive_steps(tmp_path):
    """summary.json's fine_steps: the steps of the serial fine run of "auto" by scheme."""
    path = tmp_path / "auto.toml"
    path.write_text(small_rod(rest='[run]\nmode = "serial"\n[output]\ntrajectory = false\n')
                    .replace("dt = 1e-6", 'dt = 1e-6\nscheme = "auto"\nrtol = 1e-3')
                    .replace("richardson = { m = 1, r = 0.83 }", ""))
    assert cli.main(["run", str(path), "--out", str(tmp_path / "out")]) == 0
    steps = io.read_summary(tmp_path / "out" / "summary.json")["fine_steps"]
    by = steps["by_scheme"]
    assert set(by) == {integrate.auto.EXPLICIT, integrate.auto.implicit_scheme(1e-3)}
    assert steps["accepted"] == sum(v["accepted"] for v in by.values()) > 0
    assert steps["rejected"] == sum(v["rejected"] for v in by.values())
