"""Every quick variant of the paper's experiments, end to end, against its recorded first iterate.

For each ``experiments/quick/NAME.toml``: the configuration built as ``parastokes run`` builds it,
its serial fine solution and one Parareal iteration (``validation/quick_errors.py``), with eta^1
(eq. 34), eta~^1 and the largest monitor value compared with ``docs/numbers.toml``
(``[quick_eta1]``; variants added later, in groups of their own at the end: ``LATER``). The
variants that take tens of seconds run in full under ``-m slow``; in the
default run, their CI-sized twins (two short slices, ``[quick_eta1_twins]``) do. A change to a
kernel, a model, a propagator, the coarse-solver construction, the weights or the Parareal update
moves these numbers far beyond the tolerance (measured: bit-identical on 1 and 2 threads).

The quick runs whose later iterates docs/validation.md section 2 quotes (``quick_errors.ITERATED``)
run their three iterations under ``-m slow`` (``[quick_eta_k_slow]``: eta^1..eta^3 and the largest
monitor of X^3, as ``parastokes run`` writes them); by default their twins of three short slices
run two iterations (``[quick_eta_k_twins]``), so that eta^2 is compared too.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from documented import check, values

from validation import quick_errors

QUICK = sorted(p.stem for p in (Path(__file__).parents[1] / "experiments" / "quick").glob("*.toml"))
#: Quick variants recorded in groups of their own after ``[quick_eta1]`` (same fields, same
#: command), by group.
LATER = {"quick_eta1_scene_coarse": ["scene_sphere_and_rod_coarse"],
         "quick_eta1_round4": ["cloud_sediments", "rods_25", "suspension_64_spheres",
                               "table4_ros2"],
         "quick_eta1_round5": ["stiff_rod601", "stiff_rod601_rk2"],
         "quick_eta1_circles": ["bacterium_circles"]}
#: Later variants that take longer than a default test may (measured on 2 loaded cores:
#: cloud_sediments 37 s, suspension_64_spheres 310 s): run under ``-m slow``.
SLOW_LATER = {"cloud_sediments", "suspension_64_spheres"}
CHEAP = [name for name in QUICK if name not in quick_errors.EXPENSIVE
         and not any(name in names for names in LATER.values())]
FIELDS = ("eta1", "increment1", "monitor")
#: Every run on one thread: a ``run.mode = "serial"`` variant otherwise takes every core, which
#: the other pytest-xdist worker occupies (bacterium_circles: 283 s instead of 18 s); the numbers
#: are bit-identical on 1 and 2 threads (above).
ONE_THREAD = ("execution.threads=1",)


def _compare(group: str, name: str, overrides=()) -> None:
    computed = quick_errors.first_iterate(name, [*overrides, *ONE_THREAD])
    check(group, name, [computed[k] for k in FIELDS])


def test_every_quick_variant_is_recorded():
    later = [name for group in LATER for name in values(group)]
    assert sorted([*values("quick_eta1"), *later]) == QUICK
    assert sorted(later) == sorted(n for names in LATER.values() for n in names)
    assert sorted(values("quick_eta1_twins")) == sorted(quick_errors.EXPENSIVE)
    assert sorted(quick_errors.CI_TWINS) == sorted(quick_errors.EXPENSIVE)


@pytest.mark.parametrize("name", CHEAP)
def test_quick_variant_first_iterate(name):
    _compare("quick_eta1", name)


@pytest.mark.parametrize("group, name", [
    pytest.param(g, n, marks=pytest.mark.slow) if n in SLOW_LATER else (g, n)
    for g, names in LATER.items() for n in names])
def test_later_quick_variant_first_iterate(group, name):
    _compare(group, name)


@pytest.mark.parametrize("name", sorted(quick_errors.CI_TWINS))
def test_ci_twin_first_iterate(name):
    _compare("quick_eta1_twins", name, quick_errors.CI_TWINS[name])


@pytest.mark.slow
@pytest.mark.parametrize("name", quick_errors.EXPENSIVE)
def test_expensive_quick_variant_first_iterate(name):
    _compare("quick_eta1", name)


def _compare_iterated(group: str, name: str, overrides=(), iterations: int = 3) -> None:
    run = quick_errors.iterates(name, [*overrides, *ONE_THREAD], iterations=iterations)
    check(group, name, [*run["errors"], run["monitor"]])


def test_every_iterated_run_is_recorded():
    assert sorted(values("quick_eta_k_slow")) == sorted(quick_errors.ITERATED)
    assert sorted(values("quick_eta_k_twins")) == sorted(quick_errors.ITERATED_TWINS)


@pytest.mark.parametrize("name", sorted(quick_errors.ITERATED_TWINS))
def test_ci_twin_second_iterate(name):
    _compare_iterated("quick_eta_k_twins", name, quick_errors.ITERATED_TWINS[name], 2)


@pytest.mark.slow
@pytest.mark.parametrize("name", quick_errors.ITERATED)
def test_iterated_quick_run(name):
    _compare_iterated("quick_eta_k_slow", name)
