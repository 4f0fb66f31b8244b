"""The numbers of docs/validation.md section 2 (coarse-solver stability and slice maps), recomputed
by the functions of ``validation/coarse_slices.py`` and compared with ``docs/numbers.toml``
(``[coarse_slices]``).

Default run (CI-sized): every rod step limit of the page's table and its fraction (0.75-0.95),
the vesicle's linearized limit of Table 7's Theta^0 (3.99 tau_f) against the
bisection (4.14 tau_f), and ||DG|| of the combined coarse map over the former quick slices of the
rods and Table 8 (122, 8.8, 18, 69, 91) and of two passing controls (1.14, 1.01). The slow test
reruns the whole script (about 10 min) and compares every registered number, including the
vesicle nodes, the scalar model and ||DG|| over the paper's slices.
"""

from __future__ import annotations

import pytest
from documented import check, values

from validation import coarse_slices as script

NAMES = list(script.CASES)
QUICK_DG = ("table5_g1", "table5_g2", "table8_g1", "table8_g2", "table8_g3")
CONTROLS = ("table3_g2", "table5_g3")


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


@pytest.mark.parametrize("name", QUICK_DG)
def test_amplification_over_the_former_quick_slice(name):
    former = script.CASES[name][0]
    check("coarse_slices", "dg_former", script.amplification(name, former)["combined"],
          NAMES.index(name))


@pytest.mark.parametrize("name", CONTROLS)
def test_amplification_of_passing_controls(name):
    computed = script.amplification(name, script.CONTROLS[name])["combined"]
    check("coarse_slices", "dg_controls", computed, list(script.CONTROLS).index(name))


@pytest.mark.slow
def test_every_section_2_number():
    """The whole script (about 10 min on two shared cores), every registered number."""
    numbers = script.documented_numbers(script.run_all(log=lambda _line: None))
    assert set(numbers) == set(values("coarse_slices"))
    for name, value in numbers.items():
        check("coarse_slices", name, value)
