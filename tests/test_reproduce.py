"""validation.reproduce (the paper at full scale) on tiny versions of its runs.

The plan, the cost arithmetic, the shared serial reference (bit-identical to the runner's own, and
resumed slice by slice), the record of a run, the scheduler's refusal to overwrite, and the page's
generated blocks. The runs use ``experiments/quick`` (same file names) with two short slices.
"""

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from parastokes import config, parareal
from parastokes import run as runner
from parastokes.output import trajectory as io
from validation import reproduce, reproduce_report

REPO = Path(__file__).parents[1]
TINY = ("time.t1=0.0004", "parareal.n_slices=2")


def _layout(root: Path) -> reproduce.Layout:
    return reproduce.Layout(root, REPO / "experiments" / "quick", TINY)


def _job(name: str) -> reproduce.Job:
    return {j.name: j for j in reproduce.plan()}[name]


# ---- plan and cost -----------------------------------------------------------------------------
def test_plan_names_configs_that_exist_and_references_that_precede_their_runs():
    jobs = reproduce.plan()
    names = [j.name for j in jobs]
    assert len(set(names)) == len(names)
    for i, job in enumerate(jobs):
        assert (REPO / "experiments" / job.config).exists(), job.config
        if not job.is_reference:
            assert names.index(job.reference) < i, job.name


def test_select_defaults_to_required_runs_and_brings_references_along():
    jobs = reproduce.plan()
    default = {j.name for j in reproduce.select(jobs, None)}
    assert {"table7_g1", "table8_g3", "table3_g4_n6", "table4_g3", "table5_g1"} <= default
    assert not default & {"table3_g1", "table6_eps3", "table6_eps2", "s514_five_rods"}
    everything = {j.name for j in reproduce.select(jobs, None, optional=True)}
    assert {"table3_g1", "table6_eps3"} <= everything and "table6_eps2" not in everything
    only = [j.name for j in reproduce.select(jobs, ["fig13", "table4_g2"])]
    assert only == ["ref_rod_eps5", "ref_table8", "table8_g1", "table8_g3", "table8_g2",
                    "table4_g2"]  # plan order: the cheaper runs first
    with pytest.raises(ValueError, match="table9_g1"):
        reproduce.select(jobs, ["table9_g1"])


def test_work_counts_the_fine_steps_and_coarse_calls_of_algorithm_1():
    cfg, resolved = config.load(REPO / "experiments" / "table4_g1.toml")
    assert resolved.fine_steps == 25_000
    ref = reproduce.work(cfg, resolved, reference=True)
    assert ref == {"fine_steps": 40 * 25_000, "coarse_calls": 0}
    run = reproduce.work(cfg, resolved, reference=False)
    # K = 4: fine sweeps on slices k..40 (eq. 10), serial sweeps k = 0..4 (eqs. 9, 11), + probe
    assert run["fine_steps"] == (40 + 39 + 38 + 37 + 2) * 25_000
    assert run["coarse_calls"] == 40 + 39 + 38 + 37 + 36 + 2


def test_speedup_curve_steps_follow_the_first_iteration_reaching_each_error():
    curve = reproduce.speedup_curve([1e-4, 1e-6, 2e-6, 1e-9], 0.01, 40)
    assert curve["speedup"] == [parareal.speedup(0.01, 1.0, k, 40) for k in range(1, 5)]
    assert [s["iterations"] for s in curve["steps"]] == [1, 2, 4]  # k = 3 is no better than 2
    record = {"errors": [1e-4, 1e-6, 2e-6, 1e-9], "speedup_40": curve}
    assert reproduce_report.speedup_at(record, 1e-3) == curve["speedup"][0]
    assert reproduce_report.speedup_at(record, 1e-6) == curve["speedup"][1]
    assert reproduce_report.speedup_at(record, 1e-8) == curve["speedup"][3]
    assert np.isnan(reproduce_report.speedup_at(record, 1e-10))


def test_dry_run_prints_the_cost_of_every_job(tmp_path, capsys):
    jobs = reproduce.select(reproduce.plan(), ["table4_g4"])
    rows = reproduce.dry_run(jobs, _layout(tmp_path))
    out = capsys.readouterr().out
    assert "ref_rod_eps5" in out and "table4_g4" in out and "CPU hours" in out
    assert rows[0]["fine_steps"] == 400 and rows[0]["cpu_hours_1core"] > 0
    assert rows[1]["core_hours_40cores"] > 0 and not any(r["done"] for r in rows)


# ---- the runs ----------------------------------------------------------------------------------
class _StopAfter(reproduce.ProgressFile):
    """Interrupts the serial reference after ``n`` slices, as Ctrl-C or a kill would."""

    def __init__(self, path: Path, n: int) -> None:
        super().__init__(path)
        self.n = n

    def advance(self) -> None:
        super().advance()
        if self.state["done"] == self.n:
            raise KeyboardInterrupt


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """The reference (interrupted once, then resumed) and Table 4 G⁴ run through ``run_job``."""
    root = tmp_path_factory.mktemp("repro")
    layout = _layout(root)
    ref = _job("ref_rod_eps5")
    cfg, resolved = reproduce.load_config(ref, layout)
    directory = layout.directory(ref)
    directory.mkdir(parents=True)
    with pytest.raises(KeyboardInterrupt):
        reproduce.serial_reference(cfg, resolved, directory, _StopAfter(directory / "p.json", 1))
    partial = io.load_arrays(directory / "partial.npz")[0]
    reproduce.run_job(ref, layout)
    run = _job("table4_g4")
    reproduce.run_job(run, layout)
    return layout, partial


def test_reference_resumes_after_a_stop_and_equals_the_runners_own(finished, tmp_path):
    layout, partial = finished
    assert partial["done"] == 1
    _, ours = io.load_arrays(layout.directory(_job("ref_rod_eps5")) / runner.REFERENCE)
    cfg, resolved = reproduce.load_config(_job("ref_rod_eps5"), layout)
    runner.execute(cfg, resolved, tmp_path)
    _, theirs = io.load_arrays(tmp_path / runner.REFERENCE)
    assert np.array_equal(ours["states"], theirs["states"])


def test_run_reuses_the_reference_and_matches_a_plain_runner_run(finished, tmp_path):
    layout, _ = finished
    run = _job("table4_g4")
    log = json.loads((layout.directory(run) / "progress.json").read_text())
    record = json.loads(layout.done(run).read_text())
    cfg, resolved = reproduce.load_config(run, layout)
    plain = runner.execute(cfg, resolved, tmp_path)  # computes its own reference
    assert record["errors"] == plain["errors"] and record["errors"][0] > 0
    assert [r["error"] for r in log["iterations"]] == plain["errors"]
    ref_wall = json.loads(layout.done(_job("ref_rod_eps5")).read_text())["serial_fine_s"]
    assert record["one_core"]["serial_fine_s"] == ref_wall  # reloaded, not recomputed
    probe = record["probe"]
    assert probe["n_auxiliary"] == 1 and probe["method"] == reproduce.PROBE_METHOD
    assert record["gamma_ratio"] == probe["gamma_ratio"] > 0
    assert record["speedup_40"]["n_cores"] == 40


def test_a_finished_job_is_skipped(finished, capsys):
    layout, _ = finished
    reproduce.run_job(_job("table4_g4"), layout)
    assert "already done" in capsys.readouterr().out


def test_without_resume_existing_work_is_refused(finished):
    layout, _ = finished
    argv = ["--out", str(layout.root), "--experiments", str(layout.experiments),
            "--only", "table4_g4", *(f"--set={s}" for s in TINY)]
    assert reproduce.main(argv) == 2
    assert layout.done(_job("table4_g4")).exists()  # nothing lost


def test_status_shows_done_and_not_started(finished):
    layout, _ = finished
    jobs = reproduce.select(reproduce.plan(), ["table4_g4", "table4_g1"])
    lines = reproduce.status_lines(jobs, layout)
    states = {line.split()[0]: line.split()[2] for line in lines[1:]}
    assert states == {"ref_rod_eps5": "done", "table4_g4": "done", "table4_g1": "not"}


def test_collect_writes_records_figures_and_the_page(finished, tmp_path):
    layout, _ = finished
    docs = tmp_path / "docs"
    docs.mkdir()
    shutil.copy(REPO / "docs" / "reproduction.md", docs)
    reproduce_report.collect(reproduce.plan(), layout, docs)
    record = json.loads((docs / "reproduction" / "table4_g4.json").read_text())
    assert record["config"] == "experiments/quick/table4_g4.toml"
    assert (docs / "reproduction" / "fig6.png").stat().st_size > 0
    assert (docs / "reproduction" / "fig5.png").stat().st_size > 0  # its G_{ε⁰,τ_c} line
    page = (docs / "reproduction.md").read_text()
    assert f"| G⁴ (`table4_g4`) | 1 | {record['errors'][0]:.2e}" in page
    assert "| `table4_g4` | fig6 | done (" in page
    assert "| `table4_g1` | fig6 | not started |" in page
    assert "runs not finished: table4_g1, table4_g2, table4_g3 | pending" in page

    # on a machine without the reference's files (lost --out, fresh clone), the runs vouch for it
    bare = reproduce.Layout(tmp_path / "bare", layout.experiments, layout.overrides)
    again = reproduce_report.status_table(reproduce.plan(), bare,
                                          reproduce_report.load_records(docs / "reproduction"))
    assert "| `ref_rod_eps5` | fig5 | done (by the records of table4_g4) |" in again
    assert "| `ref_rod_eps7` | fig7 | not started |" in again  # none of its runs is recorded
    # computed again there (for a run not yet recorded): still done, its progress shown beside
    partial = bare.directory(_job("ref_rod_eps5"))
    partial.mkdir(parents=True)
    (partial / "progress.json").write_text(json.dumps({"phase": "serial", "done": 3, "total": 40}))
    again = reproduce_report.status_table(reproduce.plan(), bare,
                                          reproduce_report.load_records(docs / "reproduction"))
    assert ("| `ref_rod_eps5` | fig5 | done (by the records of table4_g4) | "
            "again here (started): serial 3/40 |") in again

    def stable(text):  # all but the time stamp of the status table
        return [line for line in text.splitlines() if not line.startswith("As of ")]

    reproduce_report.collect(reproduce.plan(), layout, docs)  # idempotent
    assert stable((docs / "reproduction.md").read_text()) == stable(page)


@pytest.mark.slow
def test_scheduler_runs_a_reference_and_its_run_in_child_processes(tmp_path):
    argv = [sys.executable, "-m", "validation.reproduce", "--out", str(tmp_path), "--experiments",
            str(REPO / "experiments" / "quick"), "--only", "table4_g4", "--jobs", "2",
            *(f"--set={s}" for s in TINY)]
    subprocess.run(argv, cwd=REPO, check=True, timeout=600)
    layout = _layout(tmp_path)
    assert layout.done(_job("table4_g4")).exists()
    assert "reloaded" in layout.log(_job("table4_g4")).read_text()
    sched = json.loads(layout.scheduler.read_text())
    assert sched["state"] == "finished" and sched["running"] == {}


def test_an_interrupted_parareal_run_resumes_to_the_same_iterates(finished, tmp_path, monkeypatch):
    layout, _ = finished
    run = _job("table4_g4")
    other = reproduce.Layout(tmp_path, layout.experiments, layout.overrides)
    ref_dir = other.directory(_job("ref_rod_eps5"))
    shutil.copytree(layout.directory(_job("ref_rod_eps5")), ref_dir)

    class StopAtFirstIteration(reproduce.ProgressFile):
        def iteration(self, k, increment, error, elapsed):
            super().iteration(k, increment, error, elapsed)
            raise KeyboardInterrupt

    monkeypatch.setattr(reproduce, "ProgressFile", StopAtFirstIteration)
    with pytest.raises(KeyboardInterrupt):
        reproduce.run_job(run, other)
    assert not other.done(run).exists()
    assert (other.directory(run) / runner.CHECKPOINT).exists()  # iteration 1 kept
    monkeypatch.undo()
    started = []
    monkeypatch.setattr(
        reproduce.ProgressFile, "start", lambda self, what, total: started.append((what, total))
    )
    reproduce.run_job(run, other)
    cfg, _ = reproduce.load_config(run, other)
    assert started == [("parareal", cfg.parareal.max_iterations - 1)]  # only what is left
    resumed = json.loads(other.done(run).read_text())
    original = json.loads(layout.done(run).read_text())
    assert resumed["errors"] == original["errors"]
    assert resumed["increments"] == original["increments"]


@pytest.mark.parametrize(
    ("name", "overrides"),
    [
        ("table4_g3", TINY),  # Lagrange in ε, a and Richardson: 30 auxiliary solvers
        ("table6_eps3", TINY),  # on the coarse grid σ_c = 6σ_f (grid transfer)
        ("table8_g2", ("time.t1=1.0", "parareal.n_slices=2")),  # vesicle, RK4, Richardson
    ],
)
def test_probe_times_every_auxiliary_solver_of_each_kind_of_coarse_solver(name, overrides):
    from parastokes.config import build

    layout = reproduce.Layout(Path("unused"), REPO / "experiments" / "quick", overrides)
    cfg, resolved = reproduce.load_config(_job(name), layout)
    times = parareal.time_points(cfg.time.t0, cfg.time.t1, cfg.parareal.n_slices)
    setup = build(cfg, resolved)
    found = reproduce.probe(setup, times, setup.system.initial_state(), repeats=2)
    assert found["n_auxiliary"] == resolved.n_auxiliary == len(found["auxiliary_slice_s"][0])
    # on 40 cores: the slowest auxiliary plus the combination, median over the repeats
    ratios = [
        (max(aux) + over) / fine
        for aux, over, fine in zip(
            found["auxiliary_slice_s"], found["overhead_s"], found["fine_slice_s"], strict=True
        )
    ]
    assert found["gamma_ratio"] == pytest.approx(float(np.median(ratios)), rel=1e-12)
    assert 0 < found["gamma_ratio"] < 1


def test_collect_measures_again_a_probe_made_by_the_older_method(finished, monkeypatch):
    """A run probed by the first, wall-clock method is probed again at collect; the old probe is
    kept beside the new one."""
    layout, _ = finished
    run = _job("table4_g4")
    path = layout.directory(run) / "probe.json"
    old = {"gamma_ratio": 0.5, "n_auxiliary": 1, "fine_slice_times": [1.0, 1.0]}
    path.write_text(json.dumps(old))
    found = reproduce.current_probe(run, layout)
    assert found["method"] == reproduce.PROBE_METHOD and found["gamma_ratio"] != 0.5
    assert json.loads(path.with_name("probe.wallclock-v1.json").read_text()) == old
    calls = []
    monkeypatch.setattr(reproduce, "probe", lambda *a, **k: calls.append(a))
    assert reproduce.current_probe(run, layout) == found and not calls  # current: kept


@pytest.fixture
def repo(tmp_path, monkeypatch):
    """A git repository holding a copy of docs/reproduction.md; returns ``git(*args) -> stdout``."""
    (tmp_path / "docs").mkdir()
    shutil.copy(REPO / "docs" / "reproduction.md", tmp_path / "docs")
    for key in ("AUTHOR", "COMMITTER"):
        monkeypatch.setenv(f"GIT_{key}_NAME", "t")
        monkeypatch.setenv(f"GIT_{key}_EMAIL", "t@t")

    def git(*args):
        return subprocess.run(["git", *args], cwd=tmp_path, check=True, capture_output=True,
                              text=True).stdout

    git("init", "-q")
    git("commit", "-q", "--allow-empty", "-m", "0")
    return git


def test_collect_commit_commits_only_the_page_and_its_records(finished, tmp_path, repo):
    layout, _ = finished
    (tmp_path / "other.txt").write_text("not ours")
    argv = ["--out", str(layout.root), "--experiments", str(layout.experiments),
            "--docs", str(tmp_path / "docs"), "--collect", "--commit"]
    assert reproduce.main(argv) == 0
    assert "full-scale runs collected (table4_g4)" in repo("log", "-1", "--format=%s")
    committed = repo("show", "--name-only", "--format=", "HEAD").split()
    assert "docs/reproduction/table4_g4.json" in committed and "other.txt" not in committed


def test_collect_commit_without_finished_runs_commits_the_status(tmp_path, repo):
    argv = ["--out", str(tmp_path / "runs"), "--docs", str(tmp_path / "docs"), "--collect",
            "--commit"]
    assert reproduce.main(argv) == 0
    subject = repo("log", "-1", "--format=%s").strip()
    assert subject == "docs/reproduction: full-scale runs collected (status)"
    assert repo("show", "--name-only", "--format=", "HEAD").split() == ["docs/reproduction.md"]


@pytest.mark.parametrize(
    ("done", "total", "iterations", "shown"),
    [(2, 4, 2, "parareal 2/4"), (0, 3, 1, "parareal 1/4"), (1, 3, 2, "parareal 2/4")],
)
def test_status_counts_the_iterations_of_earlier_sessions(tmp_path, done, total, iterations, shown):
    """A resumed runner reports only the iterations left; --status shows them out of the whole."""
    layout = _layout(tmp_path)
    job = _job("table4_g4")
    layout.directory(job).mkdir(parents=True)
    rows = [{"k": k, "increment": 1e-3, "error": 10.0**-k, "elapsed": 1.0} for k in range(1, 3)]
    progress = {"phase": "parareal", "done": done, "total": total, "iterations": rows[:iterations]}
    (layout.directory(job) / "progress.json").write_text(json.dumps(progress))
    text = reproduce.progress_text(job, layout, "running")
    assert text.startswith(shown + "  η^k: 1.00e-01")
    kept = layout.directory(job) / "checkpoint.solves"
    kept.mkdir()
    for name in ("fine-k3-n3", "fine-k3-n4", "coarse-k2-n40"):
        (kept / f"{name}.npz").touch()
    text = reproduce.progress_text(job, layout, "running")
    assert text.startswith(shown) and text.endswith("(next: 2 fine, 1 coarse solves kept)")


def test_collect_refuses_only(tmp_path, capsys):
    # --collect regenerates the page from every finished run: --only cannot narrow it
    with pytest.raises(SystemExit) as info:
        reproduce.main(["--out", str(tmp_path), "--collect", "--only", "fig5"])
    assert info.value.code == 2
    assert "--collect gathers every finished run" in capsys.readouterr().err


# ---- the page's prose against the committed records ----------------------------------------------

_SUP = {"¹": 1, "²": 2, "³": 3, "⁴": 4}


def _quoted(value: str, exact: float) -> bool:
    """``value`` is ``exact`` rounded to the digits it shows."""
    digits = len(value.split("e")[0].replace(".", "")) - 1
    return float(value) == float(f"{exact:.{digits}e}")


def test_the_hand_written_errors_and_cost_ratios_of_each_run_are_its_records():
    """The prose of docs/reproduction.md states each run's errors as "Table T G^i (...) finished
    ... UTC: η¹ = ..., η² = ..." and its cost as "Its γ_G/γ_F is ... from the probe": those
    numbers are typed by hand, so they are checked against the committed records."""
    page = (REPO / "docs" / "reproduction.md").read_text()
    records = reproduce_report.load_records(REPO / "docs" / "reproduction")
    opening = re.compile(r"Table (\d) (?:G([¹²³⁴])|for ε⁰ = (\d)σ_f) \((?:[^()]|\([^()]*\))*\) "
                         r"finished [^.]*? UTC:((?:\s*η[¹²³⁴] = [0-9.]+e-\d+,?(?: and)?)+)")
    stated = set()
    for paragraph in page.split("\n\n"):
        for table, g, eps, errors in opening.findall(paragraph):
            name = f"table{table}_g{_SUP[g]}" if g else f"table{table}_eps{eps}"
            record = records[name]
            for k, value in re.findall(r"η([¹²³⁴]) = ([0-9.]+e-\d+)", errors):
                assert _quoted(value, record["errors"][_SUP[k] - 1]), (name, k, value)
            stated.add(name)
            if ratio := re.search(r"Its γ_G/γ_F is ([0-9.]+) from the probe", paragraph):
                assert float(ratio[1]) == round(record["gamma_ratio"], len(ratio[1]) - 2), name
    # every extrapolated rod run of several iterations is written up this way
    assert stated == {n for n in records if re.fullmatch(r"table[3-6]_(g[123]|eps\d)", n)}
