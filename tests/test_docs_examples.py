"""Every code example of the documentation runs (docs/documentation.md, "Every example is a test").

- The ``python`` blocks of README.md and docs/*.md: each page's runnable blocks run in order in
  one fresh interpreter, in an empty folder, as a reader would paste them; blocks marked as not
  run are checked without running (their imports, the parastokes names they use and the arguments
  of their calls). The markers: tests/doc_blocks.py. docs/extending.md's walk-through blocks are
  tests/test_extending.py's.
- The gallery's scripts (docs/gallery/plot_*.py): each runs in a fresh interpreter in an empty
  folder with matplotlib's non-interactive backend, must draw a figure, and the numbers it prints
  are checked against what its page says.
"""

from __future__ import annotations

import itertools
import json
import os
import re
import shlex
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from doc_blocks import PAGES, ROOT, WALK_THROUGH, Block, blocks, python_blocks, static_problems

GALLERY = ROOT / "docs" / "gallery"
SCRIPTS = sorted(GALLERY.glob("plot_*.py"))

#: Runs blocks the way a reader pastes them: one namespace, tracebacks naming the page's lines;
#: ``python -c`` (no script file), so that process pools do not import it again in each worker.
_DRIVER = """
import contextlib, io, json, sys, traceback
namespace = {"__name__": "__main__"}
printed = {}
for label, code in json.load(open("blocks.json")):
    out = io.StringIO()
    try:
        with contextlib.redirect_stdout(out):
            exec(compile(code, label, "exec"), namespace)
    except BaseException:
        traceback.print_exc()
        sys.exit(f"the example at {label} failed; it printed:\\n{out.getvalue()}")
    printed[label] = out.getvalue()
json.dump(printed, open("printed.json", "w"))
"""

#: Runs a gallery script as sphinx-gallery does (as __main__) and saves the figures it leaves open.
_GALLERY_RUNNER = """
import runpy, sys
import matplotlib.pyplot as plt
runpy.run_path(sys.argv[1], run_name="__main__")
for number in plt.get_fignums():
    plt.figure(number).savefig(f"figure_{number}.png", dpi=60)
"""


def _environment(folder: Path) -> dict[str, str]:
    return dict(os.environ, PYTHONPATH=f"{folder}{os.pathsep}{ROOT}", MPLBACKEND="Agg")


def _run(args: list[str], folder: Path, timeout: float = 600) -> subprocess.CompletedProcess:
    done = subprocess.run(args, cwd=folder, env=_environment(folder), capture_output=True,
                          text=True, timeout=timeout)
    assert done.returncode == 0, f"{shlex.join(args)}\n{done.stdout[-3000:]}{done.stderr[-3000:]}"
    return done


# ---- the pages -------------------------------------------------------------------------------
def _pages_with_runnable_blocks() -> list[Path]:
    return [page for page in PAGES if any(b.runs for b in blocks(page))]


def test_every_python_block_is_run_or_marked():
    """A page's Python block runs, or says why not; walk-through markers only where
    tests/test_extending.py reads them; a marker of an unknown kind is a typo."""
    known = {"skip", "quick", "setup", "after", "file", "prints", *WALK_THROUGH, "shell"}
    for block in python_blocks():
        assert set(block.markers) <= known, f"{block.label}: unknown marker {block.markers}"
        if set(block.markers) & set(WALK_THROUGH):
            assert block.page.name == "extending.md", f"{block.label}: walk-through marker"
        if "skip" in block.markers:
            assert block.marker("skip").strip(), f"{block.label}: a skip says why"


@pytest.mark.parametrize("block", [b for b in python_blocks() if not set(b.markers) &
                                   set(WALK_THROUGH)], ids=lambda b: b.label)
def test_python_block_names_exist_and_calls_bind(block: Block):
    """Every block, run or not: it compiles, what it imports from parastokes exists, and its
    calls of parastokes functions and classes match their signatures."""
    assert static_problems(block.runnable_code() if block.runs else block.code) == []


def test_the_static_check_finds_wrong_names_and_keywords():
    """The check above catches the mistakes of round 2's examples: a name that is not there, a
    keyword that the function does not take, an argument too many."""
    problems = static_problems(
        "from parastokes import models, parareal\n"
        "rod = models.rod_swimer(n_points=21)\n"
        "parareal.lagrange_weights(1.0, [1.1, 1.2], order=2)\n"
        "parareal.richardson_weights(1, 0.5, 2, 3)\n"
        "from parastokes.integrate import propagat\n")
    assert len(problems) == 4, problems
    assert any("has no 'rod_swimer'" in p for p in problems)
    assert any("lagrange_weights" in p and "order" in p for p in problems)
    assert any("richardson_weights" in p and "too many" in p for p in problems)
    assert any("cannot import 'propagat'" in p for p in problems)


@pytest.mark.parametrize("page", _pages_with_runnable_blocks(),
                         ids=lambda p: str(p.relative_to(ROOT)))
def test_page_examples_run(page: Path, tmp_path: Path):
    """A page's runnable blocks, in order, in an empty folder (``experiments/`` linked there,
    as in a checkout), after the commands their ``after`` markers name; what a block prints
    contains the text of its ``prints`` markers."""
    (tmp_path / "experiments").symlink_to(ROOT / "experiments")
    batch: list[tuple[str, str]] = []
    printed: dict[str, str] = {}

    def flush() -> None:
        if batch:
            (tmp_path / "blocks.json").write_text(json.dumps(batch))
            _run([sys.executable, "-c", _DRIVER], tmp_path)
            printed.update(json.loads((tmp_path / "printed.json").read_text()))
            batch.clear()

    for block in blocks(page):
        if block.lang != "python":
            continue
        if "file" in block.markers:
            path = tmp_path / block.marker("file").strip()
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(block.code)
        if not block.runs:
            continue
        if block.commands():
            flush()
            for command in block.commands():
                words = shlex.split(command)
                assert words[0] == "parastokes", f"{block.label}: {command}"
                _run([sys.executable, "-m", "parastokes", *words[1:]], tmp_path)
        batch.append((block.label, block.runnable_code()))
    flush()
    for block in blocks(page):
        for text in block.markers.get("prints", []):
            assert text in printed[block.label], (
                f"{block.label} should print {text!r}; it printed {printed[block.label]!r}")


# ---- the gallery -------------------------------------------------------------------------------
def _numbers(pattern: str, text: str) -> list[float]:
    match = re.search(pattern, text)
    assert match, f"{pattern!r} not in the output:\n{text}"
    return [float(g) for g in match.groups()]


def _rod_swimmer_flow(out: str) -> None:
    (stretch,) = _numbers(r"length: (\S+) \(", out)
    speed, on_wall = _numbers(r"largest speed on the plane: (\S+) μm/s; on the wall: (\S+)", out)
    assert stretch < 1e-3
    assert 40.0 < speed < 48.0  # docs/tutorial.md: 44 μm/s at t = 0.0375 s
    assert on_wall < 1e-12  # no slip: the images cancel the sources on the wall


def _parareal_convergence(out: str) -> None:
    errors = [float(e) for e in re.findall(r"error (\S+)", out)]
    assert len(errors) == 4 and all(a > 5 * b for a, b in itertools.pairwise(errors))
    assert errors[-1] < 1e-7
    theory, bound = _numbers(r"after K = 4: (\S+), bound \(eq. 15\): (\S+)", out)
    assert 1.0 < theory < bound


def _scene(out: str) -> None:
    gained, shear = _numbers(r"gained (\S+) μm on the rod \(the shear's difference across their "
                             r"2.5 μm: (\S+) μm\)", out)
    assert shear == pytest.approx(1.25) and gained == pytest.approx(shear, rel=0.1)


def _sphere_wall_brenner(out: str) -> None:
    height, brenner = _numbers(r"height after 2.5 s: (\S+) μm \(Brenner: (\S+) μm\)", out)
    (speed_error,) = _numbers(r"largest speed error against Brenner: (\S+)%", out)
    assert speed_error < 5.0  # docs/validation.md: 2.1 % at 400 points for the resistance
    assert height == pytest.approx(brenner, rel=0.03) and height < 3.0 - 1.0


def _swimmers_near_wall(out: str) -> None:
    closest, speed = _numbers(r"closest approach (\S+) μm \(centre\), mean speed (\S+) μm/s", out)
    assert 1.0 < closest < 1.5 and 0.6 < speed < 1.0  # turned before touching the wall
    free, blake = _numbers(r"in free space: (\S+) μm/s \(Blake: 2 B1/3 = (\S+) μm/s\)", out)
    assert free == pytest.approx(blake, rel=0.2)  # 200 points: +15 %; 1200 points: within 4.3 %
    radii = [float(r) for r in re.findall(r"circles of radius (\S+) μm, clockwise", out)]
    assert len(radii) == 4 and radii == sorted(radii)  # the closer, the tighter


def _tune_choice(out: str) -> None:
    chosen, plain = _numbers(r"predicted speedup (\S+) with N_it = \d+, against (\S+) for", out)
    assert chosen >= plain > 1.0


def _user_body(out: str) -> None:
    assert "contract ok" in out
    errors = _numbers(r"Parareal errors η\^k: (\S+), (\S+), (\S+)", out)
    assert errors == sorted(errors, reverse=True) and errors[-1] < 1e-6
    (difference,) = _numbers(r"against the steps above: (\S+)", out)
    assert difference < 1e-5


def _vesicle_shear(out: str) -> None:
    deformation, _, area = _numbers(r"deformation D = (\S+), inclination (\S+) degrees to the "
                                    r"flow, area change (\S+)", out)
    rate, half_shear = _numbers(r"material point: (\S+) \(γ̇/2 = (\S+)\)", out)
    assert 0.01 < deformation < 0.2 and area < 1e-2
    assert rate == pytest.approx(half_shear, rel=0.02)


#: What each script's output must show (its page says the same in words).
CHECKS: dict[str, Callable[[str], None]] = {
    "plot_parareal_convergence": _parareal_convergence,
    "plot_rod_swimmer_flow": _rod_swimmer_flow,
    "plot_scene": _scene,
    "plot_sphere_wall_brenner": _sphere_wall_brenner,
    "plot_swimmers_near_wall": _swimmers_near_wall,
    "plot_tune_choice": _tune_choice,
    "plot_user_body": _user_body,
    "plot_vesicle_shear": _vesicle_shear,
}


def test_every_gallery_script_is_checked():
    assert len(SCRIPTS) >= 8
    assert sorted(CHECKS) == [s.stem for s in SCRIPTS]
    for script in SCRIPTS:  # sphinx-gallery's title: the docstring's first line, underlined
        head = script.read_text().split('"""')[1].strip().split("\n")
        assert len(head) > 2 and set(head[1]) == {"="} and len(head[1]) >= len(head[0]), script


@pytest.mark.parametrize("script", SCRIPTS, ids=lambda s: s.stem)
def test_gallery_script_runs_and_draws(script: Path, tmp_path: Path):
    done = _run([sys.executable, "-c", _GALLERY_RUNNER, str(script)], tmp_path)
    figures = sorted(tmp_path.glob("figure_*.png"))
    assert figures and all(f.stat().st_size > 10_000 for f in figures)
    CHECKS[script.stem](done.stdout)
