"""Cost of one RK2 step of the paper's model problems (issue 3), against the kernels inside it.

Run from the repository root::

    PYTHONPATH=. python benchmarks/stepping.py [--repeats 7] [--threads 1] [--out PATH]

For one rod swimmer (M = 301, ε = 5 σ_f, wall kernels with torques), five rods (1505 points) and
the vesicle (642 points, free-space Stokeslets), it times

- ``step``: one RK2 (Heun) step through :func:`parastokes.integrate.step` plus the per-step blow-up
  checks of :func:`parastokes.integrate.run` (finite state, monitor), i.e. what ``propagate`` does
  per step;
- ``kernel``: one ``mrs.velocity`` call with the same inputs and ``check=False`` (the O(N²) sum);

- ``rest``: the step with ``mrs.velocity`` answering from a cache, i.e. everything that is not the
  two kernel evaluations;

and reports ``step / (2 kernel)`` and ``1 + rest / (2 kernel)``, the overhead ratio of an RK2
step over its two kernel evaluations (issue target: at most 1.3), and the projected wall time of
the paper's serial fine solve (one rod, T = 1, τ_f = 1e-6: 10^6 RK2 steps), and, for the rod, the
per-call time of the two unthreaded parts of the rest (``loads``, ``advance``). Each figure is the
minimum over ``--repeats`` blocks of interleaved measurements (robust against other load).
With ``--out`` the table and the command are written as markdown.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import sys
import time
from contextlib import contextmanager

import numba
import numpy as np

from parastokes import integrate, models, mrs

FINE_STEPS = 1_000_000  # T = 1 with τ_f = 1e-6 (section 5.1)
TARGET_RATIO = 1.3


def one_step(system, t, x, dt):
    """What ``integrate.run`` does per step: the RK2 step, the finiteness check, the monitor."""
    y = integrate.step(system, "rk2", t, x, dt)
    np.isfinite(y).all()
    system.monitor(y)
    return y


def kernel_call(system, t, x):
    """The O(N²) part of one ``rates`` evaluation, with the same inputs."""
    if hasattr(system, "loads"):
        f, n = system.loads(t, x)
        pos = x[:, :3]
        return lambda: mrs.velocity(
            pos, pos, f, epsilon=system.epsilon, mu=system.viscosity, torques=n, wall=system.wall,
            angular=True, n_threads=system.n_threads, check=False,
        )
    f = system.forces(x)
    return lambda: mrs.velocity(
        x, x, f, epsilon=system.epsilon, mu=system.viscosity, n_threads=system.n_threads,
        check=False,
    )


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


def measure(system, dt, repeats, calls):
    """(step, kernel, overhead): min over ``repeats`` blocks of seconds per call."""
    # a state in motion: the swimmer a few steps in, the vesicle slightly deformed
    x = integrate.propagate(system, system.initial_state(), 0.0, 5 * dt, "rk2", dt)
    t = 5 * dt
    kernel = kernel_call(system, t, x)
    result = kernel()
    one_step(system, t, x, dt)
    steps, kernels, overheads = [], [], []
    for _ in range(repeats):
        steps.append(best_time(lambda: one_step(system, t, x, dt), calls))
        kernels.append(best_time(kernel, 2 * calls))
        with kernel_replaced_by(result):
            overheads.append(best_time(lambda: one_step(system, t, x, dt), calls))
    return min(steps), min(kernels), min(overheads)


def rod_rest_parts(system, dt, repeats, calls=200):
    """Seconds per call of the rod's unthreaded per-evaluation work: ``loads`` (mechanics and
    preferred strain) and ``advance`` (positions and frame rotations); min over ``repeats``."""
    x = integrate.propagate(system, system.initial_state(), 0.0, 5 * dt, "rk2", dt)
    rates = system.rates(5 * dt, x)
    loads = min(best_time(lambda: system.loads(5 * dt, x), calls) for _ in range(repeats))
    advance = min(best_time(lambda: system.advance(x, rates, dt), calls) for _ in range(repeats))
    return loads, advance


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--threads", type=int, default=1, help="kernel threads (n_threads)")
    parser.add_argument("--out", help="write a markdown report here")
    args = parser.parse_args(argv)
    load = os.getloadavg()

    cases = [
        ("one rod (M = 301, wall)", models.rod_swimmer(n_threads=args.threads), 1e-6, 20),
        ("five rods (5 x 301, wall)", models.rod_swimmer(5, n_threads=args.threads), 1e-6, 4),
        ("vesicle (642, free space)", models.vesicle(n_threads=args.threads), 1e-3, 10),
    ]
    rows = []
    for name, system, dt, calls in cases:
        step, kernel, overhead = measure(system, dt, args.repeats, calls)
        ratios = (step / (2 * kernel), 1 + overhead / (2 * kernel))
        rows.append((name, step, kernel, overhead, *ratios))
        print(f"{name:28s} step {step * 1e3:8.3f} ms   kernel {kernel * 1e3:8.3f} ms   "
              f"rest {overhead * 1e3:7.3f} ms   ratio {rows[-1][4]:5.2f} "
              f"(from the rest: {rows[-1][5]:5.3f})", flush=True)
    loads, advance = rod_rest_parts(cases[0][1], cases[0][2], args.repeats)
    print(f"one rod, per call: loads {loads * 1e6:.1f} us, advance {advance * 1e6:.1f} us "
          "(twice each per RK2 step)")
    rod_step = rows[0][1]
    projected = FINE_STEPS * rod_step
    print(f"projected serial fine solve (rod, T = 1, 1e6 RK2 steps): {projected:.0f} s "
          f"= {projected / 60:.1f} min")

    if args.out:
        command = "PYTHONPATH=. python benchmarks/stepping.py " + " ".join(
            argv if argv is not None else sys.argv[1:]
        )
        lines = [
            "# Stepping benchmark (issue 3)",
            "",
            f"Command: `{command.strip()}`",
            "",
            f"Machine: {platform.processor() or platform.machine()}, "
            f"{numba.config.NUMBA_NUM_THREADS} hardware threads; kernel threads used: "
            f"{args.threads}; minimum over {args.repeats} blocks of interleaved measurements; "
            f"load average before the run {load[0]:.2f} (1 min).",
            "",
            "| system | s per RK2 step | s per kernel call | s per step without kernels "
            "| step / (2 kernels) | 1 + rest / (2 kernels) |",
            "|---|---|---|---|---|---|",
        ]
        lines += [
            f"| {n} | {s:.3e} | {k:.3e} | {o:.2e} | {r:.2f} | {q:.3f} |"
            for n, s, k, o, r, q in rows
        ]
        verdict = "met" if max(q for *_, q in rows) <= TARGET_RATIO else "NOT met"
        lines += [
            "",
            "The last column times the step with `mrs.velocity` answering from a cache: the work",
            "that is not the two kernel evaluations, measured directly (robust on a busy machine,",
            "where the difference of two noisy timings is not).",
            "",
            f"Of the rod's rest, per call (twice each per step): `loads` (mechanics, preferred "
            f"strain) {loads * 1e6:.1f} µs, `advance` (positions, frame rotations) "
            f"{advance * 1e6:.1f} µs.",
            "",
            f"Overhead target step / (2 kernels) <= {TARGET_RATIO}: {verdict}.",
            "",
            f"Projected serial fine solve of the paper (one rod, T = 1, τ_f = 1e-6, "
            f"{FINE_STEPS:.0e} RK2 steps): {projected:.0f} s = {projected / 60:.1f} min "
            f"({'within' if projected <= 600 else 'above'} the 10-minute target).",
            "",
        ]
        with open(args.out, "w", encoding="utf-8") as fh:
            fh.write("\n".join(lines))
    return 0 if math.isfinite(projected) else 1


if __name__ == "__main__":
    raise SystemExit(main())
