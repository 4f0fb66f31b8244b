"""GPU backend: builds, checks against the CPU, and measures, in one command.

Run from the repository root on a machine with an NVIDIA GPU (``pip install ".[gpu]"``)::

    PYTHONPATH=. python benchmarks/gpu.py --json benchmarks/gpu.json       # ~5-8 minutes on an H200

Sections (``--sections``, default all, in this order; the JSON is rewritten after each one, so a
run that is stopped keeps what it measured):

- ``kernels``: throughput in G pairs/s of the batched kernels for B = 1, 8, 40, 160 members of the
  rod (N = 301: the full wall kernel, u and w from forces and torques) and the vesicle (N = 642:
  the free-space force kernel), timed with CUDA events over back-to-back launches; the same batches
  on the CPU kernels (``mrs.velocity``, all cores of this machine); the fraction of the GPU's FP64
  peak (SMs x 64 FP64 FMA units x 2 flops x clock, Hopper) at the conventional 200 (wall) and 20
  (free) flops per pair of benchmarks/kernels.py; and the largest difference from the CPU kernels.
- ``sweep``: one whole parallel sweep of the paper's Table 4 problem (40 slices x 25,000 RK2 steps
  of the swimmer, M = 301, tau_f = 1e-6; slice n from T_{n-1}, every slice from the initial shape,
  since the cost does not depend on the start state) as one GPU batch, against the same 40 fine
  solves on a process pool over this machine's cores; the largest difference of the 40 end states.
- ``parareal``: Parareal end to end on the GPU executor: short rod (Table 4 G^3 solver) and vesicle
  (Table 7 G^1) runs against the process-pool executor (iterates compared), then the full
  Table 4 G^3 and Table 7 G^1 runs (T = 1 and T = 100, 40 slices, 4 iterations) on the GPU alone
  (wall time, increments).
- ``rigid``: rigid bodies on the hosted path (:mod:`parastokes.gpu.hosted`): B solves of the
  64-sphere suspension (4 x 4 x 4 spheres of 150 points above the wall, spacing 4a, sedimenting;
  9,600 points, a GMRES mobility solve per stage), each 2 RK2 steps, as one batch of the GPU
  executor (the solves on the host, their products batched on the GPU) against the same B solves
  on a process pool over this machine's cores; launches, their mean batch size, and the largest
  difference of the B end states.

``--smoke`` runs everything on tiny sizes (also under NUMBA_ENABLE_CUDASIM=1, to test the script).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np
from numba import cuda

from benchmarks.suspension import lattice_placement, scene_config
from parastokes import config, integrate, models, mrs, parallel, parareal
from parastokes.gpu import batch, device, stepping
from parastokes.gpu.velocity import Evaluation
from parastokes.mobility import choice
from parastokes.run import session
from parastokes.run.warmup import WarmUp

ROOT = Path(__file__).resolve().parents[1]
BATCHES = (1, 8, 40, 160)
FLOPS_PER_PAIR = {"rod": 200, "vesicle": 20}  # the convention of benchmarks/kernels.py
TARGETS = {"wall kernel at B = 40 (G pairs/s)": 60.0, "Table 4 sweep (s)": 10.0}


def gpu_info() -> dict:
    if device.simulated():
        return {"name": "numba-cuda simulator", "simulated": True, "fp64_peak_tflops": None}
    dev = cuda.get_current_device()
    sms = dev.MULTIPROCESSOR_COUNT
    clock = dev.CLOCK_RATE * 1e3  # Hz
    return {
        "name": dev.name.decode() if isinstance(dev.name, bytes) else str(dev.name),
        "compute_capability": list(dev.compute_capability),
        "sms": sms,
        "clock_ghz": clock / 1e9,
        # Hopper: 64 FP64 FMA units per SM (vector units, not the FP64 tensor cores)
        "fp64_peak_tflops": sms * 64 * 2 * clock / 1e12,
        "simulated": False,
    }


def _problem(kind: str, b: int, n: int, seed: int = 0) -> dict:
    rng = np.random.default_rng(seed)
    if kind == "rod":  # rods above the wall, as the swimmer's points
        x = np.zeros((b, n, 3))
        x[..., 0] = np.linspace(0.0, 60.0, n)
        x[..., 1] = rng.normal(scale=1.0, size=(b, n))
        x[..., 2] = 10.0 + rng.normal(scale=0.5, size=(b, n))
        eps = np.full(b, 1.0) * (1.0 + 0.01 * np.arange(b))
        torques = rng.normal(size=(b, n, 3))
    else:  # unit spheres
        verts = models.vesicle(subdivisions=3).initial_state() if n == 642 else \
            rng.normal(size=(n, 3))
        x = np.broadcast_to(verts, (b, n, 3)).copy()
        eps = np.full(b, 0.05)
        torques = None
    return dict(x=x, f=rng.normal(size=(b, n, 3)), n=torques, eps=eps,
                mu=np.full(b, 1e-3) * (1.0 + 0.01 * np.arange(b)), wall=kind == "rod")


def kernels_section(sizes: dict, batches: tuple, rounds: int, info: dict,
                    shapes: list[stepping.Launch]) -> list[dict]:
    cores = len(os.sched_getaffinity(0))
    rows = []
    for kind, n in sizes.items():
        tuned = 40 if 40 in batches else batches[-1]  # the batch of the other block shapes
        for b, shape in [(b, shapes[0]) for b in batches] + [(tuned, s) for s in shapes[1:]]:
            p = _problem(kind, b, n)
            ev = Evaluation(p["x"], p["x"], p["f"], p["n"], p["eps"], p["mu"], p["wall"], shape)
            ev.launch()
            cuda.synchronize()  # compiled and warm
            repeats = max(3, min(200, int(2e9 / (b * n * n))))
            start, end = cuda.event(), cuda.event()
            best = np.inf
            for _ in range(rounds):
                start.record()
                for _ in range(repeats):
                    ev.launch()
                end.record()
                end.synchronize()
                best = min(best, start.elapsed_time(end) / 1e3 / repeats)
            u, w = ev.result()
            kw = dict(epsilon=p["eps"], mu=p["mu"], torques=p["n"], wall=p["wall"],
                      angular=p["n"] is not None, n_threads=cores, check=False)
            cpu = mrs.velocity(p["x"], p["x"], p["f"], **kw)
            cpu_best = np.inf
            for _ in range(rounds):
                t = time.perf_counter()
                mrs.velocity(p["x"], p["x"], p["f"], **kw)
                cpu_best = min(cpu_best, time.perf_counter() - t)
            u_cpu, w_cpu = cpu if p["n"] is not None else (cpu, None)
            diff = np.abs(u - u_cpu).max() / np.abs(u_cpu).max()
            if w is not None:
                diff = max(diff, np.abs(w - w_cpu).max() / np.abs(w_cpu).max())
            pairs = b * n * n
            rate = pairs / best / 1e9
            peak = info["fp64_peak_tflops"]
            row = {
                "kind": kind, "n": n, "batch": b, "block": [shape.tx, shape.sy],
                "gpu_seconds": best,
                "gpu_gpairs_per_s": rate, "cpu_seconds": cpu_best, "cpu_threads": cores,
                "cpu_gpairs_per_s": pairs / cpu_best / 1e9, "gpu_over_cpu": cpu_best / best,
                "fraction_of_fp64_peak": None if peak is None else
                rate * 1e9 * FLOPS_PER_PAIR[kind] / (peak * 1e12),
                "max_rel_diff_vs_cpu": float(diff),
            }
            rows.append(row)
            print(f"kernel {kind:7s} N={n:4d} B={b:3d} block {shape.tx}x{shape.sy}: GPU "
                  f"{rate:8.2f} G pairs/s, CPU "
                  f"{row['cpu_gpairs_per_s']:6.2f} ({cores} threads), x{row['gpu_over_cpu']:.1f}, "
                  f"diff {diff:.1e}", flush=True)
    return rows


def _sweep_calls(system, n_slices: int, steps: int, dt: float) -> list:
    fine = integrate.Propagator(system, "rk2", dt)
    x0 = system.initial_state()
    times = parareal.time_points(0.0, n_slices * steps * dt, n_slices)
    return [(fine, (times[i], times[i + 1], x0), {}) for i in range(n_slices)]


def _gpu_against_pool(system, calls: list, cpu_workers: int,
                      launches: list[int] | None = None) -> tuple[float, float, float, float]:
    """The ``calls`` as one batch of the GPU path, then on a process pool of ``cpu_workers``:
    (GPU seconds, pool seconds, largest difference of the end states, the motion)."""
    batch.warm_up(system)
    t = time.perf_counter()
    outcomes = batch.run_calls(calls, launches=launches)
    gpu_seconds = time.perf_counter() - t
    assert all(ok for ok, _ in outcomes), [v for ok, v in outcomes if not ok]
    gpu_states = np.array([v for _, v in outcomes])
    with parallel.make_executor("processes", cpu_workers, warmup=WarmUp(system)) as ex:
        t = time.perf_counter()
        cpu_states = np.array(parallel.run_labelled(
            ex, calls[0][0], [c[1] for c in calls], [f"call {i}" for i in range(len(calls))]))
        cpu_seconds = time.perf_counter() - t
    motion = np.abs(cpu_states - calls[0][1][2]).max()
    return gpu_seconds, cpu_seconds, float(np.abs(gpu_states - cpu_states).max()), motion


def sweep_section(n_points: int, n_slices: int, steps: int, cpu_workers: int) -> dict:
    system = models.rod_swimmer(n_points=n_points, length=60.0 * (n_points - 1) / 300)
    calls = _sweep_calls(system, n_slices, steps, 1e-6)
    gpu_seconds, cpu_seconds, diff, motion = _gpu_against_pool(system, calls, cpu_workers)
    out = {"n_points": n_points, "slices": n_slices, "steps_per_slice": steps,
           "gpu_seconds": gpu_seconds, "cpu_seconds": cpu_seconds, "cpu_workers": cpu_workers,
           "gpu_over_cpu": cpu_seconds / gpu_seconds, "max_abs_diff": float(diff),
           "max_rel_diff": float(diff / motion)}
    print(f"sweep {n_slices} x {steps} RK2 steps, M = {n_points}: GPU {gpu_seconds:.2f} s, CPU "
          f"{cpu_seconds:.2f} s on {cpu_workers} processes (x{out['gpu_over_cpu']:.1f}); "
          f"end states differ by {diff / motion:.1e} of the motion", flush=True)
    return out


def rigid_section(counts: tuple[int, int, int], points: int, members: int, steps: int,
                  cpu_workers: int) -> dict:
    scene = config.build(*scene_config(lattice_placement(4.0, counts), points)).system
    calls = _sweep_calls(scene, members, steps, 0.05)
    launches: list[int] = []
    gpu_seconds, cpu_seconds, diff, motion = _gpu_against_pool(scene, calls, cpu_workers,
                                                               launches)
    n_points = sum(len(block) - 1 for block in scene.blocks(scene.initial_state()))
    out = {"bodies": len(scene.bodies), "surface_points": n_points, "members": members,
           "steps": steps, "gpu_seconds": gpu_seconds, "cpu_seconds": cpu_seconds,
           "cpu_workers": cpu_workers, "gpu_over_cpu": cpu_seconds / gpu_seconds,
           "launches": len(launches), "mean_launch_batch": float(np.mean(launches)),
           "max_rel_diff": float(diff / motion)}
    print(f"rigid {out['bodies']} spheres ({n_points} points), {members} solves x {steps} RK2 "
          f"steps: GPU (hosted) {gpu_seconds:.2f} s, CPU {cpu_seconds:.2f} s on {cpu_workers} "
          f"processes (x{out['gpu_over_cpu']:.2f}); {len(launches)} launches of "
          f"{out['mean_launch_batch']:.1f} products on average; end states differ by "
          f"{diff / motion:.1e} of the motion", flush=True)
    return out


def _configured(name: str, changes: dict) -> tuple:
    cfg, _ = config.load(ROOT / "experiments" / name)
    data = cfg.model_dump()
    for section, values in changes.items():
        data[section] = {**data[section], **values}
    cfg = config.Config.model_validate(data)
    resolved = config.resolve(cfg)
    return cfg, resolved


def _parareal(name: str, changes: dict, kind: str, workers: int | None) -> tuple:
    execution = {"executor": kind, "workers": workers, "allow_oversubscribe": True}
    cfg, resolved = _configured(name, {**changes, "execution": execution})
    setup = config.build(cfg, resolved)
    with session.start(setup) as running:
        x0 = setup.system.initial_state()
        t = time.perf_counter()
        result = parareal.run(setup.fine, setup.coarse, x0, cfg.time.t0, cfg.time.t1,
                              cfg.parareal.n_slices, 0.0, cfg.parareal.max_iterations,
                              executor=running.executor, project=setup.system.project,
                              allow_oversubscribe=True)
        return result, time.perf_counter() - t, x0


def parareal_section(short: dict, full: dict, cpu_workers: int) -> dict:
    out = {}
    for label, (name, changes) in short.items():
        gpu, gpu_seconds, x0 = _parareal(name, changes, "gpu", None)
        cpu, cpu_seconds, _ = _parareal(name, changes, "processes", cpu_workers)
        motion = np.abs(cpu.states - x0).max()
        diff = float(np.abs(gpu.states - cpu.states).max() / motion)
        out[label] = {"config": name, "changes": changes, "gpu_seconds": gpu_seconds,
                      "cpu_seconds": cpu_seconds, "max_rel_diff_of_iterates": diff,
                      "increments_gpu": gpu.increments, "increments_cpu": cpu.increments}
        print(f"parareal {label}: GPU {gpu_seconds:.1f} s, CPU {cpu_seconds:.1f} s on "
              f"{cpu_workers} processes; iterates differ by {diff:.1e} of the motion", flush=True)
    for label, (name, changes) in full.items():
        gpu, gpu_seconds, _ = _parareal(name, changes, "gpu", None)
        out[label] = {"config": name, "changes": changes, "gpu_seconds": gpu_seconds,
                      "iterations": gpu.iterations, "increments": gpu.increments,
                      "parallel_sweeps": gpu.timings.parallel_sweeps,
                      "serial_sweeps": gpu.timings.serial_sweeps}
        print(f"parareal {label}: {gpu.iterations} iterations in {gpu_seconds:.1f} s on the GPU; "
              f"increments {np.array2string(np.array(gpu.increments), precision=2)}", flush=True)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sections", default="kernels,sweep,parareal,rigid")
    parser.add_argument("--json", type=Path, default=None, help="write the results here")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--smoke", action="store_true", help="tiny sizes, to test the script")
    parser.add_argument("--shapes", default=None,
                        help="kernel blocks TXxSY: the first for all B, the others at B = 40 "
                             "(e.g. 32x8,32x4,32x16,64x4); default: the package's (32x8)")
    args = parser.parse_args(argv)
    device.require()
    cores = len(os.sched_getaffinity(0))
    info = gpu_info()
    print(f"GPU: {info['name']}; FP64 peak {info['fp64_peak_tflops']} TFLOP/s; {cores} CPU cores",
          flush=True)
    report = {"gpu": info, "cpu_cores": cores, "targets": TARGETS, "smoke": args.smoke,
              "python": platform.python_version(), "argv": sys.argv[1:]}
    if args.smoke:
        sizes, batches, sweep = {"rod": 5, "vesicle": 12}, (1, 2), (5, 2, 3)
        short = {"rod (short)": ("table4_g3.toml", {
            "model": {"n_points": 7, "length": 1.2}, "time": {"t1": 4e-5},
            "parareal": {"n_slices": 2, "max_iterations": 1},
            "coarse": {"lagrange": {"epsilon": {"nodes": [5.02, 5.04], "unit": "sigma_f"}},
                       "richardson": {"m": 0}}})}
        full = {}
        rigid = ((2, 1, 1), 12, 2, 1)
        # the GMRES path of large suspensions on 24 points (in this process: the pool's workers
        # solve them densely, so the end states differ by about GMRES's tolerance, 1e-10)
        choice.DENSE_MAX_POINTS = 0
    else:
        sizes, batches, sweep = {"rod": 301, "vesicle": 642}, BATCHES, (301, 40, 25_000)
        short = {
            "rod Table 4 G^3 (T = 4e-3)": ("table4_g3.toml", {"time": {"t1": 4e-3},
                                                               "parareal": {"max_iterations": 2}}),
            "vesicle Table 7 G^1 (T = 4)": ("table7_g1.toml", {"time": {"t1": 4.0},
                                                                "parareal": {"max_iterations": 2}}),
        }
        full = {"rod Table 4 G^3": ("table4_g3.toml", {}),
                "vesicle Table 7 G^1": ("table7_g1.toml", {})}
        rigid = ((4, 4, 4), 150, cores, 2)

    def save() -> None:
        if args.json is not None:
            args.json.write_text(json.dumps(report, indent=2, default=float) + "\n")

    sections = args.sections.split(",")
    if "kernels" in sections:
        shapes = [stepping.Launch.default()] if args.shapes is None else [
            stepping.Launch(*map(int, text.split("x"))) for text in args.shapes.split(",")]
        report["kernels"] = kernels_section(sizes, batches, args.rounds, info, shapes)
        save()
    if "sweep" in sections:
        report["sweep"] = sweep_section(*sweep, cpu_workers=cores)
        save()
    if "parareal" in sections:
        report["parareal"] = parareal_section(short, full, cpu_workers=cores)
        save()
    if "rigid" in sections:
        report["rigid"] = rigid_section(*rigid, cpu_workers=cores)
        save()
    return 0


if __name__ == "__main__":
    sys.exit(main())
