"""The body registry: built-in kinds, "module:Class" kinds, installed kinds (entry points), and the
clear error for a kind that is none of these."""

from __future__ import annotations

import itertools
import textwrap

import numpy as np
import pytest

from parastokes import config
from parastokes.config import ConfigError
from parastokes.registry import kinds as registry

USER = """\
[model]
kind = "user_body:SedimentingCloud"
n_points = 12
{extra}

[time]
t1 = 0.2

[fine]
dt = 0.01

[coarse]
dt = 0.05
lagrange = {{ epsilon = [0.12, 0.13] }}

[parareal]
n_slices = 2

[execution]
executor = "serial"
allow_oversubscribe = true
"""


def test_unknown_kind_lists_the_registered_kinds():
    with pytest.raises(ConfigError) as info:
        config.loads(USER.format(extra="").replace("user_body:SedimentingCloud", "sphere"))
    message = dict(info.value.issues)["model.kind"]
    assert "unknown body kind 'sphere'" in message
    assert "rod" in message and "vesicle" in message and "package.module:ClassName" in message


@pytest.mark.parametrize(
    ("kind", "fragment"),
    [("no_such_module:X", "cannot import module"), ("user_body:Missing", "has no attribute")],
)
def test_bad_module_kinds_name_the_problem(kind, fragment):
    with pytest.raises(ConfigError, match=fragment):
        config.loads(USER.format(extra="").replace("user_body:SedimentingCloud", kind))


def test_a_dataclass_system_is_a_kind_with_its_fields_as_keys():
    cfg, resolved = config.loads(USER.format(extra="weight = 2.0"))
    assert cfg.model.kind == "user_body:SedimentingCloud"
    assert resolved.theta0 == {"epsilon": 0.1, "viscosity": 1.0}
    assert resolved.n_points == 12
    assert resolved.lagrange == {"epsilon": [0.12, 0.13]}
    system = config.build_system(cfg, resolved)
    assert (type(system).__name__, system.weight, system.n_points) == ("SedimentingCloud", 2.0, 12)
    # the section has the class's keys: a typo is named, with a hint
    with pytest.raises(ConfigError) as info:
        config.loads(USER.format(extra="wieght = 2.0"))
    assert "did you mean 'weight'" in dict(info.value.issues)["model.wieght"]
    # and the class's types, strictly
    with pytest.raises(ConfigError, match=r"model\.n_points"):
        config.loads(USER.format(extra="").replace("n_points = 12", 'n_points = "12"'))


def test_unknown_parameters_of_a_user_kind_are_named():
    text = USER.format(extra="").replace("epsilon = [0.12, 0.13]", "weight = [1.1, 1.2]")
    with pytest.raises(ConfigError) as info:
        config.loads(text)
    assert "epsilon, viscosity" in dict(info.value.issues)["coarse.lagrange.weight"]


def test_installed_packages_register_kinds_through_entry_points(tmp_path, monkeypatch):
    package = tmp_path / "site"
    (package / "cloudpkg").mkdir(parents=True)
    (package / "cloudpkg" / "__init__.py").write_text("from user_body import SedimentingCloud\n")
    info = package / "cloudpkg-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: cloudpkg\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text(
        textwrap.dedent(
            """\
            [parastokes.bodies]
            cloud = cloudpkg:SedimentingCloud
            """
        )
    )
    monkeypatch.syspath_prepend(str(package))
    registry._get.cache_clear()
    try:
        assert "cloud" in registry.kinds()
        cfg, resolved = config.loads(USER.format(extra="").replace("user_body:SedimentingCloud",
                                                                   "cloud"))
        assert type(config.build_system(cfg, resolved)).__name__ == "SedimentingCloud"
    finally:
        registry._get.cache_clear()


def test_layouts_of_the_builtin_kinds_cover_the_state():
    for text in (config.DEMO, config.DEMO.replace(
            'kind = "rod"', 'kind = "rod"\nn_rods = 3')):
        cfg, resolved = config.loads(text)
        system = config.build_system(cfg, resolved)
        kind = registry.get(cfg.model.kind)
        layout = kind.layout(cfg.model, system, True, None)
        rows = sorted((body.first, body.first + body.rows) for body in layout)
        assert rows[0][0] == 0 and rows[-1][1] == len(system.initial_state())
        assert all(a[1] == b[0] for a, b in itertools.pairwise(rows))
        assert all(np.max(body.cells) < body.rows for body in layout)


def _module(tmp_path, monkeypatch, name: str, text: str) -> None:
    """A user module ``name`` on the path, with ``text`` as its source."""
    (tmp_path / f"{name}.py").write_text(textwrap.dedent(text))
    monkeypatch.syspath_prepend(str(tmp_path))


def test_a_body_kind_found_under_another_string_takes_that_string(tmp_path, monkeypatch):
    """A class's ``body_kind`` and a built-in's full path: the config's kind is the string
    written, and the run's layout is found under it (regression: both were refused, the section
    expecting the BodyKind's own name)."""
    _module(tmp_path, monkeypatch, "attached", """\
        from user_body import SedimentingCloud
        from parastokes.registry.kinds import derived_kind

        class Attached(SedimentingCloud):
            pass

        Attached.body_kind = derived_kind(SedimentingCloud, "attached:CLOUD")
        """)
    cfg, resolved = config.loads(USER.format(extra="").replace("user_body:SedimentingCloud",
                                                               "attached:Attached"))
    assert cfg.model.kind == "attached:Attached"
    system = config.build_system(cfg, resolved)
    (layout,) = cfg.model.layout(system, False, None)
    assert layout.rows == 12
    full = registry.get("parastokes.kinds.chain:KIND")
    section = full.section.model_validate({"kind": "parastokes.kinds.chain:KIND", "n_beads": 5})
    assert section.resolve().n_points == registry.get("chain").section.model_validate(
        {"kind": "chain", "n_beads": 5}).resolve().n_points == 5


@pytest.mark.parametrize(
    ("kind", "fragment"),
    [(":Foo", "package.module:Name"), (".x:Foo", "package.module:Name"),
     ("user_body:", "package.module:Name"), (["rod"], "non-empty string"),
     ("broken_module:X", "SyntaxError")],
)
def test_malformed_kinds_are_config_errors(tmp_path, monkeypatch, kind, fragment):
    # regression: these escaped as ValueError, TypeError or SyntaxError tracebacks
    _module(tmp_path, monkeypatch, "broken_module", "def f(:\n")
    text = USER.format(extra="").replace('"user_body:SedimentingCloud"', "KIND")
    text = text.replace("KIND", f'"{kind}"' if isinstance(kind, str) else '["rod"]')
    with pytest.raises(ConfigError) as info:
        config.loads(text)
    assert fragment in dict(info.value.issues)["model.kind"]


def test_derived_sections_keep_defaults_lengths_and_name_what_they_cannot_take(
        tmp_path, monkeypatch):
    _module(tmp_path, monkeypatch, "fielded", """\
        from __future__ import annotations

        import dataclasses
        from typing import TYPE_CHECKING

        from user_body import SedimentingCloud

        if TYPE_CHECKING:
            from decimal import Decimal

        @dataclasses.dataclass(frozen=True)
        class Tagged(SedimentingCloud):
            centre: tuple[float, float, float] = (0.0, 0.0, 0.0)
            tags: tuple[str, ...] = dataclasses.field(default_factory=lambda: ("a", "b"))

        @dataclasses.dataclass(frozen=True)
        class Unresolved(SedimentingCloud):
            price: Decimal | None = None
        """)
    base = USER.format(extra="").replace("user_body:SedimentingCloud", "fielded:Tagged")
    cfg, resolved = config.loads(base)
    system = config.build_system(cfg, resolved)
    assert system.tags == ("a", "b") and system.centre == (0.0, 0.0, 0.0)  # factory default
    with pytest.raises(ConfigError, match=r"model\.centre"):  # a 3-tuple takes 3 numbers
        config.loads(base.replace("n_points = 12", "n_points = 12\ncentre = [1.0, 2.0]"))
    with pytest.raises(ConfigError) as info:
        config.loads(base.replace("fielded:Tagged", "fielded:Unresolved"))
    assert "cannot derive a config section from the fields of Unresolved" in str(info.value)
