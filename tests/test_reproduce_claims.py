"""The verdicts of docs/reproduction.md: every claim of the paper's section 5 is evaluated by its
stated criterion.

One set of records shaped like the paper's figures (η^k per iteration, γ_G/γ_F per solver, the
speedups of eq. 14 on 40 cores) satisfies every claim; for each claim one change of those records
that the paper's words exclude makes it differ. A claim added to ``CLAIMS`` without such a pair
fails ``test_every_claim_has_a_counterexample``.
"""

import pytest

from validation import reproduce, reproduce_report


def _rec(errors: list[float], ratio: float) -> dict:
    return {"errors": errors, "gamma_ratio": ratio,
            "speedup_40": reproduce.speedup_curve(errors, ratio, 40)}


#: (errors η¹..η⁴, γ_G/γ_F) per run, shaped like the paper's figures.
PAPER_LIKE = {
    # Fig. 4: G² decays faster than G¹ at the same cost.
    "table3_g1": ([1e-5, 1e-7, 1e-9, 1e-11], 0.01),
    "table3_g2": ([1e-6, 1e-9, 1e-12, 1e-14], 0.01),
    # Fig. 5: Lagrange error dominates for small N_ε; Richardson pays off at N_ε = 5.
    "table3_g3_n2": ([5e-7], 0.05), "table3_g4_n2": ([4.5e-7], 0.1),
    "table3_g3_n3": ([2e-8], 0.05), "table3_g4_n3": ([1.9e-8], 0.1),
    "table3_g3_n5": ([1.1e-8], 0.05), "table3_g4_n5": ([1.5e-10], 0.1),
    "table3_g3_n6": ([1.2e-8], 0.05), "table3_g4_n6": ([1e-10], 0.1),
    # Fig. 6: G¹ best above 1e-6 (its step at 1e-6), G² in [1e-7, 1e-6], G³ below 1e-8 (one
    # iteration to 1e-10), G⁴ slower at first and the most accurate at the end.
    "table4_g1": ([1e-6, 5e-8, 3e-9, 2e-10], 0.01),
    "table4_g2": ([1e-7, 2e-9, 5e-11, 2e-12], 0.02),
    "table4_g3": ([1e-10, 1e-12, 1e-13, 5e-14], 0.04),
    "table4_g4": ([1e-8, 2e-12, 1e-14, 1e-15], 0.05),
    # Fig. 8: τ_c/τ_f larger for ε⁰ = 2σ_f.
    "table6_eps2": ([1e-5, 1e-8, 1e-11], 0.01),
    "table6_eps3": ([1e-5, 1e-8, 1e-11], 0.05),
    # Fig. 12: the best solver changes with the desired error; G⁴ never the fastest.
    "table7_g1": ([3e-5, 9e-6, 2e-6, 3e-8], 0.03),
    "table7_g2": ([4e-6, 7e-7, 1e-7, 2e-8], 0.06),
    "table7_g3": ([3e-9, 5e-11, 3e-13, 2e-13], 0.1),
    "table7_g4": ([4e-9, 1e-12, 2e-15, 3e-15], 0.16),
}
# Fig. 7: ε⁰ = 7σ_f, Table 4's errors reached by coarse solvers five times cheaper.
PAPER_LIKE |= {f"table5_g{i}": (PAPER_LIKE[f"table4_g{i}"][0], PAPER_LIKE[f"table4_g{i}"][1] / 5)
               for i in (1, 2, 3)}
# Fig. 13: Table 7's errors with γ_G/γ_F four times smaller (RK4 fine solver, larger τ_c).
PAPER_LIKE |= {f"table8_g{i}": (PAPER_LIKE[f"table7_g{i}"][0], PAPER_LIKE[f"table7_g{i}"][1] / 4)
               for i in (1, 2, 3)}

#: For each claim (by the start of its quote), runs replaced by values its words exclude.
COUNTEREXAMPLES: dict = {
    "the relative error of Algorith": {"table3_g2": ([1e-6, 1e-9, 1e-12, 2e-11], 0.01)},
    "Since both solvers use the tim": {"table3_g2": ([1e-6, 1e-9, 1e-12, 1e-14], 0.012)},
    "as N_ε increases, … Algorithm ": {"table3_g3_n6": ([3e-8], 0.05)},
    "For smaller values of N_ε, G⁴ ": {"table3_g4_n3": ([5e-9], 0.1)},
    "[Richardson] reduces η¹ from a": {"table3_g4_n5": ([2e-9], 0.1)},
    "when G¹ is used as the coarse ": {"table4_g2": ([1e-7, 2e-9, 5e-11, 5e-10], 0.02)},
    "After one iteration, the versi": {"table4_g4": ([5e-11, 2e-12, 1e-14, 1e-15], 0.05)},
    "the version using G⁴ eventuall": {"table4_g4": ([1e-8, 2e-12, 1e-12, 2e-13], 0.05)},
    "in the case of G¹, as the desi": {"table4_g1": ([1e-5, 5e-8, 3e-9, 2e-10], 0.01)},
    "In the case of G³, … it only t": {"table4_g3": ([1e-9, 1e-12, 1e-13, 5e-14], 0.04)},
    "the coarse solver that leads t": {"table4_g2": ([1e-7, 2e-9, 5e-11, 2e-12], 0.05)},
    "as long as the desired error i": {"table4_g4": ([1e-8, 2e-12, 1e-14, 1e-15], 0.005)},
    "to obtain a solution of the sa": {"table5_g1": PAPER_LIKE["table4_g1"]},
    "The speedup is higher in the c": {"table6_eps2": ([1e-5, 1e-8, 1e-11], 0.06)},
    "the best coarse solver to use ": {"table7_g4": ([1e-15, 1e-15, 1e-15, 1e-15], 0.001)},
    "for the range of error conside": {"table7_g3": ([5e-9, 5e-11, 3e-13, 2e-13], 0.1)},
    "Comparing Figs. 12 and 13, … t": {  # Table 7's runs: the same speedups
        f"table8_g{i}": PAPER_LIKE[f"table7_g{i}"] for i in (1, 2, 3)
    },
}


def _records(changes: dict | None = None) -> dict:
    runs = PAPER_LIKE | (changes or {})
    return {name: _rec(list(errors), ratio) for name, (errors, ratio) in runs.items()}


def _claim(start: str) -> reproduce_report.Claim:
    (claim,) = [c for c in reproduce_report.CLAIMS if c.quote.startswith(start)]
    return claim


def test_every_claim_has_a_counterexample():
    assert sorted(c.quote[:30] for c in reproduce_report.CLAIMS) == sorted(COUNTEREXAMPLES)


#: More counterexamples: each breaks one more part of a criterion of several parts.
MORE_COUNTEREXAMPLES = [
    # Fig. 4: "as expensive" fails as well when G² is more than 10 % cheaper
    ("Since both solvers use the tim", {"table3_g2": ([1e-6, 1e-9, 1e-12, 1e-14], 0.0085)}),
    # Fig. 5, N_ε = 5: G³ must stay near 1e-8 (Lagrange-limited), not only G⁴ reach 1e-10
    ("[Richardson] reduces η¹ from a", {"table3_g3_n5": ([1e-6], 0.05)}),
    # Fig. 6: G⁴ must converge more slowly than G³ at first
    ("the version using G⁴ eventuall", {"table4_g4": ([5e-11, 2e-12, 1e-14, 1e-15], 0.05)}),
    # ... and the factor 2 holds at the round-off floor only: 1.9e-11 is not 1e-11
    ("the version using G⁴ eventuall", {"table4_g3": ([1e-10, 1e-11, 1e-11, 1e-11], 0.04),
                                        "table4_g4": ([1e-8, 2e-11, 1.9e-11, 1.9e-11], 0.05)}),
    # G¹'s step at 1e-6: its second iteration must reach below 1e-6
    ("in the case of G¹, as the desi", {"table4_g1": ([1e-6, 3e-6, 3e-9, 2e-10], 0.01)}),
    # the regimes: G¹ ahead of G² inside [1e-7, 1e-6] (the paper's G² regime), although the
    # boundary 1e-7 is shared with no other regime
    ("the coarse solver that leads t", {"table4_g2": ([1.5e-7, 2e-9, 5e-11, 2e-12], 0.02)}),
]


@pytest.mark.parametrize(("start", "change"), [
    *((start, change) for start, change in COUNTEREXAMPLES.items()), *MORE_COUNTEREXAMPLES])
def test_the_paper_like_records_agree_and_the_counterexample_differs(start, change):
    claim = _claim(start)
    ours, holds = claim.evaluate(_records())
    assert holds, ours
    ours, holds = claim.evaluate(_records(change))
    assert not holds, ours


class _Reads(dict):
    """Records that remember which runs were read."""

    def __init__(self, records: dict) -> None:
        super().__init__(records)
        self.read: set[str] = set()

    def __getitem__(self, key):
        self.read.add(key)
        return super().__getitem__(key)


@pytest.mark.parametrize("claim", reproduce_report.CLAIMS, ids=lambda c: c.quote[:30])
def test_a_claim_reads_only_the_runs_it_needs(claim):
    """A verdict is drawn only once the runs in ``needs`` have finished, so a claim that read
    another run could give a verdict from an unfinished one."""
    records = _Reads(_records())
    claim.evaluate(records)
    assert records.read <= set(claim.needs)


def test_the_table_marks_agree_differ_pending_and_out_of_reach():
    records = _records(COUNTEREXAMPLES["as N_ε increases, … Algorithm "])
    del records["table3_g1"], records["table6_eps2"]
    table = reproduce_report.claims_table(records)
    rows = {line.split("|")[2].strip()[1:31]: line.rsplit("|", 2)[1].strip()
            for line in table.splitlines()[2:]}
    assert rows["as N_ε increases, … Algorithm "] == "**differ**"
    assert rows["the relative error of Algorith"] == "pending"
    assert rows["[Richardson] reduces η¹ from a"] == "agree"
    # a claim that needs a run beyond two cores (ε⁰ = 2σ_f) is not "pending": it will not come
    assert rows["The speedup is higher in the c"] == "n/a"
    assert "needs table6_eps2, out of reach" in table
    assert list(rows.values()).count("n/a") == len(reproduce_report.UNTESTABLE) + 1


def test_g4_and_g3_at_the_round_off_floor_are_equally_accurate():
    """The rod's η^k stop falling near 2e-13 (round-off after 10⁶ steps): G⁴ at 1.9e-13 and G³ at
    1.8e-13 both reached the floor, and G⁴ is "the most accurate" as far as η⁴ can tell."""
    claim = _claim("the version using G⁴ eventuall")
    records = _records({"table4_g3": ([1e-10, 1e-12, 2e-13, 1.8e-13], 0.04),
                        "table4_g4": ([1e-8, 2e-12, 1.9e-13, 1.9e-13], 0.05)})
    assert claim.evaluate(records)[1]


def test_fig6_regimes_do_not_depend_on_which_side_of_a_boundary_eta_lies():
    """G¹'s η¹ at 1e-6 exactly, or a little above or below it, puts the switch from G¹ to G² on
    one side of the paper's boundary or the other; the verdict is the same."""
    claim = _claim("the coarse solver that leads t")
    for eta in (0.8e-6, 1e-6, 1.25e-6):
        errors = [eta, 5e-8, 3e-9, 2e-10]
        assert claim.evaluate(_records({"table4_g1": (errors, 0.01)}))[1], eta


def test_a_solver_that_does_not_reach_an_error_does_not_hide_one_that_does():
    """Fig. 12's "one of G¹, G², G³ always leads to higher speedup than G⁴": at 1e-10 G¹ and G²
    (listed first) never reach it in four iterations, G³ does, faster than G⁴."""
    claim = _claim("for the range of error conside")
    records = _records({"table7_g3": ([6e-9, 5e-11, 3e-13, 2e-13], 0.1)})
    ours, holds = claim.evaluate(records)
    first = float(ours.split("e.g. ")[1])
    assert not holds and 4e-9 <= first < 6e-9  # only between G⁴'s η¹ and G³'s is G⁴ faster
    assert claim.evaluate(_records())[1]

