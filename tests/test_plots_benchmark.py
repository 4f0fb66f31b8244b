"""Figures from ``benchmarks/parareal.py --json`` (Figs. 9 and 10): the JSON format and
``parastokes plot --benchmark``. The real benchmark is not run (minutes): its sections are replaced
by fakes returning rows of the shape the real ones return."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from bench_modules import benchmark_module

from parastokes import cli
from parastokes.output import plots

FIGURES = ("spatial_vs_temporal", "scaling_benchmark")


@pytest.fixture(scope="module")
def bench():
    with benchmark_module("parareal") as module:
        yield module


# Rows as the sections build them (numpy scalars and placeholder strings included).
STRONG = [
    (1, 1, 0.0, 0.01, 0.44, 0.022, 0.98, 0.97, 0.90),
    (2, 1, 2e-5, 0.019, 0.48, 0.037, 1.92, 1.90, 0.80),
    (2, 2, 0.0, 0.019, 0.67, 0.027, 0.98, 1.10, 0.58),
    (4, 1, 3e-5, 0.03, 0.50, 0.06, np.float64(3.7), 3.5, 3.1),
]
WEAK = [(1, 1e-4, 0.28, 0.27, 0.01, 0.285), (2, 2e-4, 0.40, 0.38, 0.017, 0.40)]
FIG10 = [
    (2, 0.92, 0.80, 0.61, 2, 2e-5, "n/a (needs 4 cores)", "-", 0.0),
    (4, 1.7, 1.5, 1.2, np.int64(3), 4e-6, 1.9, 2, 1e-15),
]


def synthetic() -> dict:
    """A benchmark JSON in the documented format, written by hand."""
    return {
        "machine": {"processor": "x86_64", "available_cores": 4},
        "scaling": {
            "strong": [
                {"cores": c, "iterations": k, "measured": m, "theoretical": t, "vs_serial": v}
                for c, k, m, t, v in [
                    (1, 1, 0.97, 0.98, 0.9),
                    (2, 1, 1.9, 1.92, 1.6),
                    (4, 1, 3.5, 3.7, 3.1),
                    (2, 2, 1.1, 0.98, None),
                    (4, 2, 1.8, 1.9, 1.5),
                ]
            ],
            "weak": [
                {"cores": c, "runtime": r, "parallel_sweep": p, "model": m}
                for c, r, p, m in [
                    (1, 0.28, 0.27, 0.285),
                    (2, 0.40, 0.38, 0.40),
                    (4, 0.7, 0.6, 0.7),
                ]
            ],
        },
        "fig10": [
            {
                "cores": 2,
                "spatial_threads": 0.9,
                "spatial_blocks": 0.8,
                "parareal": 0.6,
                "both": None,
            },
            {
                "cores": 4,
                "spatial_threads": 1.7,
                "spatial_blocks": 1.5,
                "parareal": 1.2,
                "both": 1.9,
            },
        ],
    }


def check_figures(out: Path, names=FIGURES) -> None:
    for name in names:
        for fmt in ("png", "pdf"):
            path = out / f"{name}.{fmt}"
            assert path.is_file() and path.stat().st_size > 1000, path


def test_cli_draws_the_benchmark_figures(tmp_path):
    path = tmp_path / "bench.json"
    path.write_text(json.dumps(synthetic()))
    out = tmp_path / "figs"
    assert cli.main(["plot", "--benchmark", str(path), "--out", str(out), "-q"]) == 0
    check_figures(out)
    written = plots.draw_benchmark(path, tmp_path / "again", ["png"])
    assert sorted(p.name for p in written) == ["scaling_benchmark.png", "spatial_vs_temporal.png"]


def test_a_file_with_one_section_draws_its_figure_only(tmp_path):
    data = synthetic()
    del data["scaling"]
    path = tmp_path / "fig10.json"
    path.write_text(json.dumps(data))
    assert cli.main(["plot", "--benchmark", str(path), "-q"]) == 0  # --out: the file's folder
    check_figures(tmp_path, ["spatial_vs_temporal"])
    assert not (tmp_path / "scaling_benchmark.png").exists()


@pytest.mark.parametrize(
    "content, message",
    [
        (None, "not found"),
        ("{not json", "not a JSON file"),
        ('{"machine": {}}', "no 'scaling' or 'fig10' section"),
        ('{"fig10": [{"speedup": 1.0}]}', "not in the format"),
    ],
)
def test_bad_benchmark_files_exit_2(tmp_path, capsys, content, message):
    path = tmp_path / "bench.json"
    if content is not None:
        path.write_text(content)
    assert cli.main(["plot", "--benchmark", str(path), "--out", str(tmp_path)]) == 2
    assert message in capsys.readouterr().err


def test_plot_needs_directories_or_a_benchmark(tmp_path, capsys):
    assert cli.main(["plot"]) == 2
    assert "--benchmark" in capsys.readouterr().err
    path = tmp_path / "bench.json"
    path.write_text(json.dumps(synthetic()))
    assert cli.main(["plot", str(tmp_path), "--benchmark", str(path)]) == 2
    assert "not both" in capsys.readouterr().err


def test_benchmark_json_has_the_plotted_format(bench, tmp_path):
    doc = bench.benchmark_json(
        {"cores": 4},
        {"scaling": {"strong": STRONG, "weak": WEAK, "t_strong": 4e-4}, "fig10": FIG10},
    )
    json.dumps(doc, allow_nan=False)  # plain JSON: no numpy scalars, no NaN
    strong = doc["scaling"]["strong"]
    assert strong[3] == {
        "cores": 4,
        "iterations": 1,
        "error": 3e-5,
        "serial_sweeps": 0.03,
        "parallel_sweeps": 0.50,
        "serial_share": 0.06,
        "theoretical": 3.7,
        "measured": 3.5,
        "vs_serial": 3.1,
    }
    assert type(strong[3]["theoretical"]) is float
    assert doc["scaling"]["weak"][1]["runtime"] == 0.40
    assert doc["scaling"]["weak"][1]["model"] == 0.40
    assert doc["scaling"]["t_strong"] == 4e-4
    first, second = doc["fig10"]
    assert first["both"] is None and first["both_iterations"] is None
    assert (first["cores"], first["spatial_threads"], first["spatial_blocks"]) == (2, 0.92, 0.80)
    assert first["parareal"] == 0.61
    assert second["both"] == 1.9 and type(second["iterations"]) is int
    path = tmp_path / "bench.json"
    path.write_text(json.dumps(doc))
    assert len(plots.draw_benchmark(path, tmp_path, ["png", "pdf"])) == 4
    check_figures(tmp_path)


def test_script_writes_json_of_the_sections_that_ran(bench, tmp_path, monkeypatch):
    monkeypatch.setattr(
        bench, "scaling", lambda args, pools: ("strong ...", {"strong": STRONG, "weak": WEAK})
    )
    monkeypatch.setattr(bench, "fig10", lambda args, pools: ("fig10 ...", FIG10))
    md, js = tmp_path / "out.md", tmp_path / "out.json"
    argv = ["--quick", "--sections", "scaling", "fig10", "--cores", "4"]
    assert bench.main([*argv, "--out", str(md), "--json", str(js)]) == 0
    doc = json.loads(js.read_text())
    assert set(doc) == {"machine", "scaling", "fig10", "total_time"}
    assert doc["machine"]["cores"] == 4 and doc["machine"]["quick"] is True
    assert len(doc["scaling"]["strong"]) == len(STRONG) and len(doc["fig10"]) == len(FIG10)
    text = md.read_text()
    assert "## scaling\n\nstrong ..." in text and "## fig10\n\nfig10 ..." in text
