"""Figures a scientist can read: legends beside the data, short labels, integer iteration axes,
the eq. 15 bound as text, the printed speedup in the figure, the rod in x-y and x-z at a stated
scale."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from configs import small_rod

from parastokes import cli
from parastokes import run as runner
from parastokes.output import plots
from parastokes.output import trajectory as io

TINY = small_rod(
    parareal="max_iterations = 2",
    rest='[execution]\nexecutor = "serial"\n[output]\nformats = ["png"]\n',
)


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    root = tmp_path_factory.mktemp("plots")
    path = root / "run.toml"
    path.write_text('title = "' + "a long title " * 10 + '"\n' + TINY.replace(
        'formats = ["png"]', 'formats = ["png"]\nfigures = false'))
    assert cli.main(["run", str(path), "--out", str(root / "tiny"), "-q"]) == 0
    shutil.copytree(root / "tiny", root / "other")
    return root / "tiny"


@pytest.fixture(scope="module")
def figures(run_dir):
    """The figures of the run (by file stem) and of a comparison (``cmp_`` + stem), drawn once."""
    drawn = {}

    def keep(fig, stem, formats):
        fig.draw_without_rendering()
        drawn[("cmp_" if stem.parent.name == "cmp" else "") + stem.name] = fig
        return [stem]

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(plots, "_save", keep)
        plots.draw_run(run_dir, ["png"])
        plots.draw_comparison([run_dir, run_dir.parent / "other"], run_dir.parent / "cmp", ["png"])
    return drawn


def _overlaps(a, b) -> bool:
    return a.x0 < b.x1 and b.x0 < a.x1 and a.y0 < b.y1 and b.y0 < a.y1


def test_legends_sit_beside_the_data_with_short_labels(figures):
    for name in ("error_decay", "speedup_vs_error", "speedup_by_iteration"):
        ax = figures[name].axes[0]
        legend = ax.get_legend()
        assert not _overlaps(legend.get_window_extent(), ax.get_window_extent()), name
        assert all(len(t.get_text()) <= 25 for t in legend.get_texts()), name
        assert len(ax.get_title()) <= 60
    ticks = figures["error_decay"].axes[0].get_xticks()
    assert np.allclose(ticks, np.round(ticks))


def test_the_bound_is_text_and_the_printed_speedup_is_in_the_figure(run_dir, figures):
    summary = io.read_summary(run_dir / "summary.json")
    s = summary["speedup"]
    assert s["by_iteration"]["measured"][-1] == s["measured"]  # the number the report prints
    assert f"{s['measured']:8.3f}" in runner.speedup_table(summary)
    ax = figures["speedup_by_iteration"].axes[0]
    heights = sorted(p.get_height() for p in ax.patches)
    assert any(h == s["measured"] for h in heights)
    texts = [t.get_text() for t in ax.texts]
    assert texts == [f"≤{b:.3g}" for b in s["by_iteration"]["bound"]]
    assert ax.get_ylim()[1] < 1.5 * max(heights) + 1.5  # the bound does not flatten the bars
    assert list(ax.get_xticks()) == [1, 2]


def test_the_rod_is_drawn_in_x_y_and_x_z_with_the_stretch_stated(run_dir, figures):
    fig = figures["structure"]
    top, bottom = fig.axes[:2]
    assert top.get_ylabel().startswith("y") and bottom.get_ylabel().startswith("z (distance")
    for ax in (top, bottom):
        assert "stretched" in ax.get_title() or "true scale" in ax.get_title()
    z = io.read_trajectory(run_dir / "trajectory.h5")["bodies"]["rod_0"]["positions"][..., 2]
    low, high = bottom.get_ylim()
    assert low <= z.min() and z.max() <= high  # the distance to the wall is shown
    # comparisons: one label per run directory
    labels = [t.get_text() for t in figures["cmp_error_decay"].axes[0].get_legend().get_texts()]
    assert labels[0] == "tiny: error η^k" and labels[-1] == "other: increment η̃^k"
