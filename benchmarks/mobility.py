"""Cost of the rigid-body solves (parastokes.mobility) against velocity evaluations, and GMRES
iterations of the block preconditioner against gap and body count.

Run from the repository root (one BLAS thread, one kernel thread, so that the LU solves and the
kernels are compared on the same core)::

    NUMBA_NUM_THREADS=1 PYTHONPATH=. python benchmarks/mobility.py \
        [--points 2000] [--sphere 400] [--rounds 5] [--parts a b] [--json PATH]

(a) One rigid sphere of ``--points`` surface points in free space: the one-time body-frame
    factorization; one mobility solve with the reused factorization (a rigid body under an
    external load: no triangular solve; and with a surface slip or background velocity: one
    pair of triangular solves); one velocity evaluation of its points from its point forces
    (``mrs.velocity``, compiled, ε per source); and with a slip fixed in the body frame
    (``slip_frame="body"``: its solve is remembered). Minimum over ``--rounds`` (the machine is
    shared). The issue's target, one RK2 step <= 3x two velocity evaluations, is completed by the
    bodies' stepping (two solves per step plus what else a step evaluates).
(b) GMRES to relative residual 1e-10 with the block-diagonal preconditioner: one sphere of
    ``--sphere`` points at gaps δ above the wall (preconditioner "free": the reused free-space
    self block; "wall": the self block with the wall images, refactorized per solve); a row of B
    such spheres at gap δ from each other and from the wall (both preconditioners); the same row
    in free space. Also
    the time of the dense and the GMRES solve for the row, where the auto choice's crossover
    (DENSE_MAX_POINTS) comes from. Each row case is solved twice in the same run: with the
    preconditioner's sweep over near bodies (the default, parastokes.mobility.precondition) and
    without it (block Jacobi, NEAR_GAP = 0), for the iterations and the seconds per iteration;
    the sweep's setup (finding the near pairs, its kernel operators) and one iteration's cost
    with and without it are measured in CPU time against one product of the whole operator
    (NEAR_GAP as in the package: at gap 0.5a no pair is coupled and both columns are the
    same solve). ``--parts cost``: that cost alone, for the rows at gap 0.1a (seconds).
    ``--parts resist``: the resistance problem (U = -e_z on each sphere) for rows of 2, 4, 8
    spheres at gaps 0.1a and 0.5a, wall and free space: GMRES iterations (seconds) with the
    default preconditioner (the rigid-mode correction of parastokes.mobility.rigid_modes in
    front of the sweep), the sweep alone, block Jacobi, and the mobility problem's (a force
    -e_z on each) for comparison; the correction's setup in CPU time against one product.
    ``--contact``: rows of 2, 4 and 8 spheres of ``--fine``
    points at gap 0.05a (400 points are too coarse for it: the placement check refuses gaps under
    half the spacing), both preconditioners, with the wall.
"""

from __future__ import annotations

import argparse
import json
import time
from contextlib import contextmanager

import numpy as np

from parastokes import mrs
from parastokes.mobility import RigidSurface, krylov, solve_mobility, solve_resistance
from parastokes.mobility import precondition as pc
from parastokes.mobility import rigid_modes as rm
from parastokes.mobility.sphere import fibonacci_sphere, sphere_spacing
from parastokes.mobility.system import SurfaceSet

MU = 1.0
TOL = 1e-10
GAPS = (0.05, 0.1, 0.25, 0.5, 1.0, 2.0)
COUNTS = (2, 4, 8, 16)
ROW_GAPS = (0.1, 0.5, 2.0)


def best(fn, rounds: int, clock=time.perf_counter) -> float:
    """Least time of ``rounds`` calls of ``fn`` on ``clock`` (wall time by default)."""
    times = []
    for _ in range(rounds):
        t = clock()
        fn()
        times.append(clock() - t)
    return min(times)


def sphere(n: int) -> RigidSurface:
    return RigidSurface(fibonacci_sphere(n), 0.5 * sphere_spacing(n), name=f"sphere{n}")


def single_body(n: int, rounds: int) -> dict:
    s = sphere(n)
    t = time.perf_counter()
    s.self_factor(MU)
    factor = time.perf_counter() - t
    rot = np.linalg.qr(np.random.default_rng(0).normal(size=(3, 3)))[0]
    rot *= np.sign(np.linalg.det(rot))
    placed = s.place((0.1, 0.2, 0.3), rot)
    slip = np.random.default_rng(1).normal(size=(n, 3))
    rigid = best(lambda: solve_mobility(placed, mu=MU, external_force=(0, 0, 1)), rounds)
    slipped = best(lambda: solve_mobility(placed, mu=MU, slip=slip), rounds)
    body_slip = best(lambda: solve_mobility(placed, mu=MU, slip=slip, slip_frame="body"), rounds)
    forces = solve_mobility(placed, mu=MU, slip=slip).forces
    pts, eps = placed.points, np.array(placed.epsilon)
    mrs.velocity(pts, pts, forces, epsilon=eps, mu=MU)  # compile
    velocity = best(lambda: mrs.velocity(pts, pts, forces, epsilon=eps, mu=MU), rounds)
    return {
        "points": n,
        "factor_s": factor,
        "solve_rigid_s": rigid,
        "solve_slip_s": slipped,
        "velocity_s": velocity,
        "rigid_over_velocity": rigid / velocity,
        "slip_over_velocity": slipped / velocity,
        "solve_body_slip_s": body_slip,
        "body_slip_over_velocity": body_slip / velocity,
    }


@contextmanager
def near_gap(gap: float | None):
    """The preconditioner's sweep over near bodies with ``gap`` (0: block Jacobi; None: as is)."""
    old = pc.NEAR_GAP
    if gap is not None:
        pc.NEAR_GAP = gap
    try:
        yield
    finally:
        pc.NEAR_GAP = old


def timed_gmres(
    bodies: list, wall: bool, precondition: str, gap: float | None = None, **loads
) -> tuple[int, float]:
    """GMRES iterations and seconds of one mobility solve of ``bodies`` under ``loads``
    (``gap``: the sweep's NEAR_GAP; 0 is block Jacobi)."""
    with near_gap(gap):
        t = time.perf_counter()
        m = solve_mobility(
            bodies, mu=MU, wall=wall, method="gmres", tol=TOL, precondition=precondition, **loads
        )
        return m.info.iterations, time.perf_counter() - t


@contextmanager
def rigid_modes(on: bool):
    """The resistance preconditioner with (default) or without the rigid-mode correction."""
    old = krylov.use_rigid_modes
    if not on:
        krylov.use_rigid_modes = lambda sset: False
    try:
        yield
    finally:
        krylov.use_rigid_modes = old


def timed_resistance(bodies: list, wall: bool, gap: float | None = None, modes: bool = True):
    """GMRES iterations and seconds of one resistance solve of ``bodies``, each moving with
    U = -e_z (``gap``: the sweep's NEAR_GAP; ``modes``: the rigid-mode correction)."""
    with near_gap(gap), rigid_modes(modes):
        t = time.perf_counter()
        r = solve_resistance(bodies, (0, 0, -1), mu=MU, wall=wall, method="gmres", tol=TOL)
        return r.info.iterations, time.perf_counter() - t


def correction_setup(bodies: list, wall: bool, rounds: int) -> float:
    """CPU time of the rigid-mode correction's setup (M Z, C's LU) over one product."""
    sset = SurfaceSet(bodies, MU, wall)
    factors = pc.block_factors(sset, "free")
    sweep = pc.BlockSweep(sset, factors)
    rv = np.random.default_rng(2).normal(size=3 * sset.n_points)
    op = sset.operator()
    op.matvec(rv)
    setup = cpu_best(lambda: rm.RigidModeSweep(sset, factors, sweep), rounds)
    return setup / cpu_best(lambda: op.matvec(rv), rounds)


def resistance_solves(bodies: list, wall: bool) -> dict[str, tuple[int, float]]:
    """(iterations, seconds) of the resistance solve of ``bodies`` with the default
    preconditioner, the sweep alone and block Jacobi, and of the mobility problem of the same
    bodies (a force -e_z on each)."""
    return {
        "default": timed_resistance(bodies, wall),
        "sweep": timed_resistance(bodies, wall, modes=False),
        "jacobi": timed_resistance(bodies, wall, gap=0.0, modes=False),
        "mobility": timed_gmres(bodies, wall, "free", external_force=(0, 0, -1)),
    }


def resistance_rows(n: int, rounds: int = 3) -> list[dict]:
    """Resistance iterations of rows of 2, 4, 8 spheres of ``n`` points (docs/benchmarks.md,
    (b)): default, sweep alone, block Jacobi, and the mobility problem's; the correction's setup
    (CPU) over one product of the whole operator."""
    s = sphere(n)
    rows = []
    for count in (2, 4, 8):
        for gap in (0.1, 0.5):
            for wall in (True, False):
                bodies = row_bodies(s, count, gap)
                rows.append(
                    {
                        "bodies": count,
                        "gap": gap,
                        "wall": wall,
                        **resistance_solves(bodies, wall),
                        "setup_over_product": correction_setup(bodies, wall, rounds),
                    }
                )
    return rows


def cpu_best(fn, rounds: int) -> float:
    """Least CPU time of this process over ``rounds`` calls of ``fn`` (one kernel and one BLAS
    thread: the work, without the time the shared machine did not schedule us)."""
    return best(fn, rounds, time.process_time)


def sweep_cost(bodies: list, wall: bool, rounds: int = 5) -> dict:
    """CPU seconds of the sweep's setup (near pairs and their kernel operators, blocks
    excluded), of one application of the preconditioner with and without the sweep (mobility
    problem, "free" blocks) and of one product of the whole operator; the ratio of one GMRES
    iteration's cost with and without the sweep (product + preconditioner)."""
    sset = SurfaceSet(bodies, MU, wall)
    op = sset.operator()
    rng = np.random.default_rng(2)
    rv, rft = rng.normal(size=3 * sset.n_points), rng.normal(size=(sset.n_bodies, 6))
    factors = pc.block_factors(sset, "free")
    swept, jacobi = pc.BlockSweep(sset, factors), pc.BlockSweep(sset, factors, gap=0.0)
    op.matvec(rv), swept.saddle(rv, rft)
    out = {
        "couplings": swept.n_couplings,
        "setup_s": cpu_best(lambda: pc.BlockSweep(sset, []), rounds),
        "matvec_s": cpu_best(lambda: op.matvec(rv), rounds),
        "swept_s": cpu_best(lambda: swept.saddle(rv, rft), rounds),
        "jacobi_s": cpu_best(lambda: jacobi.saddle(rv, rft), rounds),
    }
    out["per_iteration"] = (out["matvec_s"] + out["swept_s"]) / (out["matvec_s"] + out["jacobi_s"])
    return out


def wall_gaps(n: int) -> list[dict]:
    s = sphere(n)
    rows = []
    for gap in GAPS:
        row: dict = {"gap": gap}
        for block in ("free", "wall"):
            row[block] = timed_gmres(gap_bodies(s, gap), True, block, **GAP_LOADS)
        rows.append(row)
    return rows


#: the loads of the one-sphere case: a force along and toward the wall, a torque
GAP_LOADS = {"external_torque": (0, 1, 0), "external_force": (1, 0, -1)}
#: the row's solvers: (column, wall, preconditioner)
ROW_SOLVERS = (("wall", True, "free"), ("wall_pc", True, "wall"), ("free", False, "free"))


def gap_bodies(s: RigidSurface, gap: float) -> list:
    """One sphere at ``gap`` above the wall (docs/benchmarks.md, (b))."""
    return [s.place((0, 0, 1 + gap))]


def row_bodies(s: RigidSurface, count: int, gap: float) -> list:
    """A row of ``count`` spheres at ``gap`` from each other and from the wall."""
    return [s.place((i * (2 + gap), 0.0, 1 + gap)) for i in range(count)]


def body_rows(n: int) -> list[dict]:
    s = sphere(n)
    rows = []
    for count in COUNTS:
        for gap in ROW_GAPS:
            bodies = row_bodies(s, count, gap)
            row: dict = {"bodies": count, "gap": gap}
            for key, wall, block in ROW_SOLVERS:
                row[key] = timed_gmres(bodies, wall, block, external_force=(0, 0, -1))
                row[key + "_jacobi"] = timed_gmres(
                    bodies, wall, block, gap=0.0, external_force=(0, 0, -1)
                )
            row["sweep"] = sweep_cost(bodies, True)
            if count * n <= 1600 and gap == ROW_GAPS[1]:
                t = time.perf_counter()
                solve_mobility(bodies, mu=MU, wall=True, method="dense", external_force=(0, 0, -1))
                row["dense_wall_s"] = time.perf_counter() - t
            rows.append(row)
    return rows


def contact_rows(n: int, gap: float = 0.05) -> list[dict]:
    """Rows of 2, 4, 8 spheres of ``n`` points at ``gap`` above the wall, both preconditioners,
    with and without the sweep."""
    s = sphere(n)
    rows = []
    for count in (2, 4, 8):
        bodies = row_bodies(s, count, gap)
        row: dict = {"bodies": count, "gap": gap, "points": n}
        for key, block in (("wall", "free"), ("wall_pc", "wall")):
            row[key] = timed_gmres(bodies, True, block, external_force=(0, 0, -1))
            row[key + "_jacobi"] = timed_gmres(
                bodies, True, block, gap=0.0, external_force=(0, 0, -1)
            )
        rows.append(row)
    return rows


def cell(result: tuple[int, float]) -> str:
    """GMRES iterations and seconds as "its (s)"."""
    return f"{result[0]:3d} ({result[1]:.2f})"


def pair(r: dict, key: str) -> str:
    """Cells "swept / Jacobi" of ``key``, with the ratio of their seconds per iteration."""
    a, b = r[key], r[key + "_jacobi"]
    ratio = (a[1] / max(a[0], 1)) / (b[1] / max(b[0], 1))
    return f"{cell(a)} / {cell(b)} [{ratio:.2f}]"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--points", type=int, default=2000)
    parser.add_argument("--sphere", type=int, default=400)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--json", type=str, default=None)
    parser.add_argument(
        "--parts", nargs="+", choices=("a", "b", "cost", "resist"), default=["a", "b"]
    )
    parser.add_argument("--contact", action="store_true", help="rows at gap 0.05a (--fine)")
    parser.add_argument("--fine", type=int, default=1200)
    args = parser.parse_args()
    out: dict = {}
    if "a" in args.parts:
        out["single"] = single_body(args.points, args.rounds)
        a = out["single"]
        print(f"(a) one sphere, {a['points']} points, free space")
        print(f"    body-frame factorization (once): {a['factor_s']:.3f} s")
        print(f"    one velocity evaluation of its points: {1e3 * a['velocity_s']:.2f} ms")
        print(
            f"    solve, rigid under a load: {1e3 * a['solve_rigid_s']:.2f} ms "
            f"= {a['rigid_over_velocity']:.2f} x one velocity evaluation"
        )
        print(
            f"    solve, with a slip:        {1e3 * a['solve_slip_s']:.2f} ms "
            f"= {a['slip_over_velocity']:.2f} x one velocity evaluation"
        )
        print(
            f"    solve, with a slip fixed in the body frame (slip_frame='body', reused): "
            f"{1e3 * a['solve_body_slip_s']:.2f} ms "
            f"= {a['body_slip_over_velocity']:.2f} x one velocity evaluation"
        )
    if "b" in args.parts:
        out["wall_gap"] = wall_gaps(args.sphere)
        print(f"(b) GMRES iterations to {TOL:g}, one sphere of {args.sphere} points above the wall")
        print("    gap/a | precondition free: its (s) | wall: its (s)")
        for r in out["wall_gap"]:
            print(f"    {r['gap']:5.2f} | {cell(r['free'])} | {cell(r['wall'])}")
        out["rows"] = body_rows(args.sphere)
        print(f"    B spheres of {args.sphere} points in a row, gap δ between them and to the wall")
        print("    each cell: swept its (s) / block Jacobi its (s) [seconds per iteration, ratio]")
        print(
            "    B | gap/a | wall: its (s) | wall, precondition 'wall': its (s) "
            "| free space: its (s) | dense with wall (s) "
            "| sweep: pairs, setup / one product, one iteration swept / Jacobi (CPU)"
        )
        for r in out["rows"]:
            dense = f"{r['dense_wall_s']:.2f}" if "dense_wall_s" in r else "-"
            sw = r["sweep"]
            print(
                f"    {r['bodies']:2d} | {r['gap']:4.1f} | {pair(r, 'wall')} "
                f"| {pair(r, 'wall_pc')} | {pair(r, 'free')} | {dense} "
                f"| {sw['couplings']}, {sw['setup_s'] / sw['matvec_s']:.3f}, "
                f"{sw['per_iteration']:.2f}"
            )
    if "cost" in args.parts:
        out["cost"] = [
            {"bodies": count, **sweep_cost(row_bodies(sphere(args.sphere), count, 0.1), True)}
            for count in COUNTS
        ]
        print(f"    the sweep's cost, rows of {args.sphere}-point spheres at gap 0.1a, wall (CPU)")
        print("    B | pairs | setup / one product | one iteration, swept / Jacobi")
        for r in out["cost"]:
            print(
                f"    {r['bodies']:2d} | {r['couplings']:2d} | {r['setup_s'] / r['matvec_s']:.3f} "
                f"| {r['per_iteration']:.3f}"
            )
    if "resist" in args.parts:
        out["resist"] = resistance_rows(args.sphere)
        print(f"    resistance problem, rows of {args.sphere}-point spheres, U = -e_z on each")
        print(
            "    B | gap/a | wall | default its (s) | sweep alone | block Jacobi "
            "| mobility (force -e_z) | correction setup / one product (CPU)"
        )
        for r in out["resist"]:
            print(
                f"    {r['bodies']:2d} | {r['gap']:4.1f} | {'yes' if r['wall'] else 'no ':3s} "
                f"| {cell(r['default'])} | {cell(r['sweep'])} | {cell(r['jacobi'])} "
                f"| {cell(r['mobility'])} | {r['setup_over_product']:.2f}"
            )
    if args.contact:
        out["contact"] = contact_rows(args.fine)
        print(f"    B spheres of {args.fine} points at gap 0.05a, wall; swept / block Jacobi")
        print("    B | precondition 'free' | precondition 'wall'")
        for r in out["contact"]:
            print(f"    {r['bodies']:2d} | {pair(r, 'wall')} | {pair(r, 'wall_pc')}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(out, fh, indent=1)


if __name__ == "__main__":
    main()
