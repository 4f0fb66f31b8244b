"""The arithmetic and bookkeeping of ``benchmarks/adaptive.py``: the predicted CPU time of a run
(stability floor, growth with the tolerance), the skip cap, resuming from the JSON, ``--redo``,
the error measure it takes from ``stiff.py`` and its arguments."""

from __future__ import annotations

import json

import numpy as np
import pytest
from bench_modules import benchmark_module

from benchmarks import stiff
from parastokes import integrate, models


@pytest.fixture(scope="module")
def ad():
    with benchmark_module("adaptive") as module:
        yield module


# Real-axis stability boundaries (Hairer & Wanner II, IV.2): Heun 2, Bogacki-Shampine 2.5127,
# Dormand-Prince 3.3066; evaluations per step: RK2 2, BS3 3 and DOPRI5 6 (first same as last).
def test_stability_floor_is_rk2_cpu_scaled_by_evaluations_and_boundary(ad):
    assert ad.stability_floor("rk23", 2.0) == pytest.approx(2.0 * 3 / 2 * 2 / 2.5127, rel=1e-4)
    assert ad.stability_floor("rk45", 2.0) == pytest.approx(2.0 * 6 / 2 * 2 / 3.3066, rel=1e-4)
    assert ad.stability_floor("rk2", 2.0) == pytest.approx(2.0)
    # The implicit schemes and auto (which may leave the pair) have no explicit floor.
    assert ad.stability_floor("ros34pw2", 2.0) == 0.0
    assert ad.stability_floor("auto", 2.0) == 0.0


ROWS = [
    {"scheme": "rk45", "rtol": 1e-2, "cpu": 30.0},
    {"scheme": "rk45", "rtol": 1e-3, "cpu": 40.0},
    {"scheme": "ros34pw2", "rtol": 1e-3, "cpu": 2.0},
    {"scheme": "ros34pw2", "rtol": 1e-5, "cpu": 500.0},  # tighter than asked: not used
    {"scheme": "auto", "rtol": 1e-4, "cpu": 3.0},
]


def test_prediction_grows_from_the_nearest_looser_rtol(ad):
    # rk45: q = 4, from 1e-3 (the nearest looser, not 1e-2) to 1e-5: x 100^(1/5).
    cpu, why = ad.predicted_cpu("rk45", 1e-5, ROWS, 1.0)
    assert cpu == pytest.approx(40.0 * 100 ** (1 / 5))
    assert "40 s at rtol 0.001" in why
    # ros34pw2: order 3 with an embedded 2, q = 2; its tighter row is no basis.
    assert ad.predicted_cpu("ros34pw2", 1e-4, ROWS, 1.0)[0] == pytest.approx(2.0 * 10 ** (1 / 3))
    # auto: q = 1 (its order 2 with no embedded order of its own).
    assert ad.predicted_cpu("auto", 1e-6, ROWS, 1.0)[0] == pytest.approx(3.0 * 100 ** (1 / 2))


def test_prediction_is_at_least_the_stability_floor(ad):
    # No rk23 row: the floor alone; one whose growth stays below the floor: the floor.
    floor = ad.stability_floor("rk23", 10.0)
    assert ad.predicted_cpu("rk23", 1e-3, ROWS, 10.0) == (floor, f"stability floor {floor:.3g} s")
    rows = [{"scheme": "rk23", "rtol": 1e-2, "cpu": 5.0}]
    assert ad.predicted_cpu("rk23", 1e-3, rows, 10.0)[0] == pytest.approx(floor)
    assert ad.predicted_cpu("ros34pw2", 1e-2, [], 10.0)[0] == 0.0


def test_forget_drops_only_the_named_schemes(ad):
    data = {"rk2": {"cpu": 1.0}, "rows": [dict(r) for r in ROWS],
            "skipped": [{"scheme": "rk45", "rtol": 1e-8}, {"scheme": "auto", "rtol": 1e-8}]}
    ad.forget(data, ["rk45"])
    assert [r["scheme"] for r in data["rows"]] == ["ros34pw2", "ros34pw2", "auto"]
    assert data["skipped"] == [{"scheme": "auto", "rtol": 1e-8}]
    assert "rk2" in data
    ad.forget(data, ["rk2"])
    assert "rk2" not in data and len(data["rows"]) == 3


def test_relative_error_is_position_error_over_largest_displacement():
    x0 = np.zeros((3, 6))
    reference = x0.copy()
    reference[1, 2] = 4.0  # largest displacement 4
    reference[2, 5] = 100.0  # not a position: ignored
    x = reference.copy()
    x[0, 0] = 0.5
    x[2, 4] = 50.0  # not a position either
    assert stiff._relative_error(x, reference, x0) == pytest.approx(0.125)


@pytest.fixture()
def tiny(ad, tmp_path, monkeypatch):
    """A rod of 11 points over T = 2e-4 s as problem ``tiny``, files under ``tmp_path``, and
    RK2's run timed at 2 s of CPU, every other at 1 s (so that the cap's decisions are exact)."""
    monkeypatch.setattr(ad, "OUT", tmp_path)
    monkeypatch.setattr(stiff, "OUT", tmp_path)
    schemes, untimed = [], []
    run = integrate.run

    def recorded(system, x0, t0, t1, scheme, *args, **kw):
        schemes.append(scheme)
        untimed.append((scheme, t1))
        return run(system, x0, t0, t1, scheme, *args, **kw)

    monkeypatch.setattr(integrate, "run", recorded)
    def timed(f):
        schemes.clear()
        before = len(untimed)
        value = f()
        del untimed[before:]  # the run just timed
        return value, 2.0 if schemes == ["rk2"] else 1.0

    monkeypatch.setattr(stiff, "_timed", timed)
    monkeypatch.setattr(ad, "UNTIMED", untimed, raising=False)
    problem = ad.Problem(lambda: models.rod_swimmer(n_points=11, length=2.0, epsilon=1.0),
                         2e-4, 1e-5, 1e-5, "tiny", 5e-6, 1.5)
    monkeypatch.setitem(ad.PROBLEMS, "tiny", lambda: problem)
    return tmp_path / "adaptive_tiny.json"


def test_measure_skips_above_the_cap_and_resumes(ad, tiny):
    data = ad.measure("tiny", [1e-3, 1e-2, 1e-5], ["rk23", "ros34pw2"], cap=2.2)
    assert data["rk2"]["cpu"] == 2.0 and data["reference"]["dt"] == 5e-6
    # rk23's floor, 2 s x 3/2 x 2/2.5127 = 2.39 s, is above the cap from the first rtol on;
    # ros34pw2 (no floor) runs at 1e-2 (1 s) and 1e-3 (predicted 1 s x 10^(1/3) = 2.15 s), not
    # at 1e-5 (1 s x 100^(1/3) = 4.64 s, from 1e-3's 1 s).
    assert [(r["scheme"], r["rtol"]) for r in data["rows"]] == [("ros34pw2", 1e-2),
                                                                ("ros34pw2", 1e-3)]
    assert all(r["cpu_over_rk2"] == 0.5 and 0 < r["error"] < 0.1 for r in data["rows"])
    assert [(s["scheme"], s["rtol"], round(s["predicted_cpu"], 3)) for s in data["skipped"]] == [
        ("rk23", 1e-2, 2.388), ("rk23", 1e-3, 2.388), ("rk23", 1e-5, 2.388),
        ("ros34pw2", 1e-5, 4.642)]
    assert "stability floor" in data["skipped"][0]["why"]
    # Each scheme run was first warmed up once, untimed, over two first steps (2e-5 s).
    assert ad.UNTIMED == [("rk2", 2e-5), ("ros34pw2", 2e-5)]
    assert json.loads(tiny.read_text()) == json.loads(json.dumps(data))
    # Resumed with a larger cap: the measured rows are kept as they were (an edited value
    # survives, RK2's too), the skipped runs are measured now and leave the skipped list.
    saved = json.loads(tiny.read_text())
    saved["rows"][0]["error"] = 123.0
    tiny.write_text(json.dumps(saved))
    again = ad.measure("tiny", [1e-2, 1e-3, 1e-5], ["rk23", "ros34pw2"], cap=5.0)
    assert again["rows"][0]["error"] == 123.0 and again["rk2"]["cpu"] == 2.0
    assert [(r["scheme"], r["rtol"]) for r in again["rows"][2:]] == [
        ("rk23", 1e-2), ("rk23", 1e-3), ("rk23", 1e-5), ("ros34pw2", 1e-5)]
    assert again["skipped"] == []


def test_main_redo_and_bad_arguments(ad, tiny, capsys):
    assert ad.main(["--problem", "tiny", "--rtols", "1e-2", "--schemes", "ros34pw2"]) == 0
    first = json.loads(tiny.read_text())
    first["rows"][0]["error"] = 123.0
    tiny.write_text(json.dumps(first))
    assert ad.main(["--problem", "tiny", "--rtols", "1e-2", "--schemes", "ros34pw2",
                    "--redo", "ros34pw2"]) == 0
    assert json.loads(tiny.read_text())["rows"][0]["error"] < 0.1  # measured again
    for bad, word in ((["--rtols", "0"], "--rtols"), (["--cap", "-1"], "--cap"),
                      (["--problem", "rod"], "--problem")):
        with pytest.raises(SystemExit) as exit_:
            ad.main(["--problem", "tiny", *bad] if bad[0] != "--problem" else bad)
        assert exit_.value.code == 2
        assert word in capsys.readouterr().err


def test_short_steps_keep_the_step_counts_over_a_shorter_t():
    base = stiff.short_steps(1.2e-5, stiff.SHORT_T)
    assert base["rk2"] == base["euler"] == [1.2e-5]
    assert base["ros34pw2"] == [1e-3, 5e-4, 2.5e-4, 1.25e-4, 6.25e-5]
    short = stiff.short_steps(4.85e-8, 2.5e-4)  # the rod of 1201 points: T / 20
    assert short["rk2"] == short["euler"] == [4.85e-8]
    assert short["ros34pw2"] == [5e-5, 2.5e-5, 1.25e-5, 6.25e-6, 3.12e-6]
    assert short["ros34pw2-krylov"] == [2.5e-5, 1.25e-5, 6.25e-6]
    assert short.keys() == base.keys()


def test_the_committed_rod301_file_resumes_without_a_run(ad, tmp_path, monkeypatch):
    """The file written before ``--problem`` existed (no load, no code, no skipped) is read
    as it is: each of its (scheme, rtol) counts as measured and its RK2 is kept."""
    original = json.loads((ad.OUT / "adaptive_rod301.json").read_text())
    (tmp_path / "adaptive_rod301.json").write_text(json.dumps(original))
    monkeypatch.setattr(ad, "OUT", tmp_path)
    monkeypatch.setattr(stiff, "OUT", tmp_path)
    monkeypatch.setattr(stiff, "reference_state", lambda *a: (None, None))

    def no_run(*args, **kw):
        raise AssertionError("a measured run was run again")

    monkeypatch.setattr(integrate, "run", no_run)
    rows = original["rows"]
    scheme = rows[0]["scheme"]
    data = ad.measure("rod301", [r["rtol"] for r in rows if r["scheme"] == scheme], [scheme],
                      cap=60.0)
    assert data["rows"] == rows and data["rk2"] == original["rk2"]
