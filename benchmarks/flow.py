"""Speed of the flow on a grid: a 128 x 128 plane around a 301-point rod above the wall.

Run from the repository root::

    PYTHONPATH=. python benchmarks/flow.py [--rounds 5] [--resolution 128] [--json PATH]

16384 targets x 301 sources = 4.9 M pairs of the full wall kernel (Stokeslets and rotlets with
their images, docs/physics.md (1)-(8)) through :func:`parastokes.flow.velocity`. Times, the
minimum over ``--rounds`` rounds (other processes share the cores):

- ``kernel``: :func:`parastokes.mrs.velocity` alone on the rod's sources (``check=False``);
- ``velocity``: the whole :func:`parastokes.flow.velocity` (the rod's loads, the kernel, u∞);

on 1 and 2 threads, and the pairs per second. The state is a rod swimmer (Table 2, 301 nodes,
ε = 1, the defaults of ``models.rod_swimmer``) after 20 steps, so its loads are not zero.
"""

from __future__ import annotations

import argparse
import json
import time

import numba
import numpy as np

from parastokes import flow, integrate, models, mrs
from parastokes.bodies.sources import fluid_sources
from parastokes.flow.grids import PlaneSpec, bodies_box, grid_for


def _best(call, rounds: int) -> float:
    times = []
    for _ in range(rounds):
        start = time.perf_counter()
        call()
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--resolution", type=int, default=128)
    parser.add_argument("--json", help="write the figures to this file")
    args = parser.parse_args()

    rod = models.rod_swimmer(1, 301, 1.0)
    state = integrate.propagate(rod, rod.initial_state(), t0=0.0, t1=2e-5, scheme="rk2",
                                dt=1e-6)
    n = args.resolution
    box = bodies_box(state[:, :3], True)
    grid = grid_for(box, (n, n), PlaneSpec(1, 0.0), wall=True)
    points = grid.points()
    sources = fluid_sources(rod, 2e-5, state)
    pairs = len(points) * len(sources.points)
    rows = []
    for threads in (1, min(2, numba.config.NUMBA_NUM_THREADS)):
        def kernel(threads=threads):
            return mrs.velocity(points, sources.points, sources.forces, epsilon=sources.epsilon,
                                mu=rod.viscosity, torques=sources.torques, wall=True,
                                n_threads=threads, check=False)

        def whole(threads=threads):
            return flow.velocity(rod, state, points, t=2e-5, n_threads=threads)

        kernel(), whole()  # compile
        for name, call in (("kernel", kernel), ("velocity", whole)):
            seconds = _best(call, args.rounds)
            rows.append({"case": name, "threads": threads, "seconds": seconds,
                         "pairs_per_second": pairs / seconds})
            print(f"{name:>9} {threads} thread(s): {seconds * 1e3:8.1f} ms  "
                  f"{pairs / seconds / 1e6:7.1f} M pairs/s  ({len(points)} x "
                  f"{len(sources.points)} = {pairs / 1e6:.2f} M pairs)")
        if threads == 1 and numba.config.NUMBA_NUM_THREADS == 1:
            break
    if args.json:
        with open(args.json, "w", encoding="utf-8") as handle:
            json.dump({"targets": len(points), "sources": len(sources.points), "rows": rows},
                      handle, indent=2)


if __name__ == "__main__":
    np.seterr(all="raise")
    main()
