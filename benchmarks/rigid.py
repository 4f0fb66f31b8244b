"""Rigid-body benchmarks (docs/benchmarks.md, "Rigid and prescribed-motion bodies").

Run from the repository root (the solves limit BLAS to the fluid's threads themselves,
:mod:`parastokes.mobility.threads`: no ``OPENBLAS_NUM_THREADS`` needed)::

    PYTHONPATH=. python benchmarks/rigid.py [--quick] [--sections ...] [--out PATH]

- ``step``: one RK2 step of a free rigid sphere of N ~ 2000 surface points (two mobility solves
  with the body-frame factorization kept, plus ``advance``) against two velocity evaluations of
  the regularized Stokeslets at its N points (what a body with explicit forces pays per RK2 step);
  the issue's target is a ratio <= 3. The factorization itself (once per shape, ε, μ) is timed
  apart, and so is a solve with the matrix assembled and factorized every time (as a body near
  the wall or with a moving part pays).
- ``blas``: one mobility solve of the bacterium near the wall (assembled and factorized at every
  evaluation) with BLAS limited to the fluid's one thread (the package's default) against the
  same solve with BLAS on the library's default thread count (what it was before the limit),
  alternating, in one run.
- ``coarse_surface`` (not run by default): Parareal on the bacterium of
  experiments/quick/bacterium_wall.toml with its coarse solver on the fine surface and on
  surfaces 2, 3 and 4 times coarser (``coarse.grid_factor``): γ_G / γ_F, iterations, errors,
  eq. 14 at 40 cores.
- ``coarse_scene`` (not run by default): the same on the scene of
  experiments/scene_sphere_and_rod.toml (a rigid sphere of 150 points beside a rod of 31
  nodes; T = 4e-4 over 8 slices): :meth:`Scene.coarsened` coarsening both (the sphere's surface,
  the rod's nodes), and only the sphere (``coarse_bodies``).
- ``parareal``: a bacterium near the wall (80 head points, a 40-point flagellum): the serial fine
  run, a Parareal run on 2 worker processes (Lagrange in ε, forward Euler at 5 τ_f), the measured
  γ_G / γ_F of one slice and the speedups eq. 14 predicts with them at 2 and 40 cores
  (:func:`parastokes.parareal.speedup.predict`).

Times are medians of repeats on this machine, which is shared and noisy: ratios measured in one
run are what to read, not absolute times.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import time
from collections.abc import Callable

import numpy as np

from parastokes import integrate, mrs, parallel, parareal
from parastokes.kinds.rigid import Bacterium, Helix, RigidBody, Sphere, Spheroid
from parastokes.kinds.rigid.shapes import spacing
from parastokes.kinds.rigid.solve import mobility
from parastokes.parareal.speedup import predict


def median_time(fn: Callable[[], object], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def step_section(n: int, repeats: int) -> list[str]:
    shape = Sphere(1.0, n)
    body = RigidBody(shape=shape, epsilon=0.5 * spacing(shape), viscosity=1.0,
                     force=(0.0, 0.0, -1.0), torque=(0.2, 0.0, 0.0))
    x = body.initial_state()
    start = time.perf_counter()
    body.rates(0.0, x)  # the factorization, once
    factorize = time.perf_counter() - start
    step = median_time(lambda: integrate.propagate(body, x, 0.0, 0.01, "rk2", 0.01), repeats)
    points = np.ascontiguousarray(x[1:, :3])
    forces = np.ones_like(points)
    mrs.velocity(points, points, forces, epsilon=body.epsilon, mu=1.0)
    two = median_time(lambda: [mrs.velocity(points, points, forces, epsilon=body.epsilon,
                                            mu=1.0, check=False) for _ in range(2)], repeats)
    surface = body.surface(0.0, x)
    assembled = median_time(lambda: mobility([dataclasses.replace(surface, key=None)], 1.0,
                                             False, None), max(1, repeats // 3))
    return [
        f"### RK2 step of a free rigid sphere, N = {n} surface points",
        "",
        "| what | time (s) | / two velocity evaluations |",
        "|---|---|---|",
        f"| two velocity evaluations at the N points | {two:.4g} | 1 |",
        f"| one RK2 step (two solves, factorization kept) | {step:.4g} | {step / two:.3g} |",
        f"| the body-frame factorization (once) | {factorize:.4g} | {factorize / two:.3g} |",
        f"| one solve assembled and factorized anew | {assembled:.4g} | {assembled / two:.3g} |",
        "",
    ]


def bacterium() -> RigidBody:
    shape = Bacterium(Spheroid(1.0, 0.5, 80), Helix(0.25, 2.0, 3.0, 40), 0.25, 2 * math.pi * 100)
    return RigidBody(shape=shape, epsilon=0.5 * spacing(shape), viscosity=1e-6, wall=True,
                     position=(0.0, 0.0, 1.5))


def blas_section(repeats: int) -> list[str]:
    import contextlib
    from unittest import mock

    import threadpoolctl

    from parastokes.mobility import choice

    system = bacterium()
    x0 = system.initial_state()
    system.rates(0.0, x0)
    default = max(lib["num_threads"] for lib in threadpoolctl.threadpool_info()
                  if lib["user_api"] == "blas")
    limited, unlimited = [], []
    for _ in range(repeats):
        limited.append(median_time(lambda: system.rates(0.0, x0), 1))
        with mock.patch.object(choice, "blas_threads",
                               lambda n: contextlib.nullcontext(n)):
            unlimited.append(median_time(lambda: system.rates(0.0, x0), 1))
    one, free = float(np.median(limited)), float(np.median(unlimited))
    n = 3 * (len(x0) - 1) + 6
    return [
        f"### One mobility solve of the bacterium near the wall ({n}² system, assembled and "
        f"factorized), median of {repeats}",
        "",
        "| BLAS threads in the solve | time (s) | / limited |",
        "|---|---|---|",
        f"| 1 (the fluid's n_threads, the package's limit) | {one:.4g} | 1 |",
        f"| {default} (the library's default, no limit) | {free:.4g} | {free / one:.3g} |",
        "",
    ]


def parareal_section(t1: float, n_slices: int) -> list[str]:
    system = bacterium()
    x0 = system.initial_state()
    dt = 2e-4
    fine = integrate.Propagator(system, "rk2", dt)
    nodes = {"epsilon": [1.2 * system.epsilon, 1.3 * system.epsilon]}
    coarse = parareal.extrapolated(system, "euler", 5 * dt, lagrange=nodes)
    slice_length = t1 / n_slices
    gamma_f = median_time(lambda: fine(0.0, slice_length, x0), 2)
    gamma_g = median_time(lambda: coarse(0.0, slice_length, x0), 2)
    start = time.perf_counter()
    reference = parareal.serial_solution(fine, x0, 0.0, t1, n_slices)
    serial = time.perf_counter() - start
    with parallel.make_executor("processes", 2) as executor:
        start = time.perf_counter()
        result = parareal.run(fine, coarse, x0, 0.0, t1, n_slices, tol=1e-8,
                              max_iterations=n_slices, reference=reference,
                              positions=system.positions, project=system.project,
                              executor=executor)
        wall = time.perf_counter() - start
    k = result.iterations
    ratio = gamma_g / gamma_f
    rows = predict(ratio, k, [2, n_slices, 40])
    lines = [
        f"### Parareal on a bacterium near the wall ({len(x0) - 1} surface points, T = {t1:g}, "
        f"{n_slices} slices, 2 worker processes)",
        "",
        "| what | value |",
        "|---|---|",
        f"| serial fine run (s) | {serial:.3g} |",
        f"| Parareal run (s), {k} iterations to η̃ < 1e-8, final error η = "
        f"{result.errors[-1]:.2e} | {wall:.3g} |",
        f"| measured speedup (serial / Parareal) | {serial / wall:.3g} |",
        f"| γ_F, γ_G of one slice (s); γ_G / γ_F | {gamma_f:.3g}, {gamma_g:.3g}; {ratio:.3g} |",
    ]
    lines += [f"| eq. 14 at N_c = {n} (K = {min(k, n)}); bound eq. 15 | {s:.3g}; {b:.3g} |"
              for n, s, b in rows]
    return [*lines, ""]


QUICK_BACTERIUM = os.path.join(os.path.dirname(__file__), "..", "experiments", "quick",
                               "bacterium_wall.toml")


SCENE = os.path.join(os.path.dirname(__file__), "..", "experiments", "scene_sphere_and_rod.toml")


def _points(system: object) -> int:
    """A rigid body's surface points; a scene's state rows."""
    n_surface = getattr(system, "n_surface", None)
    return len(system.initial_state()) if n_surface is None else n_surface  # type: ignore[attr-defined]


def coarse_surface_setup(t1: float, n_slices: int, path: str = QUICK_BACTERIUM,
                         perturb: float = 0.0) -> dict:
    """The bacterium of ``path`` with its fine and coarse solvers (T = ``t1`` over ``n_slices``
    slices): system, initial state (its entries scaled by 1 + ``perturb``, for the round-off
    sensitivity of the results), fine propagator and the serial fine solution at the slices'
    ends (with its run time)."""
    from parastokes import config

    cfg, resolved = config.load(path)
    system = cfg.model.build(1)
    x0 = system.initial_state() * (1.0 + perturb)
    fine = integrate.Propagator(system, cfg.fine.scheme, cfg.fine.dt)
    start = time.perf_counter()
    reference = parareal.serial_solution(fine, x0, 0.0, t1, n_slices)
    serial = time.perf_counter() - start
    return {"cfg": cfg, "resolved": resolved, "system": system, "x0": x0, "fine": fine,
            "reference": reference, "serial": serial, "t1": t1, "n_slices": n_slices}


def coarse_surface_coarse(setup: dict, factor: int, variant: object = None) -> Callable:
    """The setup's coarse solver (its Lagrange parameters) on a grid ``factor`` times coarser (1:
    the fine grid), of ``variant`` (the setup's system with other settings, e.g. a scene's
    ``coarse_bodies``) or of the setup's system."""
    cfg, resolved = setup["cfg"], setup["resolved"]
    return parareal.extrapolated(variant or setup["system"], cfg.coarse.scheme,
                                 resolved.coarse_base_dt, lagrange=resolved.lagrange or None,
                                 grid=factor if factor > 1 else None)


def coarse_surface_run(setup: dict, factor: int, variant: object = None,
                       coarse: Callable | None = None) -> tuple[int, int, list[float]]:
    """Parareal of the setup with its coarse solver on a grid ``factor`` times coarser (of
    ``variant``, as :func:`coarse_surface_coarse`, or ``coarse`` when already built), to
    η̃ < 1e-8 (at most N_c iterations): the coarse grid's points, the iterations and the error η
    against the serial fine solution after each iteration."""
    system = setup["system"]
    points = _points((variant or system).coarsened(factor)[0] if factor > 1 else system)
    coarse = coarse or coarse_surface_coarse(setup, factor, variant)
    result = parareal.run(setup["fine"], coarse, setup["x0"], 0.0,
                          setup["t1"], setup["n_slices"], tol=1e-8,
                          max_iterations=setup["n_slices"], reference=setup["reference"],
                          positions=system.positions, project=system.project)
    return points, result.iterations, [float(e) for e in result.errors]


def coarse_surface_section(t1: float, n_slices: int, factors: list[int],
                           path: str = QUICK_BACTERIUM,
                           only: tuple[str, ...] | None = None,
                           interleave: bool = False) -> list[str]:
    """Parareal on the body or scene of ``path`` (its fine and coarse solvers; T = ``t1`` over
    ``n_slices`` slices) with the coarse solver on the fine grid (factor 1) and on coarser ones
    (:meth:`RigidBody.coarsened`, :meth:`Scene.coarsened`; for a scene, also with only the
    bodies ``only`` coarsened, its ``coarse_bodies``): γ_G / γ_F of one slice, the iterations to
    η̃ < 1e-8, the error against the serial fine solution, and eq. 14 at 40 cores.
    ``interleave``: γ_F measured again beside each row's γ_G (alternating, median of 3 pairs)."""
    setup = coarse_surface_setup(t1, n_slices, path)
    cfg, resolved, x0, fine = setup["cfg"], setup["resolved"], setup["x0"], setup["fine"]
    system = setup["system"]
    slice_length = t1 / n_slices
    gamma_f = median_time(lambda: fine(0.0, slice_length, x0), 3)
    lines = [
        f"### Parareal on experiments/quick/{os.path.basename(path)} "
        f"({_points(system)} points; fine {cfg.fine.scheme} τ_f = {cfg.fine.dt:g}; coarse "
        f"{cfg.coarse.scheme} at {resolved.coarse_base_dt:g} s, Lagrange in "
        f"{', '.join(resolved.lagrange)}, N_G = {resolved.n_auxiliary}; T = {t1:g}, "
        f"{n_slices} slices, in one process)",
        "",
        f"Serial fine run: {setup['serial']:.3g} s; γ_F of one slice: {gamma_f:.3g} s.",
        "",
        "| coarse surface | points | γ_G / γ_F | iterations to η̃ < 1e-8 | error η after each "
        "iteration | eq. 14 at N_c = 40 (K as found); bound eq. 15 |",
        "|---|---|---|---|---|---|",
    ]
    rows = [(factor, system) for factor in factors]
    if only is not None:
        rows += [(factor, dataclasses.replace(system, coarse_bodies=only))
                 for factor in factors if factor > 1]
    for factor, variant in rows:
        coarse = coarse_surface_coarse(setup, factor, variant)
        if interleave:  # γ_F again beside each γ_G: the ratio in one stretch of load
            pairs = [(median_time(lambda: fine(0.0, slice_length, x0), 1),
                      median_time(lambda c=coarse: c(0.0, slice_length, x0), 1))
                     for _ in range(3)]
            gamma_f, gamma_g = (float(np.median(v)) for v in zip(*pairs, strict=True))
        else:
            gamma_g = median_time(lambda c=coarse: c(0.0, slice_length, x0), 3)
        points, k, errors = coarse_surface_run(setup, factor, variant, coarse)
        ratio = gamma_g / gamma_f
        (_, s40, b40), = predict(ratio, k, [40])
        shown = ", ".join(f"{e:.1e}" for e in errors)
        name = "fine (baseline)" if factor == 1 else f"factor {factor}"
        if factor > 1 and getattr(variant, "coarse_bodies", None) is not None:
            name += f", only {', '.join(variant.coarse_bodies)}"
        lines.append(f"| {name} | {points} | {ratio:.3g} | {k} | {shown} | {s40:.3g}; "
                     f"{b40:.3g} |")
        print(lines[-1], flush=True)
    return [*lines, ""]


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="small sizes (a smoke run)")
    parser.add_argument("--sections", nargs="*", default=["step", "blas", "parareal"])
    parser.add_argument("--out", help="write the tables as Markdown here")
    args = parser.parse_args(argv)
    lines = [f"load average before: {os.getloadavg()[0]:.2f}", ""]
    if "step" in args.sections:
        lines += step_section(300 if args.quick else 2000, 3 if args.quick else 5)
    if "blas" in args.sections:
        lines += blas_section(5 if args.quick else 21)
    if "parareal" in args.sections:
        lines += parareal_section(0.004 if args.quick else 0.02, 4)
    if "coarse_surface" in args.sections:
        lines += coarse_surface_section(0.0048 if args.quick else 0.024, 4 if args.quick else 8,
                                        [1, 2] if args.quick else [1, 2, 3, 4])
    if "coarse_scene" in args.sections:
        lines += coarse_surface_section(2e-4 if args.quick else 4e-4, 4 if args.quick else 8,
                                        [1, 2] if args.quick else [1, 2, 3], SCENE,
                                        only=("sphere",), interleave=True)
    lines.append(f"load average after: {os.getloadavg()[0]:.2f}")
    text = "\n".join(lines)
    print(text)
    if args.out:
        with open(args.out, "w") as f:
            f.write(text + "\n")


if __name__ == "__main__":
    main()
