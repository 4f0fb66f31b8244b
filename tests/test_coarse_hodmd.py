"""The HODMD-Parareal coarse-solver family (parastokes/coarse/hodmd/): runs from configs on every
body kind and converges to the fine solution; checks explain bad settings before any work; its
cost estimate; with the extrapolated family as G1 or G2 (the combination)."""

from __future__ import annotations

import numpy as np
import pytest

from parastokes import cli, config
from parastokes import run as runner
from parastokes.coarse.hodmd.family import Hodmd
from parastokes.coarse.hodmd.solver import HodmdCoarse
from parastokes.registry import coarse as registry

HODMD = """
[coarse]
kind = "hodmd"
snapshots = {snapshots}
window = {window}
d = {d}
[coarse.g1]
dt_ratio = 1
{g1}
[coarse.g2]
dt_ratio = {g2_ratio}
{g2}
[execution]
executor = "serial"
[output]
figures = false
"""

def problem(model: dict, t1: float, dt: float) -> str:
    """A run of 4 slices and at most 4 iterations of the body ``model`` (its [model] keys)."""
    lines = "\n".join(f"{key} = {value!r}".replace("'", '"') for key, value in model.items())
    return (f"[model]\n{lines}\n[time]\nt1 = {t1}\n[fine]\ndt = {dt}\n"
            "[parareal]\nn_slices = 4\nmax_iterations = 4\n")


#: body -> (problem, HODMD settings, τ_G1 / τ_f)
BODIES = {
    # a 21-node rod over 4 slices of 500 fine steps; G1: Euler 5 τ_f, G2: Euler 10 τ_f
    "rod": (problem(dict(kind="rod", n_points=21, length=4.0), 0.002, 1e-6),
            dict(snapshots=25, window=0.5, d=4, g1="", g2_ratio=10, g2=""), 5),
    "vesicle": (problem(dict(kind="vesicle", subdivisions=1), 0.4, 0.001),
                dict(snapshots=20, window=0.6, d=3, g1="", g2_ratio=5, g2=""), 1),
    "chain": (problem(dict(kind="chain", n_beads=10, stiffness=20.0, bending=2.0,
                           shear_rate=1.0, stretch=1.2, tilt=0.4), 0.4, 0.002),
              dict(snapshots=10, window=0.6, d=3, g1="", g2_ratio=5, g2=""), 1),
    "user": (problem(dict(kind="user_body:SedimentingCloud", n_points=12), 0.4, 0.002),
             dict(snapshots=10, window=0.6, d=3, g1="", g2_ratio=5, g2=""), 1),
}


def body_config(kind: str, **changes) -> str:
    text, settings, g1_ratio = BODIES[kind]
    coarse = HODMD.format(**(settings | changes)).replace("dt_ratio = 1\n",
                                                          f"dt_ratio = {g1_ratio}\n", 1)
    return text + coarse


@pytest.mark.parametrize("kind", list(BODIES))
def test_parareal_with_hodmd_converges_to_the_fine_solution(kind, tmp_path):
    cfg, resolved = config.loads(body_config(kind))
    assert isinstance(cfg.coarse, Hodmd)
    summary = runner.execute(cfg, resolved, tmp_path)
    errors = np.asarray(summary["errors"])
    print(kind, errors)
    assert len(errors) == 4
    assert np.all(np.diff(errors[:3]) < 0) and errors[-1] == 0.0  # exact after N_c iterations
    assert errors[0] < BOUND[kind]


#: η^1 measured (docs/hodmd.md): rod 4.8e-10, vesicle 1.1e-8, chain 9.2e-8, user body 2.2e-9
BOUND = {"rod": 1e-9, "vesicle": 3e-8, "chain": 3e-7, "user": 1e-8}


def test_hodmd_recovers_what_a_coarse_grid_g2_loses_and_composes_with_extrapolation(tmp_path):
    """On the rod, G2 = Euler 10 τ_f on the coarse grid (σ_c = 2 σ_f, spline transfer): alone its
    η^1 is 9.1e-5 (measured); HODMD with the fine-grid G1 over half of each slice brings it to
    1.0e-8. With an extrapolated G1 (Lagrange in ε, two nodes: the combination) it converges."""
    text, _, _ = BODIES["rod"]
    cfg, resolved = config.loads(text + '[coarse]\ndt_ratio = 10\ngrid_factor = 2\n[execution]'
                                 '\nexecutor = "serial"\n[output]\nfigures = false\n')
    alone = runner.execute(cfg, resolved, tmp_path / "g2")["errors"][0]
    cfg, resolved = config.loads(body_config("rod", g2="grid_factor = 2"))
    hodmd = runner.execute(cfg, resolved, tmp_path / "hodmd")["errors"][0]
    assert hodmd < alone / 1000  # measured 1.0e-8 against 9.1e-5
    combined = body_config("rod", g1="lagrange = { epsilon = [5.6, 5.65] }", g2="grid_factor = 2")
    cfg, resolved = config.loads(combined)
    assert resolved.n_auxiliary == 1 and cfg.coarse.g2.grid_factor == 2  # one task per trace
    errors = runner.execute(cfg, resolved, tmp_path / "combined")["errors"]
    assert np.all(np.diff(errors[:3]) < 0) and errors[-1] == 0.0  # measured 2.5e-6, 1.6e-7, 1.3e-8


def test_the_authors_global_initial_guess_from_a_config(tmp_path):
    """initial = "global": G1 over the first 60% of the slices (2 of 4), one HODMD of G1 − G2
    to the rest; X^0 at T_1, T_2 is G1's chain, and Parareal converges as with the sweep."""
    text = body_config("rod") .replace('kind = "hodmd"\n', 'kind = "hodmd"\ninitial = "global"\n'
                                       "initial_snapshots = 5\ninitial_d = 4\n")
    cfg, resolved = config.loads(text)
    setup = config.build(cfg, resolved)
    assert setup.coarse.initial == (0.6, 5, 4)
    x0 = setup.system.initial_state()
    guess = setup.coarse.initial_guess(np.linspace(0, 0.002, 5), x0)
    g1 = setup.coarse.g1
    np.testing.assert_allclose(guess[1], g1(0.0, 0.0005, x0), rtol=1e-12, atol=1e-12)
    errors = runner.execute(cfg, resolved, tmp_path)["errors"]
    assert np.all(np.diff(errors[:3]) < 0) and errors[-1] == 0.0 and errors[0] < 1e-8


@pytest.mark.parametrize("override, key, words", [
    ("coarse.window=[0.1]", "coarse.window", "HODMD with coarse.d = 4 needs W >= d"),
    ("coarse.window=[0.5, 1.2]", "coarse.window", "every r_s must lie in (0, 1]"),
    ("coarse.svd_tolerance=2.0", "coarse.svd_tolerance", "must lie in (0, 1)"),
    ("coarse.amplitude_tolerance=0.0", "coarse.amplitude_tolerance", "must lie in (0, 1)"),
    ("coarse.g1.dt_ratio=3", "coarse.g1.dt_ratio", "does not divide the snapshot interval"),
    ("coarse.g1.dt_ratoi=3", "coarse.g1.dt_ratoi", "did you mean 'dt_ratio'"),
    ("coarse.g2.lagrange={epsilon=[4.5, 5.5]}", "coarse.g2.lagrange.epsilon", "outside"),
    ('coarse.initial="global";coarse.initial_snapshots=2', "coarse.initial_snapshots",
     "fewer than coarse.initial_d = 10"),
])
def test_check_explains_bad_settings_in_one_line_naming_the_key(override, key, words, tmp_path,
                                                                 capsys):
    path = tmp_path / "hodmd.toml"
    path.write_text(body_config("rod"))
    sets = [arg for item in override.split(";") for arg in ("--set", item)]
    assert cli.main(["check", str(path), *sets]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 2 and lines[1].strip().startswith(f"{key}: ") and words in lines[1]


def test_the_family_is_registered_and_builds_a_tracing_solver():
    assert registry.get("hodmd") is Hodmd and "hodmd" in registry.families()
    cfg, resolved = config.loads(body_config("rod", window="[0.48, 0.52, 0.96]"))
    coarse = config.build(cfg, resolved).coarse
    assert isinstance(coarse, HodmdCoarse)
    assert coarse.windows == (12, 13, 24) and coarse.snapshots == 25 and coarse.d == 4
    # trace of iteration 1 covers the windows of iterations 1 and 2; of iteration 2, 2 and 3
    assert [coarse.window(k) for k in range(5)] == [12, 12, 13, 24, 24]
    assert resolved.coarse_steps == [4 * 24, 2 * 25]  # G1 steps over the widest window, G2's


def test_the_cost_estimate_counts_g1_over_the_window_g2_over_the_slice_and_the_svds():
    """γ_G/γ_F = (G1: 4 steps × mean traced window + G2: 2 steps × 25) × 21² / (500 × 2 × 21²)
    + 4 HODMDs (hodmd_flops) / (200 flops per pair × fine pairs)."""
    from parastokes.coarse.hodmd.family import PAIR_FLOPS, hodmd_flops

    cfg, resolved = config.loads(body_config("rod", window="[0.48, 0.52, 0.96]"))
    traced = np.mean([13, 24, 24, 24])  # iterations 1..4 (max_iterations = 4)
    fine = 500 * 2 * 21**2
    solves = (4 * traced + 2 * 25) * 21**2
    svd = 4 * hodmd_flops(63, 25, 4) / PAIR_FLOPS
    assert cli.estimated_gamma_ratio(cfg, resolved, 4) == pytest.approx((solves + svd) / fine)
    # an extrapolated G1 of two Lagrange nodes: its two auxiliary solves run one after the other
    # in the trace, whatever the cores
    cfg, resolved = config.loads(body_config("rod", window="[0.48, 0.52, 0.96]",
                                             g1="lagrange = { epsilon = [5.6, 5.65] }"))
    solves = (2 * 4 * traced + 2 * 25) * 21**2
    assert cli.estimated_gamma_ratio(cfg, resolved, 40) == pytest.approx((solves + svd) / fine)


def test_the_slice_cost_probe_times_a_trace_and_its_extrapolation():
    from parastokes import parareal

    cfg, resolved = config.loads(body_config("rod"))
    setup = config.build(cfg, resolved)
    x0 = setup.system.initial_state()
    costs = parareal.measure_slice_costs(setup.fine, setup.coarse, 0.0, resolved.slice_length,
                                         x0, repeats=1, fine_steps=20)
    assert costs.n_auxiliary == 1 and costs.auxiliary_steps == [(1, 1)]
    assert costs.auxiliary[0][0] > 0 and costs.overhead[0] > 0


def test_the_extrapolation_runs_blas_on_one_thread_and_restores_the_default(monkeypatch):
    """The SVDs of HODMD run on one BLAS thread whatever the process's default (docs/hodmd.md,
    "BLAS threads"), and the default is back afterwards."""
    import threadpoolctl

    from parastokes.coarse.hodmd import solver

    def blas() -> set[int]:
        return {lib["num_threads"] for lib in threadpoolctl.threadpool_info()
                if lib["user_api"] == "blas"}

    seen: list[set[int]] = []
    original = solver.hodmd

    def spy(*args, **kwargs):
        seen.append(blas())
        return original(*args, **kwargs)

    monkeypatch.setattr(solver, "hodmd", spy)
    cfg, resolved = config.loads(body_config("rod", window="[0.48, 0.52, 0.96]"))
    coarse = config.build(cfg, resolved).coarse
    t = np.arange(coarse.snapshots + 1, dtype=float)[:, None, None]
    differences = np.cos(0.3 * t) * np.ones((1, 4, 3))
    with threadpoolctl.threadpool_limits(limits=2, user_api="blas"):
        coarse.extrapolate(differences, coarse.window(1))
        assert blas() == {2}
    assert seen and all(s == {1} for s in seen)
