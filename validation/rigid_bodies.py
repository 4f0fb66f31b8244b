"""Rigid spheres against closed forms and exact series, for docs/validation.md ("Rigid bodies:
resistance and mobility").

1. Free space: a Fibonacci sphere of N points, ε = h/2 (h = sqrt(4πa²/N), as Khatri & Cortez tie
   ε to the grid size): drag / 6πμaU, torque / 8πμa³Ω, the L2 error of the traction against
   3μU/(2a), and the fitted orders in h.
2. Above a plane wall, center at height h: the diagonal of R_wall(h) / R_free for the same
   discretized sphere against Brenner (normal translation), Jeffery (rotation about the normal),
   Faxén and the near-wall asymptote of Goldman, Cox & Brenner (parallel translation and
   rotation) (parastokes/mobility/wall_series.py); the unnormalized values too.
3. How coarse a surface may be for its ε: the drag error and cond(M) of the 400-point sphere
   against h/ε.
4. Two spheres settling along their line of centers against Stimson & Jeffery's 1/λ (GMRES with
   the block preconditioner), and GMRES's iterations.

Usage (from the repository root): ``python -m validation.rigid_bodies [--sizes 400 800 1600 3200]
[--wall-sizes 400 1600 3200] [--toml]``; about 12 minutes on two shared cores. Prints markdown
tables; ``--toml`` prints the values as docs/numbers.toml's groups instead.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence

import numpy as np

from parastokes.mobility import RigidSurface, resistance_matrix, solve_mobility, solve_resistance
from parastokes.mobility.sphere import fibonacci_sphere, sphere_spacing
from parastokes.mobility.two_spheres import stimson_jeffery
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
#: h/ε of the coarseness table (the 400-point sphere)
SPACING_RATIOS = (0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 5.0, 6.0, 8.0)
#: half the distance of the two settling spheres' centers, d/a (cosh α = 0.5, 1, 1.5, 2)
PAIR_DISTANCES = (1.1276, 1.5431, 2.3524, 3.7622)


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


def coarseness(n: int = 400, ratios: Sequence[float] = SPACING_RATIOS) -> dict[str, list[float]]:
    """Drag / 6πμaU - 1 of the unit sphere of ``n`` points and the 2-norm condition number of its
    matrix M (eq. 6; symmetric, so from its eigenvalues) at ε = h / ratio, h = sqrt(4πa²/n)
    (the surface check is off: it refuses ratios above 4)."""
    from parastokes.mrs.operator import StokesletOperator

    points, h = fibonacci_sphere(n), sphere_spacing(n)
    drag, cond = [], []
    for ratio in ratios:
        s = RigidSurface(points, h / ratio, check=False)
        res = solve_resistance(s.place(), U=(1.0, 0.0, 0.0), mu=MU)
        drag.append(float(res.force[0, 0] / (6 * np.pi * MU) - 1))
        eig = np.abs(np.linalg.eigvalsh(StokesletOperator(None, points, h / ratio, MU).dense()))
        cond.append(float(eig.max() / eig.min()))  # M is symmetric: its singular values
    return {"drag": drag, "cond": cond}


def settling_pairs(
    n: int, distances: Sequence[float] = PAIR_DISTANCES
) -> dict[str, list[float] | list[int]]:
    """Two unit spheres of ``n`` points, centers 2d apart along z, each under the force -e_z:
    their velocity over that of one sphere of the same points (ε = h/2), Stimson & Jeffery's 1/λ,
    and the GMRES iterations of the pair's solve (block preconditioner, tol 1e-10)."""
    s = sphere(n)
    single = solve_mobility(s.place(), mu=MU, external_force=(0, 0, -1)).U[0, 2]
    ratio, iterations = [], []
    for d in distances:
        pair = solve_mobility(
            [s.place((0, 0, d)), s.place((0, 0, -d))], mu=MU, external_force=(0, 0, -1),
            method="gmres",
        )
        ratio.append(float(np.mean(pair.U[:, 2]) / single))
        iterations.append(pair.info.iterations)
    return {
        "ratio": ratio,
        "iterations": iterations,
        "exact": [1 / stimson_jeffery(d) for d in distances],
    }


def wall_values(
    n: int, heights: Sequence[float] = HEIGHTS, resolved_only: bool = True
) -> dict[str, list[float]]:
    """Per height h/a of ``heights`` (with ``resolved_only``: those whose gap is at least half the
    surface's spacing, as the page shows them): the wall corrections of the
    unit sphere of ``n`` points (diagonal of R_wall(h) / R_free: normal, rotation about the
    normal, parallel, rotation about a parallel axis), the unnormalized F_z / (6πμaU), and the
    references (Brenner, Jeffery, Faxén; GCB's asymptotes for gaps <= NEAR_GAP, else NaN)."""
    s = sphere(n)
    free = np.diag(resistance_matrix(s, mu=MU))
    out: dict[str, list[float]] = {k: [] for k in (
        "height", "normal", "rotation_normal", "parallel", "rotation_parallel", "unnormalized",
        "brenner", "jeffery", "faxen", "gcb_parallel", "gcb_rotation")}
    for h in heights:
        gap = h - 1
        if resolved_only and gap < 0.5 * sphere_spacing(n):
            continue  # the gap is not resolved by this surface
        wall = np.diag(resistance_matrix(s, (0.0, 0.0, h), mu=MU, wall=True))
        r = wall / free
        near = gap <= NEAR_GAP
        for key, value in (
            ("height", h), ("normal", r[2]), ("rotation_normal", r[5]), ("parallel", r[0]),
            ("rotation_parallel", r[3]), ("unnormalized", wall[2] / (6 * np.pi * MU)),
            ("brenner", brenner_perpendicular(h)), ("jeffery", jeffery_rotation_normal(h)),
            ("faxen", faxen_parallel(h)),
            ("gcb_parallel", gcb_parallel_translation(gap) if near else np.nan),
            ("gcb_rotation", gcb_parallel_rotation(gap) if near else np.nan),
        ):
            out[key].append(float(value))
    return out


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
        v = wall_values(n)
        for i, h in enumerate(v["height"]):
            near = not np.isnan(v["gcb_parallel"][i])
            gcb_t = f" / {v['gcb_parallel'][i]:.4f}" if near else ""
            gcb_r = f" / {v['gcb_rotation'][i]:.4f}" if near else ""
            print(
                f"| {h:.4f} | {n} | {v['normal'][i]:.4f} / {v['brenner'][i]:.4f} "
                f"| {v['rotation_normal'][i]:.4f} / {v['jeffery'][i]:.4f} "
                f"| {v['parallel'][i]:.4f} / {v['faxen'][i]:.4f}{gcb_t} "
                f"| {v['rotation_parallel'][i]:.4f}{gcb_r} "
                f"| {v['unnormalized'][i]:.4f} |"
            )
    print()


def coarseness_table() -> None:
    v = coarseness()
    print("| h/ε | " + " | ".join(f"{r:g}" for r in SPACING_RATIOS) + " |")
    print("|---|" + "---|" * len(SPACING_RATIOS))
    print("| drag / 6πμaU - 1 | " + " | ".join(f"{d:+.3f}" for d in v["drag"]) + " |")
    print("| cond(M) | " + " | ".join(f"{c:.2g}" for c in v["cond"]) + " |")
    print()


def pairs_table(sizes: Sequence[int] = (200, 400)) -> None:
    runs = [settling_pairs(n) for n in sizes]
    print("| d/a (centers 2d apart) | 1/λ | " + " | ".join(f"N = {n}" for n in sizes)
          + f" | GMRES iterations ({sizes[-1]}) |")
    print("|---|---|" + "---|" * len(sizes) + "---|")
    for i, d in enumerate(PAIR_DISTANCES):
        cells = " | ".join(f"{r['ratio'][i]:.4f}" for r in runs)
        print(f"| {d} | {runs[0]['exact'][i]:.4f} | {cells} | {runs[-1]['iterations'][i]} |")
    print()


def toml_groups(sizes: Sequence[int], wall_sizes: Sequence[int]) -> None:
    """The values of the registry's groups that this script computes, at full precision."""
    from validation.report import toml_values

    print("[rigid_coarseness]")
    print(toml_values(coarseness()))
    for n in (200, 400):
        v = settling_pairs(n)
        print(f"[rigid_pairs] N = {n}")
        print(toml_values(v))
    for n in wall_sizes:
        print(f"[rigid_wall] N = {n}")
        print(toml_values(wall_values(n)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[400, 800, 1600, 3200])
    parser.add_argument("--wall-sizes", type=int, nargs="+", default=[400, 1600, 3200])
    parser.add_argument("--toml", action="store_true", help="print docs/numbers.toml values")
    args = parser.parse_args()
    if args.toml:
        toml_groups(args.sizes, args.wall_sizes)
        return
    free_table(args.sizes)
    coarseness_table()
    pairs_table()
    wall_table(args.wall_sizes)


if __name__ == "__main__":
    main()
