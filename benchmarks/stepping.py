"""Cost of one RK2 step of the paper's model problems, against the kernels inside it.

Run from the repository root::

    PYTHONPATH=. python benchmarks/stepping.py [--repeats 31] [--threads 1] [--out PATH]

For one rod swimmer (M = 301, ε = 5 σ_f, wall kernels with torques), five rods (1505 points), the
vesicle (642 points, free-space Stokeslets), a scene of the rod and the vesicle above the wall (943
points, one wall kernel call per stage with each source's own ε, :mod:`parastokes.scene`) and a
bead-spring chain (256 beads, free-space Stokeslets, shear flow), it times

- ``run``: seconds per RK2 (Heun) step of :func:`parastokes.integrate.run` over a block of
  steps, i.e. what ``propagate`` and the Parareal solvers do: the compiled loop of
  :mod:`parastokes.stepping`;
- ``python``: one step through :func:`parastokes.integrate.step` plus the per-step checks of the
  Python loop (finite state, monitor), for comparison;
- ``kernel``: one call of the compiled kernel with the same inputs, packed beforehand (the O(N²)
  sum alone, without ``mrs.velocity``'s Python);
- ``rest``: the Python step with ``mrs.velocity`` answering from a cache, i.e. the Python loop's
  work that is not the two kernel evaluations;

and reports ``run / (2 kernel)``, the overhead ratio of an RK2 step over its two kernel
evaluations (target: at most 1.3), the same for the Python step, and the projected wall
time of the paper's serial fine solve (one rod, T = 1, τ_f = 1e-6: 10^6 RK2 steps) from ``run``.
For the rod it also prints the per-call time of the two non-kernel parts of a stage (``loads``,
``advance``), and for the machine a reference rate measured in the same run (a 2000 x 2000
float64 matmul on one thread, GFLOP/s), since this shared machine runs at different speeds at
different moments. The four measurements run in ``--repeats`` rounds of adjacent short blocks;
times are medians over the rounds, and each ratio is taken within a round (blocks milliseconds
apart, so at the same machine speed) before its median is taken. With ``--out`` the table and
the command are written as markdown.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import platform
import sys
import time
from contextlib import contextmanager

import numba
import numpy as np
from kernels import matmul_rate

from parastokes import integrate, models, mrs
from parastokes.integrate import loop
from parastokes.kinds.chain import ChainSystem
from parastokes.mrs import compiled
from parastokes.mrs.velocity import EIGHT_PI, kernel_threads
from parastokes.scene import Scene

FINE_STEPS = 1_000_000  # T = 1 with τ_f = 1e-6 (section 5.1)
TARGET_RATIO = 1.3
TARGET_MINUTES = 10.0


def one_step(system, t, x, dt):
    """What the Python loop of ``integrate.run`` does per step: the RK2 step, the finiteness
    check, the monitor."""
    y = integrate.step(system, "rk2", t, x, dt)
    np.isfinite(y).all()
    system.monitor(y)
    return y


def loads(system, t, x):
    """The point forces and torques (or None) of ``system`` at ``(t, x)``, and every point's ε:
    a scene's stacked over its bodies, as ``Scene.rates`` stacks them."""
    if not isinstance(system, Scene):
        f, torques = system.loads(t, x)
        return f, torques, np.full(1, float(system.epsilon))
    f, torques = np.zeros((len(x), 3)), np.zeros((len(x), 3))
    for body, part, (first, rows, _) in zip(system.bodies, system.blocks(x), system.shapes,
                                            strict=True):
        body_f, body_torques = body.loads(t, part)
        f[first : first + rows] = body_f
        if body_torques is not None:
            torques[first : first + rows] = body_torques
    angular = any(body.angular for body in system.bodies)
    return f, torques if angular else None, system.source_epsilon()[None]


def kernel_call(system, t, x):
    """The O(N²) part of one ``rates`` evaluation: the compiled kernel that ``mrs.velocity`` and
    the compiled loop call, on the same inputs packed beforehand as the loop packs them (so no
    Python overhead). Returns the call and its result, as ``mrs.velocity`` would return it."""
    n = x.shape[0]
    f, torques, eps = loads(system, t, x)
    angular = torques is not None
    wall = bool(getattr(system, "wall", False))
    with kernel_threads(system.n_threads) as threads:  # the count the kernels will use
        starts = compiled.tile_starts(compiled.padded_size(n), threads)
    denom = np.full(1, EIGHT_PI * system.viscosity)
    targets, sources = np.empty((3, 1, starts[-1])), np.empty((1, n, 3))
    loop.pack_points(x, targets, sources)
    u, w = np.empty((1, n, 3)), np.empty((1, n, 3))
    if angular or wall:  # forces and torques (zero for a chain at the wall), the full kernel
        torques = np.zeros_like(f) if torques is None else torques
        args = (targets, sources, f[None], torques[None], eps, wall, False, denom, starts, u, w)
        kernel = compiled.full
    else:
        args = (targets, sources, f[None], eps, denom, starts, u)
        kernel = compiled.free_u_f

    def call():
        with kernel_threads(system.n_threads):
            kernel(*args)

    call()  # what mrs.velocity returns for these inputs
    return call, ((u[0].copy(), w[0].copy()) if angular else u[0].copy())


def best_time(fn, n):
    start = time.perf_counter()
    for _ in range(n):
        fn()
    return (time.perf_counter() - start) / n


@contextmanager
def kernel_replaced_by(result):
    """``mrs.velocity`` returns a copy of ``result`` at once: what remains is non-kernel work."""
    real = mrs.velocity

    def cached(*args, **kwargs):
        return tuple(r.copy() for r in result) if isinstance(result, tuple) else result.copy()

    mrs.velocity = cached
    try:
        yield
    finally:
        mrs.velocity = real


def measure(system, dt, repeats, steps):
    """Seconds per step or call and the overhead ratios, from ``repeats`` rounds of four adjacent
    blocks of ``steps`` steps each (kernels: ``2 steps`` calls): run, Python step, kernel, rest.

    Times are medians over the rounds; each ratio is formed within a round (blocks milliseconds
    apart, so at the same machine speed) and its median taken.
    """
    # a state in motion: the swimmer a few steps in, the vesicle slightly deformed
    x = integrate.propagate(system, system.initial_state(), 0.0, 5 * dt, "rk2", dt)
    t = 5 * dt
    kernel, result = kernel_call(system, t, x)
    one_step(system, t, x, dt)
    integrate.run(system, x, t, t + steps * dt, "rk2", dt)
    times = {"run": [], "python": [], "kernel": [], "rest": []}
    for _ in range(repeats):
        start = time.perf_counter()
        integrate.run(system, x, t, t + steps * dt, "rk2", dt)
        times["run"].append((time.perf_counter() - start) / steps)
        times["python"].append(best_time(lambda: one_step(system, t, x, dt), steps))
        times["kernel"].append(best_time(kernel, 2 * steps))
        with kernel_replaced_by(result):
            times["rest"].append(best_time(lambda: one_step(system, t, x, dt), steps))
    per_round = {key: np.array(values) for key, values in times.items()}
    two_kernels = 2 * per_round["kernel"]
    out = {key: float(np.median(values)) for key, values in per_round.items()}
    out["ratio"] = float(np.median(per_round["run"] / two_kernels))
    out["python_ratio"] = float(np.median(per_round["python"] / two_kernels))
    out["rest_ratio"] = float(np.median(1 + per_round["rest"] / two_kernels))
    return out


def rod_rest_parts(system, dt, repeats, calls=200):
    """Seconds per call of the rod's unthreaded per-evaluation work: ``loads`` (mechanics and
    preferred strain) and ``advance`` (positions and frame rotations); min over ``repeats``."""
    x = integrate.propagate(system, system.initial_state(), 0.0, 5 * dt, "rk2", dt)
    rates = system.rates(5 * dt, x)
    loads = min(best_time(lambda: system.loads(5 * dt, x), calls) for _ in range(repeats))
    advance = min(best_time(lambda: system.advance(x, rates, dt), calls) for _ in range(repeats))
    return loads, advance


def paper_scene(threads):
    """The paper's rod (M = 301, ε = 5 σ_f) and vesicle (642 points, ε = 0.3 l_max) above the
    wall in one fluid (μ = 1e-6, the rod's), the vesicle 5 μm above the rod's middle."""
    vesicle = models.vesicle(viscosity=1e-6, shear_rate=0.0)
    vesicle = dataclasses.replace(vesicle, center=(30.0, 0.0, 15.0))
    return Scene((models.rod_swimmer(), vesicle), viscosity=1e-6, wall=True, n_threads=threads)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=31)
    parser.add_argument("--threads", type=int, default=1, help="kernel threads (n_threads)")
    parser.add_argument("--out", help="write a markdown report here")
    args = parser.parse_args(argv)
    load = os.getloadavg()
    reference = matmul_rate()["gflops"]

    threads = args.threads
    cases = [  # name, system, dt, steps per block (a run's fixed costs, ~30 µs, spread thin)
        ("one rod (M = 301, wall)", models.rod_swimmer(n_threads=threads), 1e-6, 40),
        ("five rods (5 x 301, wall)", models.rod_swimmer(5, n_threads=threads), 1e-6, 2),
        ("vesicle (642, free space)", models.vesicle(n_threads=threads), 1e-3, 20),
        ("scene: rod 301 + vesicle 642, wall", paper_scene(threads), 1e-6, 10),
        ("chain (256 beads, free space)",
         ChainSystem(n_beads=256, shear_rate=1.0, n_threads=threads), 1e-4, 40),
    ]
    rows = []
    for name, system, dt, steps in cases:
        m = measure(system, dt, args.repeats, steps)
        row = dict(name=name, **m)
        rows.append(row)
        print(f"{name:28s} run {m['run'] * 1e3:7.3f} ms/step   kernel {m['kernel'] * 1e3:7.3f} ms"
              f"   ratio {row['ratio']:5.2f}   | Python step {m['python'] * 1e3:7.3f} ms, "
              f"ratio {row['python_ratio']:5.2f} (from its rest: {row['rest_ratio']:5.3f})",
              flush=True)
    loads, advance = rod_rest_parts(cases[0][1], cases[0][2], args.repeats)
    print(f"one rod, per call: loads {loads * 1e6:.1f} us, advance {advance * 1e6:.1f} us "
          "(twice each per RK2 step, with a Python call's overhead)")
    projected = FINE_STEPS * rows[0]["run"]
    print(f"projected serial fine solve (rod, T = 1, 1e6 RK2 steps): {projected:.0f} s "
          f"= {projected / 60:.1f} min; machine reference (matmul, 1 thread): "
          f"{reference:.1f} GFLOP/s")

    if args.out:
        command = "PYTHONPATH=. python benchmarks/stepping.py " + " ".join(
            argv if argv is not None else sys.argv[1:]
        )
        lines = [
            "# Stepping benchmark",
            "",
            f"Command: `{command.strip()}`",
            "",
            f"Machine: {platform.processor() or platform.machine()}, "
            f"{numba.config.NUMBA_NUM_THREADS} hardware threads; kernel threads used: "
            f"{args.threads}; medians over {args.repeats} rounds of adjacent blocks (ratios formed "
            "within each round); "
            f"load average before the run {load[0]:.2f} (1 min); reference rate in this run "
            f"(2000 x 2000 float64 matmul, one thread) {reference:.1f} GFLOP/s.",
            "",
            "| system | s per RK2 step (`run`) | s per kernel call | run / (2 kernels) "
            "| s per Python step | Python step / (2 kernels) | 1 + Python rest / (2 kernels) |",
            "|---|---|---|---|---|---|---|",
        ]
        lines += [
            f"| {r['name']} | {r['run']:.3e} | {r['kernel']:.3e} | {r['ratio']:.2f} "
            f"| {r['python']:.3e} | {r['python_ratio']:.2f} | {r['rest_ratio']:.3f} |"
            for r in rows
        ]
        verdict = "met" if max(r["ratio"] for r in rows) <= TARGET_RATIO else "NOT met"
        lines += [
            "",
            "`run` is `integrate.run` over many steps (the compiled loop of "
            "`parastokes.stepping`). The last column times the Python step with `mrs.velocity` "
            "answering from a cache: its non-kernel work, measured directly.",
            "",
            f"Of the rod's stage, per call: `loads` (mechanics, preferred strain) "
            f"{loads * 1e6:.1f} µs, `advance` (positions, frame rotations) {advance * 1e6:.1f} µs "
            "(Python calls; inside the compiled loop without the call overhead).",
            "",
            f"Overhead target run / (2 kernels) <= {TARGET_RATIO}: {verdict}.",
            "",
            f"Projected serial fine solve of the paper (one rod, T = 1, τ_f = 1e-6, "
            f"{FINE_STEPS:.0e} RK2 steps): {projected:.0f} s = {projected / 60:.1f} min "
            f"({'within' if projected <= 60 * TARGET_MINUTES else 'above'} the "
            f"{TARGET_MINUTES:g}-minute target).",
            "",
        ]
        with open(args.out, "w", encoding="utf-8") as fh:
            fh.write("\n".join(lines))
    return 0 if math.isfinite(projected) else 1


if __name__ == "__main__":
    raise SystemExit(main())
