"""The configuration schema: validation with key paths, units, base files, overrides, building."""

from __future__ import annotations

import importlib
import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest
from configs import small_rod

from parastokes import config, parareal
from parastokes.config import ConfigError

ROOT = Path(__file__).resolve().parents[1]

# A small valid rod configuration; tests change one thing at a time.
BASE = small_rod(model="epsilon = 5", rest='[execution]\nexecutor = "processes"\nworkers = 4\n')

VESICLE = """
[model]
kind = "vesicle"
subdivisions = 2
[time]
t1 = 1
[fine]
dt = 0.01
[coarse]
dt_ratio = 2
[parareal]
n_slices = 2
[execution]
executor = "serial"
"""


def issues_of(text: str, *overrides: str) -> dict[str, str]:
    with pytest.raises(ConfigError) as info:
        config.loads(text, overrides=overrides)
    return dict(info.value.issues)


def test_base_configuration_is_valid_and_resolves_units():
    cfg, r = config.loads(BASE)
    assert cfg.model.kind == "rod"
    assert r.grid_spacing == pytest.approx(0.2)
    assert r.epsilon == pytest.approx(1.0)  # 5 sigma_f
    assert r.lagrange["epsilon"] == pytest.approx([1.12, 1.13])  # plain list: the model's unit
    assert r.coarse_dt == pytest.approx(1e-5)  # tau_c = 10 tau_f
    assert r.coarse_base_dt == pytest.approx(1e-5 / 0.83)  # tau = tau_c / r^m
    assert r.coarse_steps == [42, 50]  # round(0.0005 / (1e-5 / 0.83)), round(0.0005 / 1e-5)
    assert r.n_auxiliary == 4
    assert r.fine_steps == 500


@pytest.mark.parametrize(
    ("override", "path", "fragment"),
    [
        ("model.epsilonn=5", "model.epsilonn", "did you mean 'epsilon'"),
        ("parareal.n_slicse=4", "parareal.n_slicse", "did you mean 'n_slices'"),
        ("coarse.richardson.q=1", "coarse.richardson.q", "unknown key"),
        ("outptu.every=2", "outptu", "did you mean 'output'"),
        ("coarse.lagrange.epsilon.unitt='relative'", "coarse.lagrange.epsilon.unitt", "unit"),
    ],
)
def test_typos_name_the_key(override, path, fragment):
    issues = issues_of(BASE, override)
    assert path in issues
    assert fragment in issues[path]


@pytest.mark.parametrize(
    ("override", "path"),
    [
        ('parareal.n_slices="4"', "parareal.n_slices"),
        ("parareal.n_slices=4.0", "parareal.n_slices"),
        ('fine.dt="small"', "fine.dt"),
        ("model.wall=1", "model.wall"),
        ("model.shear=[0.6, 0.6]", "model.shear"),
        ('coarse.lagrange.epsilon="5.6"', "coarse.lagrange.epsilon"),
        ('fine.scheme="rk3"', "fine.scheme"),
        ('execution.executor="threads"', "execution.executor"),
        ('model.kind="sphere"', "model.kind"),
    ],
)
def test_wrong_types_name_the_key(override, path):
    assert path in issues_of(BASE, override)


@pytest.mark.parametrize(
    ("override", "path", "fragment"),
    [
        ("model.epsilon=-1", "model.epsilon", "greater than 0"),
        ("coarse.richardson.r=1.2", "coarse.richardson.r", "less than 1"),
        ("coarse.richardson.r=0", "coarse.richardson.r", "greater than 0"),
        ("coarse.richardson.m=-1", "coarse.richardson.m", "greater than or equal to 0"),
        ("coarse.lagrange.epsilon=[5.65, 5.6]", "coarse.lagrange.epsilon", "strictly increasing"),
        ("coarse.lagrange.epsilon=[4.9, 5.6]", "coarse.lagrange.epsilon", "outside the node"),
        ("coarse.lagrange.bending=[-1.0, 0.9]", "coarse.lagrange.bending", "positive"),
        ("coarse.lagrange.stiffness=[0.8, 0.9]", "coarse.lagrange.stiffness", "bending"),
        ("coarse.grid_factor=7", "coarse.grid_factor", "must divide"),
        ("time.t1=0", "time.t1", "must exceed"),
        ("fine.dt=0.01", "fine.dt", "slice length"),
        ("coarse.dt=1e-5", "coarse.dt", "exactly one"),
        ("coarse.richardson.r=0.999", "coarse.richardson.r", "must all differ"),
        ("execution.workers=2", "execution.workers", "N_G = 4"),
        ("output.tracked_points=[1]", "output.tracked_points", "vesicles only"),
        ("parareal.max_iterations=0", "parareal.max_iterations", "greater than or equal to 1"),
        (
            'coarse.lagrange.epsilon={nodes=[1.1, 1.2], unit="l_max"}',
            "coarse.lagrange.epsilon.unit",
            "l_max",
        ),
    ],
)
def test_out_of_range_values_name_the_key(override, path, fragment):
    issues = issues_of(BASE, override)
    assert path in issues
    assert fragment in issues[path]


def test_richardson_needs_r_when_m_is_positive():
    text = BASE.replace("richardson = { m = 1, r = 0.83 }", "richardson = { m = 2 }")
    assert "coarse.richardson.r" in issues_of(text)


def test_missing_required_keys_are_named():
    text = BASE.replace("dt = 1e-6\n", "").replace('kind = "rod"\n', "")
    issues = issues_of(text)
    assert set(issues) == {"model.kind", "fine.dt"}


def test_toml_syntax_errors_are_reported_as_config_errors():
    with pytest.raises(ConfigError, match="TOML syntax error"):
        config.loads("[model\nkind = 'rod'")


def test_several_issues_are_reported_together():
    issues = issues_of(BASE, "coarse.lagrange.epsilon=[5.7, 5.6]", "coarse.grid_factor=7")
    assert {"coarse.lagrange.epsilon", "coarse.grid_factor"} <= set(issues)


def test_oversubscription_is_allowed_when_asked_and_for_the_serial_executor():
    config.loads(BASE, overrides=["execution.workers=2", "execution.allow_oversubscribe=true"])
    _, r = config.loads(BASE, overrides=['execution.executor="serial"', "execution.workers=1"])
    assert r.workers == 1
    assert "execution.workers" in issues_of(BASE, 'execution.executor="serial"')


def test_vesicle_units_and_rules():
    _, r = config.loads(
        VESICLE,
        overrides=['coarse.lagrange.stiffness={nodes=[0.6, 0.7], unit="relative"}'],
    )
    assert r.epsilon == pytest.approx(0.3 * r.grid_spacing)  # 0.3 l_max
    assert r.lagrange["stiffness"] == pytest.approx([0.06, 0.07])  # relative to kappa0 = 0.1
    # a coarser icosphere: a power of 2 up to 2^subdivisions (round 5), nothing else
    config.loads(VESICLE, overrides=["coarse.grid_factor=2"])
    assert "power of 2" in issues_of(VESICLE, "coarse.grid_factor=3")["coarse.grid_factor"]
    too_fine = issues_of(VESICLE, "coarse.grid_factor=8")["coarse.grid_factor"]
    assert "at most 2^subdivisions" in too_fine
    assert "coarse.lagrange.bending" in issues_of(VESICLE, "coarse.lagrange.bending=[0.5, 0.6]")
    assert "output.tracked_points" in issues_of(VESICLE, "output.tracked_points=[5000]")
    assert "model.epsilon_unit" in issues_of(VESICLE, 'model.epsilon_unit="sigma_f"')


def test_vesicle_radius_scales_l_max_and_epsilon_and_keeps_the_tracked_points():
    cfg1, r1 = config.loads(VESICLE)
    cfg, r = config.loads(VESICLE, overrides=["model.radius=2.5"])
    assert r.grid_spacing == pytest.approx(2.5 * r1.grid_spacing, rel=1e-15)  # l_max
    assert r.epsilon == pytest.approx(2.5 * r1.epsilon, rel=1e-15)  # 0.3 l_max
    system = cfg.model.build()
    assert system.radius == 2.5 and system.epsilon == r.epsilon
    assert np.linalg.norm(system.initial_state(), axis=1) == pytest.approx(2.5, rel=1e-15)
    marks = [c.model.layout(c.model.build(), False, None)[0].marks["tracked"] for c in (cfg1, cfg)]
    np.testing.assert_array_equal(marks[0], marks[1])  # Fig. 11's points, whatever the size
    assert "model.radius" in issues_of(VESICLE, "model.radius=0")


def test_overrides_parse_toml_values():
    cfg, _ = config.loads(BASE, overrides=["parareal.n_slices=2", 'fine.scheme="rk4"'])
    assert cfg.parareal.n_slices == 2
    assert cfg.fine.scheme == "rk4"
    with pytest.raises(ConfigError, match="KEY=VALUE"):
        config.loads(BASE, overrides=["parareal.n_slices"])


def test_an_override_replaces_a_table_and_reaches_quoted_and_indexed_keys():
    # regression: a table was merged into the old one (coarse.lagrange={} kept every node), and
    # a key holding a dot or a [[bodies]] index could not be reached
    table4 = ROOT / "experiments" / "quick" / "table4_g1.toml"
    assert config.load(table4)[1].n_auxiliary == 36
    _, resolved = config.load(table4, overrides=["coarse.lagrange={}"])
    assert resolved.lagrange == {} and resolved.n_auxiliary == 1
    _, resolved = config.load(table4, overrides=["coarse.lagrange={bending=[0.7, 0.8]}"])
    assert list(resolved.lagrange) == ["bending"] and resolved.n_auxiliary == 2
    scene = ("[[bodies]]\nkind = 'chain'\nn_beads = 5\n[[bodies]]\nkind = 'chain'\n"
             "n_beads = 6\nheight = 2.0\n[time]\nt1 = 0.02\n[fine]\ndt = 1e-3\n"
             "[coarse]\ndt_ratio = 2\n[parareal]\nn_slices = 2\n[execution]\n"
             "executor = 'serial'\n")
    cfg, resolved = config.loads(scene, overrides=[
        "bodies.1.n_beads=7", 'coarse.lagrange."chain1.bending"=[0.8, 0.9]'])
    assert [body.n_beads for body in cfg.model.bodies] == [5, 7]
    assert resolved.lagrange == {"chain1.bending": [0.8, 0.9]}
    # a quoted key part may hold "=" (a body named "a=b"); the first "=" outside quotes splits
    named = scene.replace("n_beads = 6\n", "n_beads = 6\nname = 'a=b'\n")
    _, resolved = config.loads(named, overrides=['coarse.lagrange."a=b.bending"=[0.8, 0.9]'])
    assert resolved.lagrange == {"a=b.bending": [0.8, 0.9]}
    assert config.apply_overrides({}, ['x."y\\"=z".w = "u=v"']) == {"x": {'y"=z': {"w": "u=v"}}}
    for bad, fragment in (("bodies.2.n_beads=7", "not an index"), ("a..b=1", "dotted key")):
        with pytest.raises(ConfigError, match=fragment):
            config.loads(scene, overrides=[bad])


def test_a_file_that_is_not_utf8_is_named(tmp_path):
    path = tmp_path / "latin.toml"
    path.write_bytes('title = "caf\u00e9"\n'.encode("latin-1"))
    with pytest.raises(ConfigError, match=r"latin\.toml[\s\S]*not UTF-8"):
        config.load(path)


def test_base_files_merge_and_cycles_are_caught(tmp_path):
    (tmp_path / "full.toml").write_text(BASE)
    (tmp_path / "variant.toml").write_text('base = "full.toml"\n[parareal]\nn_slices = 2\n')
    cfg, _ = config.load(tmp_path / "variant.toml")
    assert cfg.parareal.n_slices == 2
    assert cfg.coarse.richardson.m == 1  # inherited
    (tmp_path / "a.toml").write_text('base = "b.toml"\n')
    (tmp_path / "b.toml").write_text('base = "a.toml"\n')
    with pytest.raises(ConfigError, match="circular"):
        config.load(tmp_path / "a.toml")
    with pytest.raises(ConfigError, match="cannot read"):
        config.load(tmp_path / "missing.toml")


def test_resolved_dict_keeps_defaults_and_derived_values():
    cfg, r = config.loads(BASE)
    data = config.resolved_dict(cfg, r)
    assert data["model"]["frequency"] == pytest.approx(40 * math.pi)  # Table 2 default
    assert data["resolved"]["epsilon"] == pytest.approx(1.0)
    assert data["resolved"]["n_auxiliary"] == 4


def test_build_gives_the_configured_system_and_propagators():
    cfg, r = config.loads(
        BASE,
        overrides=[
            'coarse.lagrange.bending={nodes=[0.8, 0.9], unit="relative"}',
            'execution.executor="serial"',
            "execution.workers=1",
        ],
    )
    setup = config.build(cfg, r)
    assert setup.system.params == pytest.approx(
        {"epsilon": 1.0, "viscosity": 1e-6, "bending": 1.0}
    )
    assert setup.fine.dt == 1e-6
    assert setup.fine.scheme == "rk2"
    coarse = setup.coarse
    assert isinstance(coarse, parareal.Extrapolated)
    assert len(coarse.auxiliary) == 4  # 2 epsilon nodes x 2 bending nodes
    assert [p.dt for p in coarse.auxiliary[0]] == pytest.approx([1e-5 / 0.83, 1e-5])
    thetas = sorted((t["epsilon"], t["bending"]) for t in coarse.thetas)
    expected = [(1.12, 0.8), (1.12, 0.9), (1.13, 0.8), (1.13, 0.9)]
    assert [pytest.approx(t) for t in expected] == thetas


def test_build_uses_the_coarse_grid():
    cfg, r = config.loads(BASE, overrides=["coarse.grid_factor=4"])
    setup = config.build(cfg, r)
    assert isinstance(setup.coarse, parareal.OnCoarseGrid)
    assert setup.coarse.propagator.system.n_points == 6  # (21 - 1) / 4 + 1


def test_vesicle_build_has_the_absolute_epsilon():
    cfg, r = config.loads(VESICLE)
    setup = config.build(cfg, r)
    assert setup.system.epsilon == r.epsilon
    assert setup.system.stiffness == 0.1


def test_demo_configuration_is_valid():
    cfg, r = config.loads(config.DEMO)
    assert cfg.run.mode == "both"
    assert cfg.execution.workers == 2
    assert cfg.parareal.n_slices == 2
    assert r.n_auxiliary == 2  # N_G <= N_c: no oversubscription needed


def test_config_reference_is_up_to_date():
    spec = importlib.util.spec_from_file_location(
        "gen_config_reference", ROOT / "docs" / "gen_config_reference.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    committed = (ROOT / "docs" / "config.md").read_text(encoding="utf-8")
    assert committed == module.render(), "run: python docs/gen_config_reference.py"


def test_the_coarse_solver_family_is_a_key_with_the_extrapolated_default():
    cfg, _ = config.loads(BASE)
    assert cfg.coarse.kind == "extrapolated"
    assert cfg.model_dump()["coarse"]["kind"] == "extrapolated"
    issues = issues_of(BASE, 'coarse.kind="spectral"')
    assert "coarse.kind" in issues and "extrapolated" in issues["coarse.kind"]


def test_implicit_schemes_and_adaptive_steps_are_keys_checked_before_any_work(monkeypatch):
    """docs/stiff.md: the schemes by name, rtol/atol finite and positive with a scheme that has
    an error estimate; implicit schemes on the GPU executor too (hosted)."""
    cfg, _ = config.loads(VESICLE, overrides=['fine.scheme="ros2"', "fine.rtol=1e-4"])
    assert (cfg.fine.scheme, cfg.fine.rtol, cfg.fine.atol) == ("ros2", 1e-4, None)
    assert issues_of(VESICLE, 'fine.scheme="ros2"', "fine.rtol=-1")["fine.rtol"] == (
        "must be a finite number > 0, got -1.0")
    assert "no error estimate" in issues_of(VESICLE, 'fine.scheme="lieuler"',
                                            "fine.rtol=1e-3")["fine.rtol"]
    assert issues_of(VESICLE, 'fine.scheme="ros2"', "fine.atol=1e-3")["fine.rtol"] == (
        "required with fine.atol (adaptive steps)")
    # the GPU executor hosts implicit solves (parastokes.gpu.hosted): nothing to refuse (on a
    # machine with a GPU: this one may have none)
    from parastokes.gpu import device

    monkeypatch.setattr(device, "missing", lambda: None)
    cfg, _ = config.loads(VESICLE, overrides=['coarse.scheme="ros2-krylov"',
                                              'execution.executor="gpu"'])
    assert (cfg.coarse.scheme, cfg.execution.executor) == ("ros2-krylov", "gpu")


def test_adaptive_coarse_solvers_are_keys_checked_before_any_work():
    cfg, _ = config.loads(VESICLE, overrides=['coarse.scheme="ros2"', "coarse.rtol=1e-3"])
    assert (cfg.coarse.rtol, cfg.coarse.atol) == (1e-3, None)
    assert "needs the fixed steps" in issues_of(
        VESICLE, 'coarse.scheme="ros2"', "coarse.rtol=1e-3", "coarse.richardson.m=1",
        "coarse.richardson.r=0.5")["coarse.rtol"]
    assert issues_of(VESICLE, "coarse.atol=1e-3")["coarse.rtol"] == (
        "required with atol (adaptive steps)")


def test_a_serial_mode_run_without_threads_evaluates_on_every_core(monkeypatch):
    """No workers share the cores of a run of run.mode = "serial": unless execution.threads says
    otherwise, its system's kernels use them all, and give the numbers of one thread."""
    from parastokes.config import checks

    monkeypatch.setattr(checks, "available_cores", lambda: 2)
    serial = small_rod(model="epsilon = 5", rest='[run]\nmode = "serial"\n')
    cfg, resolved = config.loads(serial)
    assert resolved.threads == 2 and config.build_system(cfg, resolved).fluid.n_threads == 2
    one_cfg, one = config.loads(serial + "[execution]\nthreads = 1\n")
    assert one.threads == 1 and config.build_system(one_cfg, one).fluid.n_threads == 1
    assert config.loads(BASE)[1].threads == 1  # Parareal's workers occupy the cores
    systems = [config.build_system(cfg, resolved), config.build_system(one_cfg, one)]
    x0 = systems[0].initial_state()
    two_threads, one_thread = (s.rates(0.0, x0) for s in systems)
    np.testing.assert_array_equal(two_threads, one_thread)
