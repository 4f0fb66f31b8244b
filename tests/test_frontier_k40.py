"""benchmarks/frontier.py's ``--k40``: the analogue's K checked on 40 slices. F's serial solution
slice by slice (bit for bit ``parareal.serial_solution``, resumed from its last slice), the
resumable Parareal run whose kept iterates give eta^k as ``parareal.run`` measures it, and the
summary's K (F's own error counted) and speedups. A rod of 21 nodes over 40 slices of 5e-5 s."""

from __future__ import annotations

import json
import types

import numpy as np
import pytest
from bench_modules import benchmark_module

from parastokes import parareal
from parastokes.parareal.checkpoint import CheckpointMismatch

LABEL = "ros34pw2 2.5e-5"


@pytest.fixture
def frontier(tmp_path, monkeypatch):
    """The module with a tiny problem ``tiny`` (8-slice analogue, slices of 5e-5 s) whose files
    go under ``tmp_path``."""
    with benchmark_module("frontier") as module:
        monkeypatch.setattr(module, "OUT", tmp_path / "frontier")
        monkeypatch.setattr(module, "K40_WORK", tmp_path / "k40")
        monkeypatch.setitem(module.PROBLEMS, "tiny", module.Problem(
            "a tiny rod", {**module.ROD, "n_points": 21, "length": 4}, ("rk2", 1e-5), 5e-5, 8,
            1e-6, 1.0, ("rk4", 5e-6), (("rk2", 1e-5),)))
        monkeypatch.setitem(module.CANDIDATES, "tiny", {LABEL: module.Candidate(
            "implicit", {"scheme": "ros34pw2", "dt": 2.5e-5})})
        yield module


def _setup(frontier):
    return frontier.build(frontier.k40_problem("tiny"), frontier.CANDIDATES["tiny"][LABEL].coarse)


def test_k40_problem_is_forty_slices_of_the_analogues_length(frontier):
    for name, t1 in (("table4", 1.0), ("rod601_long", 0.1), ("tiny", 40 * 5e-5)):
        p = frontier.k40_problem(name)
        assert (p.slices, p.slice_length) == (40, frontier.PROBLEMS[name].slice_length)
        assert p.t1 == pytest.approx(t1)
        assert (p.fine, p.target) == (frontier.PROBLEMS[name].fine, frontier.PROBLEMS[name].target)


def test_reference_is_the_serial_solution_and_resumes_from_its_last_slice(frontier, tmp_path):
    setup, problem = _setup(frontier), frontier.k40_problem("tiny")
    work = tmp_path / "ref"
    work.mkdir()
    full = frontier.k40_reference(setup, problem, work)
    expected = parareal.serial_solution(setup.fine, setup.system.initial_state(), 0.0, problem.t1,
                                        40)
    assert np.array_equal(full, expected)
    assert json.loads((work / "reference.json").read_text())["slices_done"] == 40
    # a run killed after slice 37: the rest is computed again, the done slices are not
    saved = full.copy()
    saved[38:] = np.nan
    np.save(work / "reference.npy", saved)
    (work / "reference.json").write_text(json.dumps({"slices_done": 37, "cpu": 1.0}))
    calls = []

    def fine(a, b, x):
        calls.append(a)
        return setup.fine(a, b, x)

    again = frontier.k40_reference(types.SimpleNamespace(fine=fine, system=setup.system),
                                   problem, work)
    assert len(calls) == 3 and calls[0] == pytest.approx(37 * 5e-5)
    assert np.array_equal(again, expected)
    assert np.array_equal(np.load(work / "reference.npy"), expected)


def test_kept_iterates_give_the_runs_own_errors_and_a_resumed_run_continues(frontier, tmp_path):
    setup, problem = _setup(frontier), frontier.k40_problem("tiny")
    x0 = setup.system.initial_state()
    reference = parareal.serial_solution(setup.fine, x0, 0.0, problem.t1, 40)
    direct = parareal.run(setup.fine, setup.coarse, x0, t0=0.0, t1=problem.t1, n_slices=40,
                          tol=0.0, max_iterations=3, reference=reference)
    work = tmp_path / "par"
    work.mkdir()
    frontier.k40_parareal(setup, problem, 2, work, {"label": LABEL})
    frontier.k40_parareal(setup, problem, 3, work, {"label": LABEL})  # resumed at iteration 3
    record = json.loads((work / "iterates.json").read_text())
    assert sorted(record["increments"]) == ["1", "2", "3"]
    exact = {"rel": 1e-12, "abs": 0.0}  # (eta ~ 1e-8: approx's default abs would hide a swap)
    assert [record["increments"][k] for k in "123"] == pytest.approx(direct.increments, **exact)
    iterates = [np.load(work / f"iterate_{k}.npy") for k in (1, 2, 3)]
    assert np.array_equal(iterates[-1], direct.states[-1])
    assert frontier.k40_errors(reference, iterates) == pytest.approx(direct.errors, **exact)
    with pytest.raises(CheckpointMismatch):
        frontier.k40_parareal(setup, problem, 3, work, {"label": "another G"})


@pytest.mark.slow  # (two worker processes start and compile: a minute on a loaded machine)
def test_worker_processes_give_the_same_iterates(frontier, tmp_path):
    setup, problem = _setup(frontier), frontier.k40_problem("tiny")
    for workers in (1, 2):
        (tmp_path / str(workers)).mkdir()
        frontier.k40_parareal(setup, problem, 1, tmp_path / str(workers), {}, workers=workers)
    assert np.array_equal(np.load(tmp_path / "1" / "iterate_1.npy"),
                          np.load(tmp_path / "2" / "iterate_1.npy"))
    record = json.loads((tmp_path / "2" / "iterates.json").read_text())
    assert list(record["increments"]) == ["1"] and record["increments"]["1"] > 0


def _fake_run(frontier, errors, slices_done=40):
    """The analogue's results (F's own error 2^-22, the fastest serial run twice cheaper than F)
    and a 40-slice run whose iterates at T lie exactly ``errors`` (relative) from F's."""
    out = frontier.OUT
    out.mkdir(parents=True)
    analogue = {"problem": {"title": "a tiny rod", "target": 1e-6, "fine": ["rk2", 1e-5]},
                "serial": [{"scheme": "rk2", "dt": 1e-5, "error": 2.0**-22, "cpu_per_time": 4.0},
                           {"scheme": "rk4", "dt": 2e-5, "error": 1e-9, "cpu_per_time": 2.0}],
                "candidates": {LABEL: {"family": "implicit", "coarse": {}, "alpha": 0.05,
                                       "n_auxiliary": 1, "errors": [1e-5, 1e-7]}}}
    (out / "tiny.json").write_text(json.dumps(analogue))
    work = frontier.K40_WORK / "tiny"
    work.mkdir(parents=True)
    reference = np.ones((41, 4, 3))
    np.save(work / "reference.npy", reference)
    (work / "reference.json").write_text(json.dumps({"slices_done": slices_done, "cpu": 2.0}))
    for k, error in enumerate(errors, start=1):
        np.save(work / f"iterate_{k}.npy", reference[-1] * (1.0 + error))
    (work / "iterates.json").write_text(json.dumps(
        {"increments": {str(k): 0.5 for k in range(1, len(errors) + 1)}, "cpu": 3.0}))
    return work


def test_summary_counts_f_own_error_in_k_and_scales_to_the_best_serial(frontier):
    """eta^2 = 8e-7 alone reaches 1e-6, plus F's own 2.4e-7 it does not: K = 3 (the analogue's
    eta^2 = 1e-7 gave 2). The speedups are eq. 14 / the pipelined formula with the analogue's
    alpha, halved (the fastest serial run costs half of F)."""
    work = _fake_run(frontier, [1e-5, 8e-7, 1e-7])
    s = frontier.k40_summary("tiny", LABEL, work)
    assert s["errors"] == pytest.approx([1e-5, 8e-7, 1e-7], rel=1e-9)
    assert (s["K"], s["analogue"]["K"], s["slices"], s["iterations"]) == (3, 2, 40, [1, 2, 3])
    assert s["fine_own_error"] == 2.0**-22
    pipelined = 1 / ((1 + 3 / 40) * 0.05 + 3 / 40)
    assert s["speedups"]["vs_F"]["pipelined"] == pytest.approx(pipelined)
    assert s["speedups"]["vs_best"]["pipelined"] == pytest.approx(pipelined / 2)
    assert s["speedups"]["vs_best"]["standard"] == pytest.approx(1 / (4 * 0.05 + 3 / 40) / 2)


def test_summary_waits_for_the_whole_reference(frontier):
    s = frontier.k40_summary("tiny", LABEL, _fake_run(frontier, [1e-5, 1e-7], slices_done=39))
    assert (s["errors"], s["K"], s["speedups"]) == (None, None, None)
    assert s["increments"] == [0.5, 0.5] and s["cpu"]["reference_slices"] == 39


def test_cli_k40_summary_writes_the_json(frontier):
    _fake_run(frontier, [1e-5, 1e-7])
    frontier.main(["--k40", "tiny", LABEL, "2", "--k40-part", "summary"])
    written = json.loads((frontier.OUT / "k40_tiny.json").read_text())
    assert written["K"] == 2 and written["label"] == LABEL
    assert written["errors"] == pytest.approx([1e-5, 1e-7], rel=1e-9)
