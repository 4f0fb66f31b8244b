"""The rigid-body numbers of docs/validation.md ("Rigid bodies: resistance and mobility") and the
algorithmic ones of docs/benchmarks.md (GMRES iterations; Parareal on the bacterium with a coarse
surface), recomputed and compared with ``docs/numbers.toml``:

- ``[rigid_coarseness]``: drag error and cond(M) of the 400-point sphere against h/ε
  (``validation.rigid_bodies.coarseness``);
- ``[rigid_pairs]``: two spheres settling along their line of centers against Stimson &
  Jeffery's 1/λ, N = 400, and GMRES's iterations (``validation.rigid_bodies.settling_pairs``; the
  N = 200 column is ``tests/test_mobility_sphere.py::test_two_spheres_settling_stimson_jeffery``);
- ``[rigid_gmres]``: GMRES iterations of the block preconditioner, one sphere above the wall at
  gaps >= 0.25a and rows of 2 spheres by default, rows of 4-16 spheres slow
  (``benchmarks/mobility.py``);
- ``[rigid_resist]``: GMRES iterations of the resistance problem for rows of 2 and 4 spheres by
  default, 8 slow (``benchmarks/mobility.py --parts resist``);
- ``[rigid_coarse_surface]``: the bacterium's Parareal with its coarse solver on coarser surfaces
  (``benchmarks/rigid.py --sections coarse_surface``), slow; its CI-sized twin
  ``[rigid_coarse_surface_twins]`` (3 slices, T = 1.2 ms, factor 2) by default, and the
  coarse surfaces' points by default.
"""

from __future__ import annotations

import pytest
from bench_modules import benchmark_module
from documented import check

from validation import rigid_bodies


def test_drag_and_conditioning_against_h_over_eps():
    values = rigid_bodies.coarseness()
    check("rigid_coarseness", "drag", values["drag"])
    check("rigid_coarseness", "cond", values["cond"])


def test_settling_pair_400_against_stimson_jeffery():
    values = rigid_bodies.settling_pairs(400)
    check("rigid_pairs", "exact", values["exact"])
    check("rigid_pairs", "ratio_400", values["ratio"])
    check("rigid_pairs", "iterations_400", values["iterations"])


def _one_sphere_iterations(bench, gaps):
    s = bench.sphere(400)
    return {pc: [bench.timed_gmres(bench.gap_bodies(s, gap), True, pc, **bench.GAP_LOADS)[0]
                 for gap in gaps] for pc in ("free", "wall")}


#: the rows (B, δ/a) of docs/benchmarks.md's row table that [rigid_gmres] pins (not δ = 0.1a)
ROWS = [(b, gap) for b in (2, 4, 8, 16) for gap in (0.5, 2.0)]


def _check_rows(bench, which):
    s = bench.sphere(400)
    for i in which:
        count, gap = ROWS[i]
        bodies = bench.row_bodies(s, count, gap)
        for key, wall, pc in bench.ROW_SOLVERS:
            its = bench.timed_gmres(bodies, wall, pc, external_force=(0, 0, -1))[0]
            check("rigid_gmres", f"rows_{key}", its, i)


def test_gmres_iterations_one_sphere_and_pairs():
    """One sphere of 400 points at gaps 0.25a-2a above the wall (both preconditioners) and the
    rows of two spheres (wall with either preconditioner, free space)."""
    with benchmark_module("mobility") as bench:
        its = _one_sphere_iterations(bench, (0.25, 0.5, 1.0, 2.0))
        check("rigid_gmres", "one_free", its["free"])
        check("rigid_gmres", "one_wall", its["wall"])
        _check_rows(bench, [0, 1])


@pytest.mark.slow
def test_gmres_iterations_rows_of_4_to_16():
    with benchmark_module("mobility") as bench:
        _check_rows(bench, range(2, len(ROWS)))


FACTORS = (1, 2, 3, 4)


def test_coarse_surface_points():
    """The coarse surfaces' points (fine surface 300; factors 2, 3, 4)."""
    with benchmark_module("rigid") as bench:
        from parastokes import config

        system = config.load(bench.QUICK_BACTERIUM)[0].model.build(1)
        points = [system.n_surface] + [system.coarsened(f)[0].n_surface for f in FACTORS[1:]]
    check("rigid_coarse_surface", "points", points)


def _check_parareal(group, t1, n_slices, factors, names):
    with benchmark_module("rigid") as bench:
        setup = bench.coarse_surface_setup(t1, n_slices)
        iterations = []
        for factor, name in zip(factors, names, strict=True):
            _, k, errors = bench.coarse_surface_run(setup, factor)
            iterations.append(k)
            check(group, f"errors_{name}", errors)
    check(group, "iterations", iterations)


def test_coarse_surface_parareal_twin():
    """The CI-sized twin of the table: factor 2 over 3 slices of 0.4 ms."""
    _check_parareal("rigid_coarse_surface_twins", 0.0012, 3, [2], ["f2"])


@pytest.mark.slow
def test_coarse_surface_parareal():
    """The table: T = 24 ms over 8 slices, the coarse solver on the fine surface and on surfaces
    2, 3 and 4 times coarser: iterations to η̃ < 1e-8 and η after each."""
    _check_parareal("rigid_coarse_surface", 0.024, 8, FACTORS, ["fine", "f2", "f3", "f4"])


#: the rows (B, δ/a, wall) of docs/benchmarks.md's resistance table, in its order
RESIST_ROWS = [(b, gap, wall) for b in (2, 4, 8) for gap in (0.1, 0.5) for wall in (True, False)]


def _resistance_iterations(bench, rows):
    s = bench.sphere(400)
    found: dict[str, list[int]] = {"default": [], "sweep": [], "jacobi": [], "mobility": []}
    for count, gap, wall in rows:
        solves = bench.resistance_solves(bench.row_bodies(s, count, gap), wall)
        for name, (its, _) in solves.items():
            found[name].append(its)
    return found


def _check_resistance(which):
    with benchmark_module("mobility") as bench:
        found = _resistance_iterations(bench, [RESIST_ROWS[i] for i in which])
    for name, its in found.items():
        for i, value in zip(which, its, strict=True):
            check("rigid_resist", name, value, i)


def test_resistance_iterations_of_rows_of_2_and_4():
    """``[rigid_resist]``: GMRES iterations of the resistance rows of 2 and 4 spheres (default
    preconditioner, the sweep alone, block Jacobi) and of the mobility problem of the same rows."""
    _check_resistance(range(8))


@pytest.mark.slow
def test_resistance_iterations_of_rows_of_8():
    _check_resistance(range(8, len(RESIST_ROWS)))
