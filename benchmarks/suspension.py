"""Cost, memory and GMRES iterations of the mobility solve of many rigid bodies (docs/benchmarks.md,
"Suspensions").

Run from the repository root, one kernel thread (the solves limit BLAS to the kernels' count)::

    NUMBA_NUM_THREADS=1 PYTHONPATH=. python benchmarks/suspension.py \
        [--parts scaling scene64 coarse rods] [--counts 1 10 100 1000] [--points 42] \
        [--fraction 0.05] [--rounds 3] [--json PATH]

(scaling) B spheres of radius 1 and ``--points`` surface points sedimenting above the wall, placed
    at random in a cube at volume fraction ``--fraction`` (``[[suspensions]]``, seed 1; the cube's
    bottom half a radius above the wall), built from a config as a run builds them: one
    evaluation of the scene (``Scene.rates``: its one mobility solve, GMRES with the per-body
    blocks; ``Scene.coupled``), its GMRES iterations, one product of the fluid operator over all
    surface points, the evaluation over the product, and the memory of an evaluation: numpy's
    peak allocation during it (tracemalloc, the last round) per surface point, against the
    (3N)² floats a dense operator would take. CPU time of this process, least of ``--rounds``
    (one round from 1000 bodies on: one product and one evaluation, about 3 minutes).
(scene64) 64 spheres of 150 points (9,600 points) on a 4 x 4 x 4 lattice above the wall,
    lowest layer at height 3a, spacing 3a (volume fraction 0.155) and 4a (0.065): one
    evaluation over one product, measured alternately, least of ``--rounds``.
(coarse) Coarse corrections tried on the mobility problem (dense matrices, 27 spheres of 42
    points on a lattice of spacing 3a above the wall, GMRES to 1e-10 with restart 200): the
    iterations with the per-body saddle blocks alone (block Jacobi), and with a multiplicative
    Galerkin coarse correction in front of them on each body's rigid modes ([Z; I]: the forces
    of its unit rigid motions alone with the motions), on the 12 B vectors of those forces and
    motions apart, and on each body's five strain modes (the blocks' response to a straining
    flow E (x - c) on it alone).
(rods) 1, 5, 10 and 25 rods of 51 points above the wall (experiments/rods_25.toml with
    ``model.n_rods``): one rate evaluation (the rods' forces, one product of the fluid operator
    for u and w from f and n, the rods' frames; no solve), least of ``--rounds``, and its peak
    allocation (tracemalloc) per point.
(hosted) The host's share of the GPU executor's hosted solves (docs/parallel.md, ``gpu``),
    measured without a device: 1, 2 and 4 evaluations of the 64-sphere scene (lattice 4a) and of
    100 spheres of 42 points as hosted solves, their batched products computed by the CPU kernels
    in the router's thread; wall time less the products' time is the host's work per round.
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import time
import tracemalloc
from collections.abc import Callable

import numpy as np
import scipy.linalg as sla
from scipy.sparse.linalg import LinearOperator, gmres

from parastokes import config, mrs
from parastokes.mobility import RigidSurface
from parastokes.mobility.sphere import fibonacci_sphere, sphere_spacing
from parastokes.mobility.system import SurfaceSet
from parastokes.mrs.operator import StokesletOperator

MU = 1e-6
#: a Stokes speed of 1 μm/s for a sphere of radius 1 μm: 6 π μ a
WEIGHT = 6 * math.pi * MU

def scene_config(placement: dict, points: int) -> tuple:
    """The configuration (and its resolved values) of one suspension of spheres of ``points``
    points (``placement``: the keys of its table) sedimenting above the wall: the solvers of a
    tiny serial run, which the benchmark does not use."""
    data = {
        "title": "suspension benchmark",
        "scene": {"viscosity": MU, "wall": True},
        "suspensions": [{"name": "s", **placement, "body": {
            "kind": "rigid", "radius": 1.0, "n_points": points,
            "force": [0.0, 0.0, -WEIGHT]}}],
        "time": {"t1": 0.1}, "fine": {"dt": 0.05}, "coarse": {"dt_ratio": 2},
        "parareal": {"n_slices": 2}, "execution": {"executor": "serial"},
    }
    cfg = config.parse(data)
    return cfg, config.resolve(cfg)


def random_placement(count: int, fraction: float) -> dict:
    """``count`` spheres at random in a cube at volume ``fraction``, half a radius above the
    wall."""
    edge = (count * 4 / 3 * math.pi / fraction) ** (1 / 3)
    return {"placement": "random", "count": count, "size": [edge] * 3,
            "center": [0.0, 0.0, 0.5 + edge / 2], "seed": 1}


def lattice_placement(spacing: float, counts: tuple[int, int, int] = (4, 4, 4)) -> dict:
    """``counts`` spheres (4 x 4 x 4) ``spacing`` apart, the lowest layer at height 3."""
    return {"placement": "lattice", "counts": list(counts), "spacing": spacing,
            "center": [0.0, 0.0, 3 + (counts[2] - 1) / 2 * spacing]}


def cpu_best(fn: Callable[[], object], rounds: int) -> float:
    """Least CPU time of this process over ``rounds`` calls of ``fn``."""
    times = []
    for _ in range(rounds):
        t = time.process_time()
        fn()
        times.append(time.process_time() - t)
    return min(times)


def measure(setup: tuple, rounds: int) -> dict:
    """One evaluation of the scene of ``setup`` (:func:`scene_config`: its coupled solve)
    against one product of its
    operator (see the module), alternated ``rounds`` times; the last evaluation under
    tracemalloc for its memory. The first evaluation includes the body-frame factorization of
    the sphere (once per shape: a few ms at 42 points)."""
    scene = config.build(*setup).system
    x0 = scene.initial_state()
    surfaces = [body.surface(0.0, block) for body, block in zip(scene.bodies, scene.blocks(x0),
                                                                 strict=True)]
    points = np.concatenate([s.points for s in surfaces])
    epsilon = np.concatenate([np.full(len(s.points), s.epsilon) for s in surfaces])
    op = StokesletOperator(None, points, epsilon, MU, wall=True)
    f = np.random.default_rng(0).normal(size=3 * len(points))
    op.matvec(f)  # compiled
    product, evaluation = [], []
    for i in range(rounds):
        product.append(cpu_best(lambda: op.matvec(f), 1))
        if i == rounds - 1:
            tracemalloc.start()
        t = time.process_time()
        coupled = scene.coupled(0.0, x0)
        evaluation.append(time.process_time() - t)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    n = len(points)
    return {
        "bodies": len(surfaces), "points": n,
        "iterations": coupled.solution.info.iterations,
        "residual": coupled.solution.info.residual,
        "product_s": min(product), "evaluation_s": min(evaluation),
        "ratio": min(evaluation) / min(product),
        "peak_bytes": peak, "bytes_per_point": peak / n, "dense_bytes": (3 * n) ** 2 * 8,
    }


def scaling(counts: list[int], points: int, fraction: float, rounds: int) -> list[dict]:
    out = []
    for count in counts:
        row = measure(scene_config(random_placement(count, fraction), points),
                      rounds if count < 1000 else 1)
        out.append(row)
        print(f"    {row['bodies']:5d} | {row['points']:6d} | {row['iterations']:3d} | "
              f"{row['evaluation_s']:8.3f} | {row['product_s']:7.3f} | {row['ratio']:5.2f} | "
              f"{row['peak_bytes'] / 2**20:8.1f} | {row['bytes_per_point']:6.0f} | "
              f"{row['dense_bytes'] / 2**30:9.3g}", flush=True)
    return out


def scene64(rounds: int) -> list[dict]:
    out = []
    for spacing in (3.0, 4.0):
        row = {"spacing": spacing,
               **measure(scene_config(lattice_placement(spacing), 150), rounds)}
        out.append(row)
        print(f"    {spacing:4.1f} | {row['iterations']:3d} | {row['evaluation_s']:6.2f} | "
              f"{row['product_s']:5.3f} | {row['ratio']:5.2f}", flush=True)
    return out


# ---- (coarse): coarse corrections on the mobility problem, dense -----------------------------
def _strains() -> list[np.ndarray]:
    """A basis of the traceless symmetric 3 x 3 matrices (five straining flows)."""
    out = []
    for i, j in ((0, 1), (0, 2), (1, 2)):
        e = np.zeros((3, 3))
        e[i, j] = e[j, i] = 1.0
        out.append(e)
    for i, j in ((0, 1), (1, 2)):
        e = np.zeros((3, 3))
        e[i, i], e[j, j] = 1.0, -1.0
        out.append(e)
    return out


def coarse_corrections(points: int = 42, side: int = 3, spacing: float = 3.0) -> dict[str, int]:
    """GMRES iterations of the dense mobility problem of ``side``³ spheres with the per-body
    saddle blocks alone and behind each coarse correction (see the module)."""
    s = RigidSurface(fibonacci_sphere(points), 0.5 * sphere_spacing(points), name="s")
    bodies = [s.place((i * spacing, j * spacing, 3 + k * spacing))
              for i in range(side) for j in range(side) for k in range(side)]
    sset = SurfaceSet(bodies, 1.0, True)
    m, k = sset.operator().dense(), sset.motion()
    n3, nb = m.shape[0], sset.n_bodies
    a = np.block([[m, -k], [-k.T, np.zeros((6 * nb, 6 * nb))]])
    force = np.zeros((nb, 6))
    force[:, 2] = -1.0
    b = np.concatenate([np.zeros(n3), -force.ravel()])
    blocks, z = [], np.zeros((n3, 6 * nb))
    for i, p in enumerate(bodies):
        rows = sset.rows(i)
        mi = StokesletOperator(None, p.points, p.epsilon, 1.0).dense()
        ki = k[rows, 6 * i:6 * i + 6]
        blocks.append(sla.lu_factor(np.block([[mi, -ki], [-ki.T, np.zeros((6, 6))]])))
        z[rows, 6 * i:6 * i + 6] = np.linalg.solve(mi, ki)

    def jacobi(r: np.ndarray) -> np.ndarray:
        out = np.zeros_like(r)
        for i in range(nb):
            rows, y = sset.rows(i), slice(n3 + 6 * i, n3 + 6 * i + 6)
            x = sla.lu_solve(blocks[i], np.concatenate([r[rows], r[y]]))
            out[rows], out[y] = x[:-6], x[-6:]
        return out

    def iterations(prec: Callable[[np.ndarray], np.ndarray]) -> int:
        count = [0]
        op = LinearOperator(a.shape, matvec=lambda v: a @ prec(v))
        gmres(op, b, rtol=1e-10, atol=0.0, restart=200, callback_type="pr_norm",
              callback=lambda _: count.__setitem__(0, count[0] + 1))
        return count[0]

    def corrected(v: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
        lu = sla.lu_factor(v.T @ a @ v)

        def prec(r: np.ndarray) -> np.ndarray:
            q = v @ sla.lu_solve(lu, v.T @ r)
            return q + jacobi(r - a @ q)

        return prec

    zeros = np.zeros((n3, 6 * nb))
    strain = np.array([jacobi(np.concatenate([
        np.zeros(3 * sset.offsets[i]), ((p.points - p.center) @ e.T).ravel(),
        np.zeros(3 * (sset.offsets[-1] - sset.offsets[i + 1]) + 6 * nb)]))
        for i, p in enumerate(bodies) for e in _strains()]).T
    return {
        "bodies": nb,
        "jacobi": iterations(jacobi),
        "rigid_modes": iterations(corrected(np.vstack([z, np.eye(6 * nb)]))),
        "rigid_apart": iterations(corrected(np.block([[z, zeros],
                                                      [np.zeros((6 * nb, 6 * nb)),
                                                       np.eye(6 * nb)]]))),
        "strain": iterations(corrected(strain)),
    }


RODS_25 = "experiments/rods_25.toml"


def rods(counts: list[int], rounds: int) -> list[dict]:
    """One rate evaluation of ``n`` rods of experiments/rods_25.toml for each ``n`` in
    ``counts``: its CPU time (least of ``rounds``), points and peak allocation."""
    out = []
    for count in counts:
        cfg, resolved = config.load(RODS_25, [f"model.n_rods={count}", "execution.threads=1"])
        system = config.build_system(cfg, resolved)
        x0 = system.initial_state()
        system.rates(0.0, x0)  # compiled
        best = cpu_best(lambda s=system, x=x0: s.rates(0.0, x), rounds)
        tracemalloc.start()
        system.rates(0.0, x0)
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        points = len(system.positions(x0))
        row = {"rods": count, "points": points, "evaluation_s": best, "peak_bytes": peak,
               "bytes_per_point": peak / points, "per_point_squared_ns": best / points**2 * 1e9}
        out.append(row)
        print(f"    {count:4d} | {points:6d} | {best * 1e3:9.3f} | {peak / 2**20:8.2f} | "
              f"{peak / points:7.0f} | {row['per_point_squared_ns']:6.2f}", flush=True)
    return out


class _CpuProducts:
    """A stand-in for :class:`parastokes.gpu.velocity.Evaluation` (same arguments): the batched
    products on the CPU kernels (one thread), their time added to ``seconds``."""

    seconds = 0.0

    def __init__(self, targets, sources, forces, torques, epsilon, mu, wall, launch=None):
        self.args = (targets, sources, forces)
        self.kw = dict(epsilon=epsilon, mu=mu, torques=torques, wall=wall,
                       angular=torques is not None or wall)

    def launch(self) -> None:
        t = time.perf_counter()
        out = mrs.velocity(*self.args, **self.kw)
        self.out = out if isinstance(out, tuple) else (out, None)
        _CpuProducts.seconds += time.perf_counter() - t

    def result(self):
        return self.out


def hosted(batches: list[int]) -> list[dict]:
    """The host's share of hosted solves (parastokes.gpu.hosted) without a device: B evaluations
    of a suspension as B hosted solves whose batched products are computed by the CPU kernels in
    the router's thread (:class:`_CpuProducts`). The products run only while every solve waits,
    so the wall time less the products' time is the host's work (GMRES, the body blocks, the
    threads' hand-over) that a device round cannot go below."""
    from parastokes.gpu import hosted as hosted_module

    out = []
    cases = {"64 spheres x 150, lattice 4a": scene_config(lattice_placement(4.0), 150),
             "100 spheres x 42, random 0.05": scene_config(random_placement(100, 0.05), 42)}
    for label, setup in cases.items():
        scene = config.build(*setup).system
        x0 = scene.initial_state()
        scene.rates(0.0, x0)  # compiled, factorized
        for count in batches:
            router = hosted_module.Router(evaluation=_CpuProducts)
            _CpuProducts.seconds = 0.0
            t = time.perf_counter()
            outcomes = router.run([functools.partial(scene.rates, 0.0, x0)] * count)
            wall = time.perf_counter() - t
            assert all(ok for ok, _ in outcomes)
            rounds = len(router.launches)
            host = wall - _CpuProducts.seconds
            row = {"case": label, "solves": count, "rounds": rounds, "wall_s": wall,
                   "products_s": _CpuProducts.seconds, "host_s": host,
                   "host_ms_per_solve_round": host / rounds / count * 1e3,
                   "product_ms_per_solve_round": _CpuProducts.seconds / rounds / count * 1e3}
            out.append(row)
            print(f"    {label} | {count:2d} | {rounds:3d} | {wall:7.2f} | "
                  f"{_CpuProducts.seconds:7.2f} | {row['host_ms_per_solve_round']:6.2f} | "
                  f"{row['product_ms_per_solve_round']:7.2f}", flush=True)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--parts", nargs="+",
                        choices=("scaling", "scene64", "coarse", "rods", "hosted"),
                        default=["scaling", "scene64", "coarse"])
    parser.add_argument("--counts", nargs="+", type=int, default=[1, 10, 100, 1000])
    parser.add_argument("--points", type=int, default=42)
    parser.add_argument("--fraction", type=float, default=0.05)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--json", type=str, default=None)
    args = parser.parse_args()
    out: dict = {}
    if "scaling" in args.parts:
        print(f"(scaling) spheres of {args.points} points at random, volume fraction "
              f"{args.fraction:g}, above the wall; CPU s, one thread")
        print("    bodies | points | its | evaluation | product | ratio | peak MiB | B/point "
              "| dense GiB")
        out["scaling"] = scaling(args.counts, args.points, args.fraction, args.rounds)
    if "scene64" in args.parts:
        print("(scene64) 64 spheres of 150 points, 4 x 4 x 4 lattice above the wall")
        print("    spacing/a | its | evaluation (s) | product (s) | ratio")
        out["scene64"] = scene64(args.rounds)
    if "coarse" in args.parts:
        out["coarse"] = coarse_corrections()
        c = out["coarse"]
        print(f"(coarse) {c['bodies']} spheres, GMRES iterations to 1e-10: blocks alone "
              f"{c['jacobi']}, + rigid modes [Z; I] {c['rigid_modes']}, + forces and motions "
              f"apart {c['rigid_apart']}, + strain modes {c['strain']}")
    if "rods" in args.parts:
        print("(rods) rods of 51 points above the wall (experiments/rods_25.toml); CPU, one thread")
        print("    rods | points | evaluation (ms) | peak MiB | B/point | ns per point pair")
        out["rods"] = rods([1, 5, 10, 25], max(args.rounds, 5))
    if "hosted" in args.parts:
        print("(hosted) B evaluations as hosted solves, products on the CPU kernels in the "
              "router's thread; seconds of wall time")
        print("    case | solves | rounds | wall | products | host ms per solve and round | "
              "product ms per solve and round")
        out["hosted"] = hosted([1, 2, 4])
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(out, fh, indent=1)


if __name__ == "__main__":
    main()
