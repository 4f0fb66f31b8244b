"""The quick-scale physics/algorithm numbers of docs/benchmarks.md (not its timings), recomputed
and compared with ``docs/numbers.toml`` (``[bench_parareal]``): eta~^1 and eta^1 of the Parareal
benchmark's cases (``benchmarks/parareal.py``, section "Speedup against eq. 14", N_c = 2 slices,
one iteration; the same rod run is the N_c = 2, N_it = 1 row of the strong-scaling table), and
the Parareal column of the Fig. 10 analogue (five rods). The rod cases run by default (M = 301,
2 x 500 RK2 steps; five rods, 40 steps); the vesicle (2 x 1000 steps) is slow.
"""

from __future__ import annotations

import pytest
from bench_modules import benchmark_module
from documented import check

from parastokes import parareal


def _iterations(case_name: str, iterations: int = 1) -> parareal.PararealResult:
    with benchmark_module("parareal") as bench:
        case = bench.rod_case(1, 5e-4) if case_name == "rod" else bench.vesicle_case(1.0)
        t1 = 2 * case.slice_length
        reference = parareal.serial_solution(case.fine, case.x0, 0.0, t1, 2)
        return bench.run_parareal(case, 2, t1, None, iterations, reference=reference)


def _first_iteration(case_name: str) -> tuple[float, float]:
    res = _iterations(case_name)
    return res.increments[0], res.errors[0]


def test_rod_speedup_case_first_iterate():
    """Also the strong-scaling row N_c = 2, N_it = 2: after N_c iterations Parareal is the serial
    solution, eta = 0 exactly ([bench_parareal_exact])."""
    res = _iterations("rod", 2)
    check("bench_parareal", "rod_increment1", res.increments[0])
    check("bench_parareal", "rod_eta1", res.errors[0])
    check("bench_parareal_exact", "rod_eta2", res.errors[1])


@pytest.mark.slow
def test_vesicle_speedup_case_first_iterate():
    increment, error = _first_iteration("vesicle")
    check("bench_parareal", "vesicle_increment1", increment)
    check("bench_parareal", "vesicle_eta1", error)


def test_fig10_parareal_iterations():
    """Fig. 10's five rods on N_c = 2 slices of 20 fine steps, stopping at eta~ < 1e-5 (at most
    N_c iterations): the N_it and eta~ of the table in docs/benchmarks.md."""
    with benchmark_module("parareal") as bench:
        res = bench.run_parareal(bench.rod_case(5, 0.0), 2, 40e-6, None, 2, tol=1e-5)
    check("bench_parareal", "fig10_iterations", res.iterations)
    check("bench_parareal", "fig10_increment", res.increments[-1])
