"""The data handling of ``benchmarks/work_precision.py``: which (CPU ratio, error) points each
family of a work-precision diagram gets from the JSON of ``stiff.py`` and ``adaptive.py``."""

from __future__ import annotations

import json
import math

import pytest
from bench_modules import benchmark_module


@pytest.fixture(scope="module")
def wp():
    with benchmark_module("work_precision") as module:
        yield module


# The layout of stiff.py's files: rows with dt (None when adaptive, with rtol then), refresh.
STIFF = {"rows": [
    {"scheme": "euler", "dt": 1e-5, "error": 1e-3, "cpu": 1.0, "refresh": 5},
    {"scheme": "rk2", "dt": 1e-5, "error": 1e-6, "cpu": 2.0, "refresh": 5},
    {"scheme": "rk2", "dt": 5e-6, "error": 1e-7, "cpu": 8.0, "refresh": 5},
    {"scheme": "ros2", "dt": 1e-4, "error": 1e-2, "cpu": 0.5, "refresh": 5},
    {"scheme": "ros2", "dt": 5e-5, "error": 4e-3, "cpu": 1.5, "refresh": 5},
    {"scheme": "ros34pw2", "dt": 1e-4, "error": 2e-3, "cpu": 3.0, "refresh": 10},
    {"scheme": "ros34pw2", "dt": 1e-3, "error": math.inf, "cpu": math.nan, "refresh": 5,
     "blowup": "blow-up"},
    {"scheme": "ros34pw2", "dt": None, "rtol": 1e-3, "error": 5e-3, "cpu": 0.25, "refresh": 5},
    {"scheme": "ros34pw2", "dt": None, "rtol": 1e-4, "error": 6e-4, "cpu": 0.75, "refresh": 5},
]}
# The layout of adaptive.py's file: the explicit run apart, rows with rtol.
ADAPTIVE = {"rk2": {"dt": 1e-5, "error": 1e-6, "cpu": 4.0, "steps": 10}, "rows": [
    {"scheme": "rk23", "rtol": 1e-3, "error": 1e-4, "cpu": 2.0},
    {"scheme": "rk23", "rtol": 1e-4, "error": 2e-5, "cpu": 1.8},
    {"scheme": "auto", "rtol": 1e-3, "error": 3e-3, "cpu": 1.0},
    {"scheme": "auto", "rtol": 1e-4, "error": 0.0, "cpu": 3.0},
    {"scheme": "ros34pw2", "rtol": 1e-3, "error": 4e-3, "cpu": 6.0},
]}


def test_points_per_family_are_cpu_ratio_then_error(wp):
    got = wp.series([json.loads(json.dumps(STIFF)), ADAPTIVE])
    assert list(got) == ["fixed explicit", "fixed implicit", "adaptive", "auto"]
    # CPU over RK2 of the largest step of the same file (2.0 s), the error as measured.
    assert got["fixed explicit"] == {"euler": [(0.5, 1e-3)], "rk2": [(1.0, 1e-6), (4.0, 1e-7)]}
    # Sorted from the largest error; the refresh named when not 5; the blow-up left out.
    assert got["fixed implicit"] == {"ros2": [(0.25, 1e-2), (0.75, 4e-3)],
                                     "ros34pw2, J every 10": [(1.5, 2e-3)]}
    # adaptive.py's ratios against its own rk2 (4.0 s); its ros34pw2 kept apart from file 1's.
    assert got["adaptive"] == {"ros34pw2": [(0.125, 5e-3), (0.375, 6e-4)],
                               "rk23": [(0.5, 1e-4), (0.45, 2e-5)],  # by error, not CPU
                               "ros34pw2 (file 2)": [(1.5, 4e-3)]}
    # An error that rounds to zero cannot sit on a log axis: left out, not invented.
    assert got["auto"] == {"auto": [(0.25, 3e-3)]}


def test_explicit_cpu_and_family(wp):
    assert wp.explicit_cpu(STIFF) == 2.0
    assert wp.explicit_cpu(ADAPTIVE) == 4.0
    with pytest.raises(ValueError, match="no RK2 row"):
        wp.explicit_cpu({"rows": [STIFF["rows"][0]]})
    assert wp.family({"scheme": "rk45", "rtol": 1e-3}) == "adaptive"
    assert wp.family({"scheme": "rk45", "dt": 1e-5, "rtol": None}) == "fixed explicit"
    assert wp.family({"scheme": "lieuler", "dt": 1e-5}) == "fixed implicit"
    assert wp.family({"scheme": "auto", "rtol": 1e-3}) == "auto"


def test_every_problem_file_is_readable(wp):
    for files, _, _ in wp.PROBLEMS.values():
        for name in files:
            data = json.loads((wp.OUT / name).read_text())
            assert wp.explicit_cpu(data) > 0
            assert any(wp.series([data]).values())


def test_skipped_runs_are_named(wp):
    files = [STIFF, {**ADAPTIVE, "skipped": [{"scheme": "rk45", "rtol": 1e-8, "cap": 300.0},
                                              {"scheme": "auto", "rtol": 1e-7, "cap": 300.0}]}]
    assert wp.skipped(files) == ["rk45 at rtol 1e-08", "auto at rtol 1e-07"]
    assert wp.skipped([STIFF]) == []


def test_auto_against_the_cheapest_fixed_run_reaching_its_error(wp):
    got = wp.auto_against_fixed([STIFF, ADAPTIVE])
    # auto at rtol 1e-3: 3e-3 at 1.0/4.0 of its file's RK2; the fixed runs with error <= 3e-3:
    # euler (0.5), ros34pw2 (1.5), the rk2 rows (1.0, 4.0) and adaptive.py's rk2 entry (1.0).
    assert got[0] == {"rtol": 1e-3, "error": 3e-3, "cpu": 0.25, "best": "euler at 1e-05 s",
                      "best_cpu": 0.5, "over_best": 0.5, "error_over_rtol": 3.0}
    # An error of 0: no fixed run reaches it.
    assert got[1]["best"] is None and got[1]["over_best"] is None
    # adaptive.py's own RK2 at the limit counts as a fixed run.
    alone = wp.auto_against_fixed([ADAPTIVE])[0]
    assert (alone["best"], alone["best_cpu"], alone["over_best"]) == ("rk2 at 1e-05 s", 1.0, 0.25)
