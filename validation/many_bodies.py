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
3. The circulation inside a cloud: relative to the cloud, its spheres move as the inside of a
   Hadamard–Rybczynski drop of viscosity ratio 1 (:func:`drop_flow`); each sphere's velocity
   less the mean regressed on it (:func:`circulation`).
4. The cloud in time (``--tail``): 100 spheres falling some 28 cloud radii (RK2; the spheres
   kept apart by a short-range :func:`repulsion`), where the spheres that leave it go
   (:func:`tail_shape`; Nitsche & Batchelor: from its rear into a vertical tail).

Usage (from the repository root): ``python -m validation.many_bodies [--full] [--toml]``: the
tables of docs/validation.md (``--full``: also the sizes of the slow tests; half a minute, two
minutes with ``--full`` on an idle core); ``--toml``: the values of docs/numbers.toml's
[many_cloud], [many_row] and [many_circulation] instead. ``--tail [--until T]``: the cloud in
time (about 10 minutes of CPU), written to docs/figures/cloud_tail.json and cloud_tail.png.
"""

from __future__ import annotations

import argparse
import itertools
import json
import time
from collections.abc import Sequence
from pathlib import Path

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
#: (surface points, spheres, cloud radius R, seeds) of the circulation table; 250 spheres slow
CIRCULATIONS = ((42, 30, 8.0, (1, 2, 3)), (42, 100, 12.0, (1, 2, 3)), (42, 250, 16.0, (1, 2, 3)))
#: the range (largest gap, in a) and the strength (over the weight) of :func:`repulsion`
REPULSION_RANGE, REPULSION_FORCE = 0.5, 4.0
#: a sphere has left the cloud beyond this many R from the centroid of the rest
TAIL_REACH = 1.2
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


def rotne_prager_velocities(centers: np.ndarray, a: float) -> np.ndarray:
    """Each sphere's velocity (n, 3) over one sphere's speed alone, equal forces f = -e_z, from
    the Rotne–Prager tensor of every other sphere: f + Σ (3a/4r) [(1 + 2a²/3r²) f
    + (1 - 2a²/r²)(f·r̂) r̂]."""
    d = centers[:, None, :] - centers[None, :, :]
    r = np.linalg.norm(d, axis=-1)
    np.fill_diagonal(r, np.inf)
    along = -d[..., 2] / r  # f·r̂
    isotropic = 0.75 * a / r * (1 + 2 * a * a / (3 * r * r))
    radial = 0.75 * a / r * (1 - 2 * a * a / (r * r)) * along / r
    out = np.einsum("ij,ijk->ik", radial, d)
    out[:, 2] -= 1.0 + isotropic.sum(axis=1)
    return out


def rotne_prager(centers: np.ndarray, a: float) -> np.ndarray:
    """Each sphere's speed over one alone (:func:`rotne_prager_velocities`, downwards):
    1 + Σ (3a/4r) [(1 + 2a²/3r²) + (1 - 2a²/r²) cos²θ], θ from the vertical."""
    return -rotne_prager_velocities(centers, a)[:, 2]


def velocities(surface: RigidSurface, centers: np.ndarray,
               forces=(0.0, 0.0, -1.0)) -> tuple[np.ndarray, int]:
    """Each sphere's velocity (n, 3) over one sphere's speed alone when all fall together under
    equal forces -e_z (or ``forces``, (n, 3)), one mobility solve (GMRES), and the GMRES
    iterations."""
    solved = solve_mobility([surface.place(c) for c in centers], mu=MU,
                            external_force=forces, method="gmres")
    return solved.U / single_speed(surface), solved.info.iterations


def speeds(surface: RigidSurface, centers: np.ndarray) -> tuple[np.ndarray, int]:
    """Each sphere's speed over one alone (:func:`velocities`, downwards), and the GMRES
    iterations."""
    velocity, iterations = velocities(surface, centers)
    return -velocity[:, 2], iterations


def cloud_centers(count: int, radius: float, seed: int) -> np.ndarray:
    """The centres of a random cloud of ``count`` spheres in a sphere of radius ``radius`` about
    the origin (the ``[[suspensions]]`` placement, gap :data:`CLOUD_GAP`)."""
    centers, _ = random_centers(count, "sphere", [0.0, 0.0, 0.0], None, radius, 1.0,
                                2.0 + CLOUD_GAP, np.random.default_rng(seed))
    return centers


def cloud(n: int, count: int, radius: float, seed: int) -> dict:
    """One random cloud (see the module): the mean speed over one sphere's, the Rotne–Prager
    mean of the same configuration, Nitsche & Batchelor's 1 + (6/5)(count - 1) a_eff/R."""
    surface = sphere(n)
    a = effective_radius(surface)
    centers = cloud_centers(count, radius, seed)
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


def drop_flow(offsets: np.ndarray, radius: float) -> np.ndarray:
    """The flow (n, 3) inside a Hadamard–Rybczynski drop of radius R and viscosity ratio λ = 1
    falling at unit speed along -z, relative to the drop, at ``offsets`` from its centre (z up,
    ρ the distance from the vertical axis): from ψ = r² sin²θ (r²/R² - 1)/(4(1 + λ)),
    u_z = ((z² + 2ρ²)/R² - 1)/4 (mean 0 over the ball: -1/4 at the centre, which falls
    ahead, +1/4 at the equator's edge, which lags) and u_ρ = -ρz/(4R²) (inwards above the
    centre, outwards below)."""
    x, y, z = np.asarray(offsets, dtype=float).T
    scale = 0.25 / radius**2
    return np.column_stack([-scale * x * z, -scale * y * z,
                            scale * (z * z + 2 * (x * x + y * y)) - 0.25])


def circulation(centers: np.ndarray, velocity: np.ndarray) -> dict[str, float]:
    """How the spheres' velocities relative to their mean follow the drop's internal flow.

    ``velocity`` (n, 3) over one sphere's speed U_0 (falling along -z). The drop is the ball
    with the centres' centroid and second moment, R_d = (5/3 <|x - x̄|²>)^1/2 (the radius of a
    uniform ball of the same spread: the force density lives at the centres), falling at the
    collective speed U_c = -<u_z> - 1 (the mean speed less the sphere's own). Each sphere's
    velocity less the mean is regressed on U_c :func:`drop_flow`: the slope (1 for the drop)
    and the correlation coefficient, vertically and horizontally (x and y together)."""
    offsets = centers - centers.mean(axis=0)
    radius = float(np.sqrt(5 / 3 * np.mean(np.sum(offsets**2, axis=1))))
    collective = float(-velocity[:, 2].mean() - 1.0)
    predicted = collective * drop_flow(offsets, radius)
    predicted -= predicted.mean(axis=0)
    relative = velocity - velocity.mean(axis=0)
    out = {"drop_radius": radius, "collective": collective}
    for name, columns in (("z", [2]), ("h", [0, 1])):
        p, m = predicted[:, columns].ravel(), relative[:, columns].ravel()
        out[f"slope_{name}"] = float(p @ m / (p @ p))
        out[f"correlation_{name}"] = float(p @ m / np.sqrt((p @ p) * (m @ m)))
    return out


def cloud_circulation(n: int, count: int, radius: float, seed: int) -> dict:
    """:func:`circulation` of one random cloud (the cloud table's), from one mobility solve,
    and the slopes of the Rotne–Prager velocities of the same configuration (``rp_slope_z``,
    ``rp_slope_h``: the pairwise sum, without the reflections)."""
    surface = sphere(n)
    centers = cloud_centers(count, radius, seed)
    velocity, _ = velocities(surface, centers)
    pairwise = circulation(centers, rotne_prager_velocities(centers, effective_radius(surface)))
    return {"points": n, "count": count, "radius": radius, "seed": seed,
            **circulation(centers, velocity),
            "rp_slope_z": pairwise["slope_z"], "rp_slope_h": pairwise["slope_h"]}


def circulation_values(rows: Sequence[tuple[int, int, float, Sequence[int]]]
                       ) -> dict[str, list]:
    """The circulation table's columns (docs/numbers.toml [many_circulation])."""
    found = [cloud_circulation(n, count, radius, seed) for n, count, radius, seeds in rows
             for seed in seeds]
    return {key: [c[key] for c in found] for key in found[0]}


def repulsion(centers: np.ndarray) -> np.ndarray:
    """The short-range forces (n, 3) that keep the spheres of a falling cloud apart: between two
    spheres whose surfaces come within :data:`REPULSION_RANGE` (gap h), a push apart along the
    line of centres of :data:`REPULSION_FORCE` (1 - h/range)² times the weight."""
    d = centers[:, None, :] - centers[None, :, :]
    r = np.linalg.norm(d, axis=-1)
    np.fill_diagonal(r, np.inf)
    push = REPULSION_FORCE * np.clip(1 - (r - 2.0) / REPULSION_RANGE, 0.0, None) ** 2
    return np.einsum("ij,ijk->ik", push / r, d)


def fall(centers: np.ndarray, times: Sequence[float], dt: float, n: int = 42,
         report=None) -> list[np.ndarray]:
    """The sphere centres (m, 3) of a cloud starting at ``centers`` at ``times`` (in a/U_0, the
    first the start's) as it falls: RK2 (Heun) steps of about ``dt`` a/U_0, each sphere of
    ``n`` points moved by the mobility solve of all under its weight -e_z and
    :func:`repulsion` (:func:`velocities`). ``report(i, centres)`` is called as each time is
    reached."""
    surface = sphere(n)

    def rates(x: np.ndarray) -> np.ndarray:
        return velocities(surface, x, repulsion(x) - [0.0, 0.0, 1.0])[0]

    x = np.array(centers, dtype=float)
    out = [x.copy()]
    for t0, t1 in itertools.pairwise(times):
        if report is not None:
            report(len(out) - 1, out[-1])
        steps = max(1, round((t1 - t0) / dt))
        h = (t1 - t0) / steps
        for _ in range(steps):
            k1 = rates(x)
            x = x + 0.5 * h * (k1 + rates(x + h * k1))
        out.append(x.copy())
    if report is not None:
        report(len(out) - 1, out[-1])
    return out


def tail_shape(centers: np.ndarray, radius: float) -> dict:
    """Where the spheres of a falling cloud are: the cloud is the spheres within
    :data:`TAIL_REACH` R of the centroid of the cloud (found by iterating from all), the rest
    have left it; each of those lies above (behind: within 45° of the upward vertical through
    the centroid), below (ahead) or beside. Also the cloud's shape: the rms vertical offset over
    the rms horizontal one (1 for a ball, below 1 oblate), and the least distance between two
    centres (2 at contact). ``highest``: the farthest sphere above the centroid, over R."""
    inside = np.ones(len(centers), dtype=bool)
    for _ in range(50):
        middle = centers[inside].mean(axis=0)
        now = np.linalg.norm(centers - middle, axis=1) <= TAIL_REACH * radius
        if (now == inside).all():
            break
        inside = now
    offsets = centers - middle
    vertical, horizontal = offsets[:, 2], np.hypot(offsets[:, 0], offsets[:, 1])
    left = ~inside
    gaps = np.linalg.norm(centers[:, None] - centers[None], axis=-1)
    np.fill_diagonal(gaps, np.inf)
    return {"centroid": middle.tolist(), "left": int(left.sum()),
            "above": int((left & (vertical > horizontal)).sum()),
            "below": int((left & (-vertical > horizontal)).sum()),
            "beside": int((left & (np.abs(vertical) <= horizontal)).sum()),
            "highest": float(vertical.max() / radius),
            "aspect": float(np.sqrt(np.mean(vertical[inside] ** 2)
                                    / np.mean(horizontal[inside] ** 2 / 2))),
            "closest": float(gaps.min())}


def tail(count: int = 100, radius: float = 12.0, seed: int = 1, until: float = 30.0,
         every: float = 2.5, dt: float = 0.05, path: Path | None = None,
         resume: dict | None = None) -> dict:
    """The cloud of ``count`` spheres falling until ``until`` a/U_0 (:func:`fall`), and
    :func:`tail_shape` every ``every``: the distance fallen in R, how many spheres have left
    and where. Also the circulation over the first ``every`` (:func:`circulation` of the
    displacements over the time). With ``path``, the summary is written there (JSON) after
    every record; ``resume``: such a summary to go on from (its last state and time, the same
    steps as one run)."""
    summary: dict = resume or {
        "count": count, "radius": radius, "seed": seed, "dt": dt,
        "reach": TAIL_REACH, "repulsion": [REPULSION_RANGE, REPULSION_FORCE], "times": [],
        "records": [], "seconds": []}
    begin = summary["times"][-1] if resume else 0.0
    times = list(np.arange(begin, until + every / 2, every))
    offset = len(summary["times"]) - 1 if resume else 0
    cpu = time.process_time() - (summary["seconds"][-1] if resume else 0.0)

    def record(i: int, x: np.ndarray) -> None:
        if resume and i == 0:
            return
        first = np.array(summary.get("first", x))
        shape = tail_shape(x, radius)
        top = summary["records"][0]["centroid"][2] if summary["records"] else shape["centroid"][2]
        shape["fallen"] = (top - shape["centroid"][2]) / radius
        summary["times"].append(times[i])
        summary["records"].append(shape)
        summary["seconds"].append(time.process_time() - cpu)
        if i + offset == 1:
            summary["circulation"] = circulation(first, (x - first) / times[i])
        summary["first"], summary["last"] = first.tolist(), x.tolist()
        if path is not None:
            path.write_text(json.dumps(summary) + "\n")

    x0 = np.array(resume["last"]) if resume else cloud_centers(count, radius, seed)
    fall(x0, times, dt, report=record)
    return summary


def step_check(count: int = 100, radius: float = 12.0, seed: int = 1, span: float = 2.0,
               dt: float = 0.05) -> dict:
    """The step's error: the centres after ``span`` a/U_0 with steps ``dt`` and ``dt/2``, the
    largest distance between the two (in a) and the mean displacement relative to the
    centroid over the span (what the error is compared with)."""
    first, coarse = fall(cloud_centers(count, radius, seed), [0.0, span], dt)
    fine = fall(first, [0.0, span], dt / 2)[1]
    moved = (coarse - coarse.mean(axis=0)) - (first - first.mean(axis=0))
    return {"span": span, "dt": dt, "difference": float(np.linalg.norm(coarse - fine,
                                                                        axis=1).max()),
            "relative_motion": float(np.linalg.norm(moved, axis=1).mean())}


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


def plot_tail(summary: dict, path: Path) -> None:
    """Side view (x, z) of the sphere centres at the first and the last time, each about its
    cloud's centroid, the spheres that have left the cloud hollow."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    radius = summary["radius"]
    fig, axes = plt.subplots(1, 2, figsize=(4.6, 5.0), sharex=True, sharey=True)
    for ax, key, i in zip(axes, ("first", "last"), (0, -1), strict=True):
        x = np.array(summary[key]) - summary["records"][i]["centroid"]
        left = np.linalg.norm(x, axis=1) > TAIL_REACH * radius
        ax.scatter(x[~left, 0] / radius, x[~left, 2] / radius, s=12, c="tab:blue")
        ax.scatter(x[left, 0] / radius, x[left, 2] / radius, s=12, facecolors="none",
                   edgecolors="tab:red")
        ax.add_patch(plt.Circle((0, 0), TAIL_REACH, fill=False, ls="--", color="0.5"))
        ax.set_aspect("equal")
        ax.set_xlabel("x / R")
        ax.set_title(f"t = {summary['times'][i]:g} a/U₀\nfallen "
                     f"{summary['records'][i]['fallen']:.1f} R", fontsize=10)
    axes[0].set_ylabel("z / R (up; gravity down)")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


#: The columns of the circulation and the tail tables: (heading, value, format).
CIRCULATION_COLUMNS = (("spheres", "count", "d"), ("R/a", "radius", "g"), ("seed", "seed", "d"),
                       ("R_d/a", "drop_radius", ".2f"), ("U_c/U₀", "collective", ".3f"),
                       ("slope: u_z", "slope_z", ".3f"), ("correlation", "correlation_z", ".3f"),
                       ("slope: u_x, u_y", "slope_h", ".3f"),
                       ("correlation", "correlation_h", ".3f"),
                       ("Rotne–Prager slope: u_z", "rp_slope_z", ".3f"),
                       ("u_x, u_y", "rp_slope_h", ".3f"))
TAIL_COLUMNS = (("t U₀/a", "time", "g"), ("fallen / R", "fallen", ".1f"),
                ("left (beyond 1.2 R)", "left", "d"), ("above", "above", "d"),
                ("below", "below", "d"), ("beside", "beside", "d"),
                ("highest / R", "highest", ".2f"), ("rms vertical / horizontal", "aspect", ".2f"),
                ("closest centres / a", "closest", ".2f"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--full", action="store_true", help="also the slow tests' sizes")
    parser.add_argument("--toml", action="store_true", help="print docs/numbers.toml values")
    parser.add_argument("--tail", action="store_true",
                        help="the 100-sphere cloud falling (about 10 minutes): the step check, "
                        "docs/figures/cloud_tail.json and .png, the table")
    parser.add_argument("--until", type=float, default=30.0, help="--tail: the time in a/U_0")
    parser.add_argument("--resume", action="store_true",
                        help="--tail: go on from docs/figures/cloud_tail.json to --until")
    args = parser.parse_args()
    if args.tail:
        figures = Path(__file__).resolve().parents[1] / "docs" / "figures"
        path = figures / "cloud_tail.json"
        before = json.loads(path.read_text()) if args.resume else None
        check = before["step_check"] if before is not None else step_check()
        print(f"step check over {check['span']:g} a/U_0: dt = {check['dt']:g} against "
              f"{check['dt'] / 2:g}: {check['difference']:.2e} a apart, relative motion "
              f"{check['relative_motion']:.3f} a", flush=True)
        summary = tail(until=args.until, path=path, resume=before)
        summary["step_check"] = check
        path.write_text(json.dumps(summary) + "\n")
        plot_tail(summary, figures / "cloud_tail.png")
        print_table(TAIL_COLUMNS, {"time": summary["times"], **{
            key: [r[key] for r in summary["records"]] for key in summary["records"][0]}})
        print(f"circulation over the first {summary['times'][1]:g} a/U_0: "
              + ", ".join(f"{k} {v:.3f}" for k, v in summary["circulation"].items()))
        return
    clouds = cloud_values(CLOUDS if args.full else CLOUDS[:2])
    rows = row_values(ROWS if args.full else ROWS[:1])
    circulations = circulation_values(CIRCULATIONS if args.full else CIRCULATIONS[:2])
    if args.toml:
        from validation.report import toml_values

        print("[many_cloud]")
        print(toml_values({k: v for k, v in clouds.items() if k not in ("count", "seed")}))
        print("[many_row]")
        print(toml_values(rows))
        print("[many_circulation]")
        print(toml_values({k: v for k, v in circulations.items()
                          if k not in ("points", "count", "seed")}))
        return
    print_table(CLOUD_COLUMNS, clouds)
    print()
    print_table(ROW_COLUMNS, rows)
    print()
    print_table(CIRCULATION_COLUMNS, circulations)


if __name__ == "__main__":
    main()
