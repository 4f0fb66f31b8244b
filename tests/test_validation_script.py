"""The claims of docs/validation.md about extrapolated coarse solvers on a rod (Figs. 3 and 5).

``validation/rod_extrapolation.py`` evaluates its qualitative claims with ``claims``; here they
must hold on the quick setup (computed afresh) and on the saved full results of the report.
"""

import json
from pathlib import Path

import pytest

from validation import rod_extrapolation as script

FULL_RESULTS = Path(__file__).parents[1] / "docs" / "figures" / "rod_extrapolation.json"


@pytest.fixture(scope="module")
def quick():
    return script.run_all(script.QUICK, log=lambda _line: None)


def test_quick_run_supports_every_claim_and_plots(quick, tmp_path):
    failed = [name for name, holds in script.claims(quick).items() if not holds]
    assert not failed
    script.plot_fig3(quick, tmp_path / "fig3.png")
    script.plot_fig5(quick, tmp_path / "fig5.png")
    assert (tmp_path / "fig3.png").stat().st_size > 0 and (tmp_path / "fig5.png").stat().st_size > 0


def test_saved_full_results_support_every_claim():
    if not FULL_RESULTS.exists():
        pytest.skip("run python -m validation.rod_extrapolation first")
    results = json.loads(FULL_RESULTS.read_text())
    assert results["setup"]["n_points"] == script.FULL.n_points
    claims = script.claims(results)
    assert claims == results["claims"]
    assert all(claims.values()), claims
