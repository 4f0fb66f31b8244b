"""The cost model of section 3 (eqs. 12-15) and a speedup predictor for planning runs.

Run ``python -m parastokes.parareal.speedup --ratio 0.02 --iterations 3 --cores 8 16 32 64`` to
print the theoretical speedup (eq. 14 with no overhead) and the bound (eq. 15) for any core count,
from a gamma_G / gamma_F ratio measured on a small machine (``res.speedup()["gamma_ratio"]``).
"""

from __future__ import annotations

import argparse
from collections.abc import Iterable, Sequence

__all__ = [
    "parareal_runtime",
    "pipelined_runtime",
    "predict",
    "speedup",
    "speedup_bound",
    "speedup_pipelined",
    "speedup_standard",
]


def _check(iterations: int, n_slices: int) -> None:
    if n_slices < 1 or not 0 <= iterations <= n_slices:
        raise ValueError(
            f"need 0 <= iterations <= n_slices and n_slices >= 1, got {iterations}, {n_slices}"
        )


def parareal_runtime(
    gamma_g: float, gamma_f: float, iterations: int, n_slices: int, overhead: float = 0.0
) -> float:
    """Eq. 12: sum_{k=0}^{N_it} (N_c - k) gamma_G + N_it gamma_F + Upsilon_oh."""
    _check(iterations, n_slices)
    coarse_calls = 0.5 * (iterations + 1) * (2 * n_slices - iterations)
    return coarse_calls * gamma_g + iterations * gamma_f + overhead


def speedup(
    gamma_g: float, gamma_f: float, iterations: int, n_slices: int, overhead: float = 0.0
) -> float:
    """Eq. 14: Upsilon_F / Upsilon_pr with Upsilon_F = N_c gamma_F (eq. 13).

    ``overhead = 0`` gives the paper's theoretical speedup.
    """
    return n_slices * gamma_f / parareal_runtime(gamma_g, gamma_f, iterations, n_slices, overhead)


def speedup_bound(gamma_ratio: float, iterations: int, n_slices: int) -> float:
    """Eq. 15: 2 / ((N_it + 1)(2 - N_it / N_c)) * gamma_F / gamma_G, with gamma_ratio = G/F."""
    _check(iterations, n_slices)
    return 2.0 / ((iterations + 1) * (2.0 - iterations / n_slices)) / gamma_ratio


def speedup_standard(alpha: float, iterations: int, n_slices: int) -> float:
    """The closed formula of Algorithm 1's speedup, 1 / ((1 + K) alpha + K / P), with alpha =
    gamma_G / gamma_F, K iterations and P slices on P workers: eq. 14 without overhead when
    every serial sweep is counted over all P slices (eq. 12 counts P - k; the two agree to
    O(K^2 / P)). Limit as P grows: 1 / ((K + 1) alpha)."""
    _check(iterations, n_slices)
    return 1.0 / ((1 + iterations) * alpha + iterations / n_slices)


def speedup_pipelined(alpha: float, iterations: int, n_slices: int) -> float:
    """The closed formula of pipelined Parareal's speedup, 1 / ((1 + K / P) alpha + K / P): wall
    time P gamma_G + K (gamma_F + gamma_G), the pipeline in which slice n's worker runs its coarse
    and fine solves one after the other (Minion 2010, Ruprecht 2017). The event-based schedule of
    ``run(..., schedule="pipelined")`` is at least as fast (see :func:`pipelined_runtime`).
    Limit as P grows: 1 / alpha."""
    _check(iterations, n_slices)
    return 1.0 / ((1 + iterations / n_slices) * alpha + iterations / n_slices)


def pipelined_runtime(gamma_g: float, gamma_f: float, iterations: int, n_slices: int) -> float:
    """The critical path of the pipelined schedule, K gamma_F + (N - K) gamma_G (for
    gamma_G <= gamma_F): every path from X_0 to X_N^K takes K fine and N - K coarse steps, so
    this is its wall time when no task ever waits for a worker."""
    _check(iterations, n_slices)
    return iterations * gamma_f + (n_slices - iterations) * gamma_g


def schedule_speedups(
    schedule: str, gamma_g: float, gamma_f: float, iterations: int, n_slices: int
) -> tuple[float, float]:
    """(theoretical speedup, its bound) of a run of ``schedule`` with one worker per slice and no
    overhead: Algorithm 1's eqs. 14 and 15 for ``"standard"``; for ``"pipelined"`` the simulated
    wall time of that schedule on N_c workers (:func:`~parastokes.parareal.simulate`) and the
    speedup of its critical path (:func:`pipelined_runtime`: no task waits for a worker)."""
    if schedule == "pipelined":
        from .schedule_model import simulate  # (it imports the schedules, which import this)

        ratio = gamma_g / gamma_f
        wall = simulate("pipelined", n_slices, iterations, n_slices, ratio).wall
        return n_slices / wall, n_slices * gamma_f / pipelined_runtime(
            gamma_g, gamma_f, iterations, n_slices
        )
    return (
        speedup(gamma_g, gamma_f, iterations, n_slices),
        speedup_bound(gamma_g / gamma_f, iterations, n_slices),
    )


def predict(
    gamma_ratio: float, iterations: int, cores: Iterable[int]
) -> list[tuple[int, float, float]]:
    """(N_c, theoretical speedup eq. 14, bound eq. 15) for each core count (one slice per core).

    ``gamma_ratio`` is gamma_G / gamma_F per slice as measured at any N_c; both times scale with the
    slice length, so the ratio carries over to other N_c at the same coarse and fine steps. Parareal
    never needs more than N_c iterations, so the iteration count is capped at N_c.
    """
    if gamma_ratio <= 0.0:
        raise ValueError(f"gamma_ratio must be positive, got {gamma_ratio}")
    rows = []
    for n_cores in cores:
        n_it = min(iterations, n_cores)
        rows.append(
            (
                n_cores,
                speedup(gamma_ratio, 1.0, n_it, n_cores),
                speedup_bound(gamma_ratio, n_it, n_cores),
            )
        )
    return rows


def main(argv: Sequence[str] | None = None) -> None:
    """Print the predicted speedup table (see the module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ratio", type=float, required=True, help="gamma_G / gamma_F")
    parser.add_argument("--iterations", type=int, required=True, help="Parareal iterations N_it")
    parser.add_argument("--cores", type=int, nargs="+", required=True, help="core counts N_c")
    args = parser.parse_args(argv)
    print(f"{'N_c':>6} {'N_it':>5} {'speedup (eq. 14)':>17} {'bound (eq. 15)':>15}")
    for n_cores, theory, bound in predict(args.ratio, args.iterations, args.cores):
        print(f"{n_cores:>6} {min(args.iterations, n_cores):>5} {theory:>17.3f} {bound:>15.3f}")


if __name__ == "__main__":
    main()
