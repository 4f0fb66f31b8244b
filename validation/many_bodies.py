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

Usage (from the repository root): ``python -m validation.many_bodies [--full] [--toml]``: the
tables of docs/validation.md (``--full``: also the sizes of the slow tests; half a minute, two
minutes with ``--full`` on an idle core); ``--toml``: the values of docs/numbers.toml's
[many_cloud] and [many_row] instead.
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


def cloud_values(rows: Sequence[tuple[int, int, float, Sequence[int]]]) -> dict[str, list]:
    """The cloud table's columns (docs/numbers.toml [many_cloud]), one entry per (row, seed)."""
    clouds = [cloud(n, count, radius, seed) for n, count, radius, seeds in rows
              for seed in seeds]
    keys = ("points", "count", "radius", "seed", "fraction", "mean", "rotne_prager", "theory",
            "iterations")
    out: dict[str, list] = {key: [c[key] for c in clouds] for key in keys}
    out["collective"] = [(c["mean"] - 1) / (c["theory"] - 1) for c in clouds]
    return out


def row_values(rows: Sequence[tuple[int, int, Sequence[float]]]) -> dict[str, list]:
    """The row table's columns (docs/numbers.toml [many_row]), one entry per (row, spacing):
    the end and middle sphere's speeds, their Rotne–Prager values, the largest relative
    difference over the row, and a pair's speed against the two-sphere series."""
    out: dict[str, list] = {key: [] for key in (
        "points", "spacing", "end", "middle", "rp_end", "rp_middle", "difference", "pair",
        "series")}
    for n, count, spacings in rows:
        for spacing in spacings:
            r, pair = row(n, count, spacing), row(n, 2, spacing)
            speeds, reference = np.array(r["speeds"]), np.array(r["rotne_prager"])
            out["points"].append(n)
            out["spacing"].append(spacing)
            out["end"].append(float(speeds[0]))
            out["middle"].append(float(speeds[count // 2]))
            out["rp_end"].append(float(reference[0]))
            out["rp_middle"].append(float(reference[count // 2]))
            out["difference"].append(float(np.max(np.abs(speeds / reference - 1))))
            out["pair"].append(float(pair["speeds"][0]))
            out["series"].append(float(pair["pair"]))
    return out


#: The columns of the two tables of docs/validation.md: (heading, value, format).
CLOUD_COLUMNS = (("N (points)", "points", "d"), ("spheres", "count", "d"), ("R/a", "radius", "g"),
                 ("volume fraction", "fraction", ".3f"), ("seed", "seed", "d"),
                 ("mean speed / one sphere's", "mean", ".4f"),
                 ("Rotne–Prager", "rotne_prager", ".4f"),
                 ("1 + (6/5)(n - 1) a/R", "theory", ".4f"),
                 ("(mean - 1) / ((6/5)(n - 1) a/R)", "collective", ".4f"),
                 ("GMRES", "iterations", "d"))
ROW_COLUMNS = (("N (points)", "points", "d"), ("spacing/a", "spacing", "g"),
               ("end sphere", "end", ".4f"), ("middle sphere", "middle", ".4f"),
               ("Rotne–Prager: end", "rp_end", ".4f"), ("middle", "rp_middle", ".4f"),
               ("largest relative difference", "difference", ".1e"),
               ("two spheres", "pair", ".4f"), ("their series", "series", ".4f"))


def print_table(columns: Sequence[tuple[str, str, str]], values: dict[str, list]) -> None:
    """A markdown table of ``values`` (name -> one entry per row) in ``columns``."""
    print("| " + " | ".join(heading for heading, _, _ in columns) + " |")
    print("|" + "---|" * len(columns))
    for i in range(len(values[columns[0][1]])):
        print("| " + " | ".join(format(values[key][i], spec) for _, key, spec in columns) + " |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--full", action="store_true", help="also the slow tests' sizes")
    parser.add_argument("--toml", action="store_true", help="print docs/numbers.toml values")
    args = parser.parse_args()
    clouds = cloud_values(CLOUDS if args.full else CLOUDS[:2])
    rows = row_values(ROWS if args.full else ROWS[:1])
    if args.toml:
        from validation.report import toml_values

        print("[many_cloud]")
        print(toml_values({k: v for k, v in clouds.items() if k not in ("count", "seed")}))
        print("[many_row]")
        print(toml_values(rows))
        return
    print_table(CLOUD_COLUMNS, clouds)
    print()
    print_table(ROW_COLUMNS, rows)


if __name__ == "__main__":
    main()
