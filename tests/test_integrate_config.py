"""The adaptive schemes in configs: `check` refuses in one line (exit 2) what cannot work."""

from __future__ import annotations

import pytest
from test_config import VESICLE

from parastokes import cli, config
from parastokes.config import ConfigError


def _issues(*overrides: str) -> dict[str, str]:
    with pytest.raises(ConfigError) as info:
        config.loads(VESICLE, overrides=overrides)
    return dict(info.value.issues)


@pytest.mark.parametrize("section", ["fine", "coarse"])
@pytest.mark.parametrize("pair", ["rk23", "rk45"])
def test_a_pair_with_a_fixed_step_is_refused_and_with_rtol_accepted(section, pair):
    assert _issues(f'{section}.scheme="{pair}"')[f"{section}.rtol"] == (
        f"required by the embedded pair '{pair}' (adaptive steps); give rtol, or a fixed-step "
        "scheme such as rk4")
    cfg, _ = config.loads(VESICLE, overrides=[f'{section}.scheme="{pair}"', f"{section}.rtol=1e-4"])
    assert getattr(cfg, section).scheme == pair


def test_check_exits_2_in_one_line(tmp_path, capsys):
    path = tmp_path / "pair.toml"
    path.write_text(VESICLE.replace("dt = 0.01", 'dt = 0.01\nscheme = "rk45"'))
    assert cli.main(["check", str(path)]) == cli.ExitCode.CONFIG
    err = capsys.readouterr().err
    assert "fine.rtol: required by the embedded pair 'rk45'" in err
