"""The numbers of docs/validation.md section 2 (coarse-solver stability and slice maps), recomputed
by the functions of ``validation/coarse_slices.py`` and compared with ``docs/numbers.toml``
(``[coarse_slices]``).

Default run (CI-sized): every rod step limit of the page's table and its fraction (0.75-0.95),
the vesicle's linearized limit of Table 7's Theta^0 (3.99 tau_f) against the bisection
(4.14 tau_f), the spectral radius rho(DG) and norm of Table 5 G^1's combined coarse map over its
former quick slice (the whole Jacobian), rho of Table 8 G^1's over its former quick slice from two
random starts (ARPACK; they agree to 1e-6, which a cut-short iteration does not), and rho of the
passing control Table 5 G^3, and ‖DG‖ of a CI-sized twin of the vesicle (Table 8 G^1's solvers
on 42 points, the whole Jacobian). The slow tests add the vesicle's registered ‖DG‖ over its former
quick slices (the whole Jacobian, 1927 calls each), the other former quick slices and controls, and
rerun the whole script (about 10 min plus the Jacobians) for every registered number, including
the vesicle nodes, the scalar model and rho(DG) over the paper's slices.

``[coarse_slices_more]``: the weight sums sum |w_j v_q| of the scalar-model table, and the
monitors of the combined states of section 4's initial sweeps (by default all but the two over
the paper's slices on the M = 301 rod, which take about 20 s each).
"""

from __future__ import annotations

import math

import pytest
from documented import check, values

from validation import coarse_slices as script
from validation import map_norm

NAMES = list(script.CASES)


def test_rod_step_limits_and_fractions():
    rows = [r for r in script.rod_limits(lambda _line: None) if r["n_points"] == 61]
    check("coarse_slices", "rod_limit", [r["limit/tau_f"] for r in rows])
    check("coarse_slices", "rod_fraction", [r["fraction"] for r in rows])


def test_vesicle_linearized_limit_against_the_bisection():
    spectrum = script.VesicleSpectrum()
    lam7 = spectrum.lam({"epsilon": spectrum.system.epsilon, "stiffness": spectrum.system.stiffness,
                         "viscosity": spectrum.system.viscosity})
    check("coarse_slices", "vesicle_lambda", lam7, script.VESICLE_ROWS.index("table7_g4 (Theta^0)"))
    check("coarse_slices", "vesicle_limit", 2 / lam7 / 1e-3, 0)
    bisection = script.vesicle_bisection_check(lambda _line: None)["bisection/tau_f"]
    check("coarse_slices", "vesicle_bisection", bisection)


def _former(name: str) -> dict:
    return script.amplification(name, script.CASES[name][0])


@pytest.mark.parametrize(
    "name",
    ["table5_g1", pytest.param("table5_g2", marks=pytest.mark.slow),
     pytest.param("table8_g2", marks=pytest.mark.slow),
     pytest.param("table8_g3", marks=pytest.mark.slow)],
)
def test_linearized_map_over_the_former_quick_slice(name):
    found = _former(name)
    index = NAMES.index(name)
    check("coarse_slices", "dg_former", found["combined"], index)
    check("coarse_slices", "dg_norm_former", found["norm"], index)


def test_vesicle_spectral_radius_does_not_depend_on_the_start():
    """Table 8 G^1 over its former quick slice (ARPACK on 1926 unknowns): two random starts give
    the registered rho to 1e-6 (the five-step power iteration gave 18.1, and varied by 0.5% with
    a Krylov space of 24 to 90 directions)."""
    _, _, system, coarse = script.load("table8_g1")
    inner = getattr(coarse, "propagator", coarse)
    x0 = system.initial_state()
    span = script.CASES["table8_g1"][0]
    rhos = []
    for seed in (0, 1):
        probe = map_norm.Probe(lambda x: inner(0.0, span, x), system.positions, x0)
        assert probe.size > map_norm.DENSE_LIMIT  # the iterative path
        rhos.append(map_norm.arnoldi_radius(probe, seed))
    assert rhos[0] == pytest.approx(rhos[1], rel=1e-6)
    for rho in rhos:
        check("coarse_slices", "dg_former", rho, NAMES.index("table8_g1"))


#: The vesicle cases whose ‖DG‖ over the former quick slice is registered (the whole Jacobian:
#: 1927 calls of G, 7 to 21 min each on one shared core).
VESICLE_NORMS = [n for n, norm in zip(NAMES, values("coarse_slices")["dg_norm_former"], strict=True)
                 if n.startswith(("table7", "table8")) and not math.isnan(norm)]
#: The CI-sized twin: Table 8 G^1's solvers on a 42-point vesicle (``model.subdivisions=1``).
TWIN = ("model.subdivisions=1",)


@pytest.mark.slow
@pytest.mark.parametrize("name", VESICLE_NORMS)
def test_vesicle_map_norm_over_the_former_quick_slice(name):
    """‖DG‖ of the vesicle's combined coarse map from the whole forward-difference Jacobian (no
    adjoint needed), and its rho, which must agree with ARPACK's (``dg_former``)."""
    found = script.dense_map(name, script.CASES[name][0])
    index = NAMES.index(name)
    check("coarse_slices", "dg_norm_former", found["norm"], index)
    check("coarse_slices", "dg_former", found["rho_dense"], index)


def test_vesicle_map_norm_ci_twin():
    """The comparison of the slow test above on a 42-point vesicle (127 calls of G)."""
    found = script.dense_map("table8_g1", script.CASES["table8_g1"][0], sets=TWIN)
    assert found["calls"] == 127
    check("vesicle_norm_twin", "table8_g1_former", [found["rho_dense"], found["norm"]])


@pytest.mark.parametrize(
    "name", ["table5_g3", pytest.param("table3_g2", marks=pytest.mark.slow)]
)
def test_spectral_radius_of_passing_controls(name):
    computed = script.amplification(name, script.CONTROLS[name])["combined"]
    check("coarse_slices", "dg_controls", computed, list(script.CONTROLS).index(name))


@pytest.mark.slow
def test_every_section_2_number():
    """The whole script, every registered number."""
    numbers = script.documented_numbers(script.run_all(log=lambda _line: None))
    assert set(numbers) == set(values("coarse_slices"))
    for name, value in numbers.items():
        if name == "dg_norm_former":  # the script leaves the vesicle's NaN: the test above
            for i, norm in enumerate(value):
                if NAMES[i] not in VESICLE_NORMS:
                    check("coarse_slices", name, norm, i)
            continue
        check("coarse_slices", name, value)


def test_combination_weight_sums():
    scalar = [name for name in script.CASES if name.startswith(("table7", "table8"))]
    found = [script.combination(name, span)["sum_abs_weights"]
             for name in scalar for span in script.CASES[name]]
    check("coarse_slices_more", "sum_abs_weights", found)


@pytest.mark.parametrize(
    "key",
    [pytest.param(key, marks=pytest.mark.slow) if key.startswith("rod301") and "paper" in key
     else key for key in script.SWEEPS],
)
def test_initial_sweep_monitors(key):
    found = script.sweep(*script.SWEEPS[key])
    check("coarse_slices_more", key, found["combined"])
    if f"{key}_auxiliary" in values("coarse_slices_more"):
        check("coarse_slices_more", f"{key}_auxiliary", found["auxiliary"])
    blowup = values("coarse_slices_more").get(f"{key}_blowup_t")
    assert (found["blowup"] is None) == (blowup is None)
    if blowup is not None:
        check("coarse_slices_more", f"{key}_blowup_t", found["blowup"]["t"])
