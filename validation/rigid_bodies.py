"""Rigid spheres against closed forms and exact series, for docs/validation.md ("Rigid bodies:
resistance and mobility").

1. Free space: a Fibonacci sphere of N points, ε = h/2 (h = sqrt(4πa²/N), as Khatri & Cortez tie
   ε to the grid size): drag / 6πμaU, torque / 8πμa³Ω, the L2 error of the traction against
   3μU/(2a), and the fitted orders in h.
2. Above a plane wall, center at height h: the diagonal of R_wall(h) / R_free for the same
   discretized sphere against Brenner (normal translation), Jeffery (rotation about the normal),
   Faxén and the near-wall asymptote of Goldman, Cox & Brenner (parallel translation and
   rotation) (parastokes/mobility/wall_series.py); the unnormalized values too.

Usage (from the repository root): ``python -m validation.rigid_bodies [--sizes 400 800 1600 3200]
[--wall-sizes 400 1600 3200]``; about 10 minutes on two shared cores. Prints markdown tables.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence

import numpy as np

from parastokes.mobility import RigidSurface, resistance_matrix, solve_resistance
from parastokes.mobility.sphere import fibonacci_sphere, sphere_spacing
from parastokes.mobility.wall_series import (
    brenner_perpendicular,
    faxen_parallel,
    gcb_parallel_rotation,
    gcb_parallel_translation,
    jeffery_rotation_normal,
)

MU = 1.0
#: heights h/a = cosh α for α = 0.3, 0.5, 1, 1.5, 2 (Brenner's table), plus gap 0.05 a
HEIGHTS = (1.05, 1.0453, 1.1276, 1.5431, 2.3524, 3.7622)
#: the near-wall asymptotes of Goldman, Cox & Brenner are shown for gaps up to this (in a)
NEAR_GAP = 0.15


def sphere(n: int) -> RigidSurface:
    return RigidSurface(fibonacci_sphere(n), 0.5 * sphere_spacing(n), name=f"sphere{n}")


def free_errors(n: int) -> tuple[float, float, float]:
    """Relative errors of drag, torque and L2 traction for the unit sphere of n points."""
    placed = sphere(n).place()
    res = solve_resistance(placed, U=(1.0, 0.0, 0.0), mu=MU)
    rot = solve_resistance(placed, Omega=(1.0, 0.0, 0.0), mu=MU)
    traction = res.forces * n / (4 * np.pi)
    exact = np.array([1.5 * MU, 0.0, 0.0])
    l2 = float(np.sqrt(np.mean(np.sum((traction - exact) ** 2, axis=1))) / 1.5)
    return res.force[0, 0] / (6 * np.pi) - 1, rot.torque[0, 0] / (8 * np.pi) - 1, l2


def free_table(sizes: Sequence[int]) -> None:
    print("| N | h | ε | drag / 6πμaU - 1 | torque / 8πμa³Ω - 1 | traction L2 error |")
    print("|---|---|---|---|---|---|")
    rows = []
    for n in sizes:
        h = sphere_spacing(n)
        d, t, tr = free_errors(n)
        rows.append((h, abs(d), abs(t), tr))
        print(f"| {n} | {h:.4f} | {h / 2:.4f} | {d:+.4f} | {t:+.4f} | {tr:.4f} |")
    arr = np.array(rows)
    orders = [np.polyfit(np.log(arr[:, 0]), np.log(arr[:, k]), 1)[0] for k in (1, 2, 3)]
    print(
        f"\nfitted orders in h: drag {orders[0]:.2f}, torque {orders[1]:.2f}, "
        f"traction {orders[2]:.2f}\n"
    )


def wall_table(sizes: Sequence[int]) -> None:
    print(
        "| h/a | N | normal: ours / Brenner | rot. normal: ours / Jeffery "
        "| parallel: ours / Faxén (/ GCB) | rot. parallel: ours (/ GCB) | normal, unnormalized |"
    )
    print("|---|---|---|---|---|---|---|")
    for n in sizes:
        s = sphere(n)
        free = np.diag(resistance_matrix(s, mu=MU))
        for h in HEIGHTS:
            gap = h - 1
            if gap < 0.5 * sphere_spacing(n):
                continue  # the gap is not resolved by this surface
            wall = np.diag(resistance_matrix(s, (0.0, 0.0, h), mu=MU, wall=True))
            r = wall / free
            near = gap <= NEAR_GAP
            gcb_t = f" / {gcb_parallel_translation(gap):.4f}" if near else ""
            gcb_r = f" / {gcb_parallel_rotation(gap):.4f}" if near else ""
            print(
                f"| {h:.4f} | {n} | {r[2]:.4f} / {brenner_perpendicular(h):.4f} "
                f"| {r[5]:.4f} / {jeffery_rotation_normal(h):.4f} "
                f"| {r[0]:.4f} / {faxen_parallel(h):.4f}{gcb_t} "
                f"| {r[3]:.4f}{gcb_r} "
                f"| {wall[2] / (6 * np.pi * MU):.4f} |"
            )
    print()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[400, 800, 1600, 3200])
    parser.add_argument("--wall-sizes", type=int, nargs="+", default=[400, 1600, 3200])
    args = parser.parse_args()
    free_table(args.sizes)
    wall_table(args.wall_sizes)


if __name__ == "__main__":
    main()
