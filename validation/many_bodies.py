"""The collective physics of many rigid spheres, for docs/validation.md ("Many bodies").

Spheres of radius a = 1 discretized by N Fibonacci points (ε = h/2), each under the same force
-e_z, in free space, solved together by GMRES with the per-body blocks (one mobility solve).
Speeds are given over that of one sphere of the same discretization, and the references use its
hydrodynamic radius a_eff = F / (6πμ U_1) (1.058 at N = 42, 1.027 at 162: the regularized
surface is that much larger), so that the discretization error of a sphere alone cancels and
what is compared is the interaction.

1. A spherical cloud: ``count`` spheres placed at random (``[[suspensions]]``'s placement,
   :func:`parastokes.config.placement.random_centers`, gap 0.6 a) in a sphere of radius R. A
   dilute cloud settles as a drop of the suspension: its spheres fall faster than one alone, on
   average by (6/5)(count - 1) a/R (the Oseen flow of the others averaged over uniform positions
   in a ball, E[(1 + cos²θ)/r] = 8/(5R); Nitsche & Batchelor, J. Fluid Mech. 340, 161 (1997):
   (6/5) N a/R). Also the Rotne–Prager sum of the same configuration (pairwise, no reflections).
2. A horizontal row of ``count`` spheres ``spacing`` apart, falling across it: each sphere's
   speed against the Rotne–Prager sum, and for two spheres against the two-sphere mobility
   functions (:func:`parastokes.mobility.two_spheres.pair_mobility`).

Usage (from the repository root): ``python -m validation.many_bodies [--full]``: the tables of
docs/validation.md (``--full``: also the sizes of the slow tests; about a minute, five with
``--full``).
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence

import numpy as np

from parastokes.config.placement import random_centers
from parastokes.mobility import RigidSurface, solve_mobility
from parastokes.mobility.sphere import fibonacci_sphere, sphere_spacing
from parastokes.mobility.two_spheres import pair_mobility

MU = 1.0
#: the least gap between two spheres of a random cloud (in radii)
CLOUD_GAP = 0.6
#: (surface points, spheres, cloud radius R, seeds) of the cloud table; the slow rows last
CLOUDS = ((42, 30, 8.0, (1, 2, 3)), (42, 100, 12.0, (1, 2, 3)), (42, 250, 16.0, (1, 2)),
          (162, 250, 16.0, (1,)))
#: (surface points, spheres, spacings) of the row table
ROWS = ((42, 9, (3.0, 4.0, 6.0)), (162, 9, (3.0, 4.0, 6.0)))


def sphere(n: int) -> RigidSurface:
    return RigidSurface(fibonacci_sphere(n), 0.5 * sphere_spacing(n), name=f"sphere{n}")


def single_speed(surface: RigidSurface) -> float:
    """The sedimentation speed of one sphere under a unit force."""
    return float(-solve_mobility([surface.place()], mu=MU,
                                 external_force=(0.0, 0.0, -1.0)).U[0, 2])


def effective_radius(surface: RigidSurface) -> float:
    """a_eff = F / (6πμ U_1) of the discretized sphere."""
    return 1.0 / (6.0 * np.pi * MU * single_speed(surface))


def rotne_prager(centers: np.ndarray, a: float) -> np.ndarray:
    """Each sphere's speed over one alone, equal forces along -z, from the Rotne–Prager tensor
    of every other sphere: 1 + Σ (3a/4r) [(1 + 2a²/3r²) + (1 - 2a²/r²) cos²θ], θ from the
    vertical."""
    d = centers[:, None, :] - centers[None, :, :]
    r = np.linalg.norm(d, axis=-1)
    np.fill_diagonal(r, np.inf)
    cos2 = (d[..., 2] / r) ** 2
    terms = 0.75 * a / r * ((1 + 2 * a * a / (3 * r * r)) + (1 - 2 * a * a / (r * r)) * cos2)
    return 1.0 + terms.sum(axis=1)


def speeds(surface: RigidSurface, centers: np.ndarray) -> tuple[np.ndarray, int]:
    """Each sphere's speed over one alone when all fall together under equal forces (one
    mobility solve, GMRES), and the GMRES iterations."""
    solved = solve_mobility([surface.place(c) for c in centers], mu=MU,
                            external_force=(0.0, 0.0, -1.0), method="gmres")
    return -solved.U[:, 2] / single_speed(surface), solved.info.iterations


def cloud(n: int, count: int, radius: float, seed: int) -> dict:
    """One random cloud (see the module): the mean speed over one sphere's, the Rotne–Prager
    mean of the same configuration, Nitsche & Batchelor's 1 + (6/5)(count - 1) a_eff/R."""
    surface = sphere(n)
    a = effective_radius(surface)
    centers, _ = random_centers(count, "sphere", [0.0, 0.0, 0.0], None, radius, 1.0,
                                2.0 + CLOUD_GAP, np.random.default_rng(seed))
    ratio, iterations = speeds(surface, centers)
    return {"points": n, "count": count, "radius": radius, "seed": seed, "a_eff": a,
            "fraction": count / radius**3, "mean": float(ratio.mean()),
            "rotne_prager": float(rotne_prager(centers, a).mean()),
            "theory": 1.0 + 1.2 * (count - 1) * a / radius, "iterations": iterations}


def row(n: int, count: int, spacing: float) -> dict:
    """A row along x (see the module): every sphere's speed over one alone and its Rotne–Prager
    value; for two spheres also the two-sphere mobility functions' (across the line)."""
    surface = sphere(n)
    a = effective_radius(surface)
    centers = np.array([[i * spacing, 0.0, 0.0] for i in range(count)])
    ratio, iterations = speeds(surface, centers)
    out = {"points": n, "count": count, "spacing": spacing, "a_eff": a, "speeds": ratio.tolist(),
           "rotne_prager": rotne_prager(centers, a).tolist(), "iterations": iterations}
    if count == 2:
        out["pair"] = pair_mobility(spacing / a)[1]
    return out


def cloud_table(rows: Sequence[tuple[int, int, float, Sequence[int]]]) -> list[dict]:
    out = []
    print("| N (points) | spheres | R/a | volume fraction | seed | mean speed / one sphere's "
          "| Rotne–Prager | 1 + (6/5)(n - 1) a/R | (mean - 1) / ((6/5)(n - 1) a/R) | GMRES |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for n, count, radius, seeds in rows:
        for seed in seeds:
            c = cloud(n, count, radius, seed)
            out.append(c)
            print(f"| {n} | {count} | {radius:g} | {c['fraction']:.3f} | {seed} | "
                  f"{c['mean']:.4f} | {c['rotne_prager']:.4f} | {c['theory']:.4f} | "
                  f"{(c['mean'] - 1) / (c['theory'] - 1):.4f} | {c['iterations']} |",
                  flush=True)
    return out


def row_table(rows: Sequence[tuple[int, int, Sequence[float]]]) -> list[dict]:
    out = []
    print("| N (points) | spheres | spacing/a | end, middle speed / one sphere's "
          "| Rotne–Prager | largest relative difference | two spheres: ours / series |")
    print("|---|---|---|---|---|---|---|")
    for n, count, spacings in rows:
        for spacing in spacings:
            r, pair = row(n, count, spacing), row(n, 2, spacing)
            out += [r, pair]
            s, rp = np.array(r["speeds"]), np.array(r["rotne_prager"])
            mid = count // 2
            print(f"| {n} | {count} | {spacing:g} | {s[0]:.4f}, {s[mid]:.4f} | "
                  f"{rp[0]:.4f}, {rp[mid]:.4f} | {np.max(np.abs(s / rp - 1)):.1e} | "
                  f"{pair['speeds'][0]:.4f} / {pair['pair']:.4f} |", flush=True)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--full", action="store_true", help="also the slow tests' sizes")
    args = parser.parse_args()
    clouds = CLOUDS if args.full else CLOUDS[:2]
    cloud_table(clouds)
    print()
    row_table(ROWS if args.full else ROWS[:1])


if __name__ == "__main__":
    main()
