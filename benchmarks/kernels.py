"""Throughput of the regularized-Stokeslet kernels: pair interactions per second.

Run from the repository root::

    PYTHONPATH=. python benchmarks/kernels.py [--rounds 7] [--json PATH]

Times, for N = 301, 642, 1505 and 5000 points (targets = sources, N² pairs each):

- ``free``: the free-space force kernel, ``mrs.velocity(x, x, f)`` (u from f, eq. 6);
- ``wall``: the full wall kernel, ``mrs.velocity(x, x, f, torques=n, wall=True, angular=True)``
  (u and w from f and n, the physics notes' (1)-(8), the paper's eqs. 3-6);

on 1 and 2 threads with ``check=False`` (the kernel alone), plus one line per kernel with
validation on (N = 642, alternating calls with and without it); the numpy oracle
(``mrs.reference.velocity``) on the two smaller N only (it holds O(N²) arrays). All cases are
timed in turn over ``--rounds`` rounds and the minimum is kept (other processes share the cores).
The kernels' flop rates, counting :data:`FLOPS_PER_PAIR` flops per pair, are compared with a
float64 2000 x 2000 matmul on one thread, measured in a subprocess with ``OPENBLAS_NUM_THREADS=1``
in the same run.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from functools import partial

import numba
import numpy as np

from parastokes import mrs

SIZES = (301, 642, 1505, 5000)
ORACLE_SIZES = (301, 642)
THREADS = (1, 2)
#: Conventional flop counts per pair: ~20 for the free force kernel, ~200 for the full
#: wall kernel (free u, w from f, n plus the four image parts). docs/benchmarks.md details
#: the operation counts of the compiled code.
FLOPS_PER_PAIR = {"free": 20, "wall": 200}
#: Targets: G pairs/s per core on 1 thread, on 2 threads (total), and the speed-up over
#: the oracle.
TARGETS = {"free": (0.9, None, 25.0), "wall": (0.2, 0.4, 25.0)}
EPSILON, MU = 0.05, 1.0

_MATMUL = r"""
import ctypes, json, sys, time
import numpy as np

def corename():
    # The OpenBLAS core type picked at run time, read from the library numpy loaded.
    with open("/proc/self/maps") as maps:
        paths = {line.split()[-1] for line in maps if "openblas" in line.lower()}
    for path in sorted(paths):
        lib = ctypes.CDLL(path)
        for symbol in ("scipy_openblas_get_corename64_", "openblas_get_corename64_",
                       "openblas_get_corename"):
            if hasattr(lib, symbol):
                fn = getattr(lib, symbol)
                fn.restype = ctypes.c_char_p
                return fn().decode()
    return "unknown"

n = int(sys.argv[1])
rng = np.random.default_rng(0)
a, b = rng.random((n, n)), rng.random((n, n))
a @ b
times = []
for _ in range(int(sys.argv[2])):
    t0 = time.perf_counter()
    a @ b
    times.append(time.perf_counter() - t0)
print(json.dumps({"gflops": 2 * n**3 / min(times) / 1e9, "corename": corename()}))
"""


def matmul_rate(n: int = 2000, repeats: int = 5) -> dict:
    """Single-thread float64 n x n matmul rate (GFLOP/s) and OpenBLAS core, in a subprocess."""
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    out = subprocess.run(
        [sys.executable, "-c", _MATMUL, str(n), str(repeats)],
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(out.stdout)


def _problem(kind: str, n: int, seed: int = 0):
    """Points in a 10 x 10 x 10 box above the wall, random forces (and torques for the wall)."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(0.0, 10.0, (n, 3))
    x[:, 2] += 0.5
    f = rng.normal(size=(n, 3))
    if kind == "free":
        return (x, x, f), {}
    return (x, x, f), dict(torques=rng.normal(size=(n, 3)), wall=True, angular=True)


def _batch(fn, seconds: float = 0.02) -> int:
    """Calls per timed sample so that one sample lasts about ``seconds`` (after a warm-up)."""
    fn()
    t0 = time.perf_counter()
    fn()
    return max(1, round(seconds / max(time.perf_counter() - t0, 1e-9)))


def _cases() -> list[tuple[dict, object]]:
    """(row, callable) for every timed case: the kernels and the oracle."""
    cases = []
    for kind in ("free", "wall"):
        for n in SIZES:
            args, kw = _problem(kind, n)
            compiled = partial(mrs.velocity, *args, epsilon=EPSILON, mu=MU, **kw)
            row = dict(kernel=kind, n=n, threads=1, check=False, oracle=False)
            for threads in THREADS:
                cases.append(
                    (row | dict(threads=threads), partial(compiled, n_threads=threads, check=False))
                )
            if n in ORACLE_SIZES:
                oracle = partial(mrs.reference.velocity, *args, epsilon=EPSILON, mu=MU, **kw)
                cases.append((row | dict(oracle=True), oracle))
    return cases


def measure(rounds: int) -> list[dict]:
    """Seconds per call of every case over ``rounds`` interleaved rounds.

    The cases are timed in turn, round after round, so that every case samples the same
    stretches of machine load (other processes share the two cores). Kept per case: the minimum
    and the median wall time, and the minimum CPU time of the calling thread (``thread_time``),
    which for one thread excludes the time the process was not scheduled. Short calls are timed
    in batches of about 20 ms.
    """
    cases = _cases()
    batches = [_batch(fn) for _, fn in cases]
    wall = [[] for _ in cases]
    cpu = [[] for _ in cases]
    for _ in range(rounds):
        for i, ((_, fn), k) in enumerate(zip(cases, batches, strict=True)):
            t0, c0 = time.perf_counter(), time.thread_time()
            for _ in range(k):
                fn()
            cpu[i].append((time.thread_time() - c0) / k)
            wall[i].append((time.perf_counter() - t0) / k)
    return [
        dict(
            row,
            seconds=min(w),
            median_seconds=float(np.median(w)),
            cpu_seconds=min(c) if row["threads"] == 1 else None,
        )
        for (row, _), w, c in zip(cases, wall, cpu, strict=True)
    ]


def validation_overhead(kind: str, n: int = 642, calls: int = 200) -> dict:
    """One thread, N = n: seconds per call with ``check=True`` and ``check=False``.

    The two are called alternately ``calls`` times each and the minima kept, so that the small
    difference (tens of µs) is not lost in the machine's load fluctuations.
    """
    args, kw = _problem(kind, n)
    compiled = partial(mrs.velocity, *args, epsilon=EPSILON, mu=MU, n_threads=1, **kw)
    best = {True: np.inf, False: np.inf}
    for _ in range(calls):
        for check in (True, False):
            t0 = time.perf_counter()
            compiled(check=check)
            best[check] = min(best[check], time.perf_counter() - t0)
    return dict(
        kernel=kind,
        n=n,
        threads=1,
        check=True,
        oracle=False,
        seconds=best[True],
        median_seconds=best[True],
        cpu_seconds=None,
        check_overhead=best[True] / best[False] - 1.0,
        check_overhead_us=1e6 * (best[True] - best[False]),
        seconds_without_check=best[False],
    )


def call_overhead(calls: int = 2000, rounds: int = 7) -> dict:
    """CPU seconds per ``mrs.velocity(check=False)`` call on 8 targets and 8 sources (wall, u and
    w from f and n, one thread): 64 pairs, so what is measured is the call's fixed cost (packing,
    thread setting, allocation, dispatch)."""
    args, kw = _problem("wall", 8)
    call = partial(mrs.velocity, *args, epsilon=EPSILON, mu=MU, n_threads=1, check=False, **kw)
    call()
    best = np.inf
    for _ in range(rounds):
        t0 = time.process_time()
        for _ in range(calls):
            call()
        best = min(best, (time.process_time() - t0) / calls)
    return dict(seconds=best)


def run(rounds: int) -> dict:
    """All the measurements, as a JSON-ready dict."""
    load_before = os.getloadavg()
    blas = matmul_rate()
    timed = measure(rounds)
    oracle = {(r["kernel"], r["n"]): r["seconds"] for r in timed if r["oracle"]}
    rows = [r for r in timed if not r["oracle"]]
    rows += [validation_overhead(kind) for kind in ("free", "wall")]
    for row in rows:
        pairs = row["n"] ** 2
        rate = pairs / row["seconds"]
        row["gpairs_per_s"] = rate / 1e9
        row["gpairs_per_s_per_core"] = rate / 1e9 / row["threads"]
        row["gpairs_per_cpu_s"] = pairs / row["cpu_seconds"] / 1e9 if row["cpu_seconds"] else None
        row["gflops"] = rate * FLOPS_PER_PAIR[row["kernel"]] / 1e9
        row["flops_over_matmul_per_core"] = row["gflops"] / row["threads"] / blas["gflops"]
        t_oracle = (
            oracle.get((row["kernel"], row["n"]))
            if row["threads"] == 1 and not row["check"]
            else None
        )
        row["x_oracle"] = None if t_oracle is None else t_oracle / row["seconds"]
        row["oracle_seconds"] = t_oracle
    return dict(
        machine=dict(
            cpu=_cpu_name(),
            cores=os.cpu_count(),
            python=platform.python_version(),
            numpy=np.__version__,
            numba=numba.__version__,
            numba_threads=numba.config.NUMBA_NUM_THREADS,
            openblas_core=blas["corename"],
            openblas_coretype_env=os.environ.get("OPENBLAS_CORETYPE"),
            loadavg_before=load_before,
            loadavg_after=os.getloadavg(),
        ),
        matmul_gflops_1thread=blas["gflops"],
        call_overhead=call_overhead(),
        flops_per_pair=FLOPS_PER_PAIR,
        targets={
            k: dict(zip(("per_core_1t", "total_2t", "x_oracle"), v, strict=True))
            for k, v in TARGETS.items()
        },
        rows=rows,
    )


def _cpu_name() -> str:
    """The CPU model and its vector extensions (from /proc/cpuinfo where available)."""
    try:
        with open("/proc/cpuinfo") as info:
            lines = info.read().splitlines()
    except OSError:
        return platform.processor() or "unknown"
    model = next((ln.split(":", 1)[1].strip() for ln in lines if ln.startswith("model name")), "?")
    flags = next((ln.split(":", 1)[1].split() for ln in lines if ln.startswith("flags")), [])
    simd = [f for f in ("avx2", "fma", "avx512f") if f in flags]
    return f"{model} ({', '.join(simd)})"


def table(result: dict) -> str:
    """The compact text table of :func:`run`'s result."""
    m = result["machine"]
    lines = [
        f"cpu: {m['cpu']}, {m['cores']} cores; python {m['python']}, numpy {m['numpy']}, "
        f"numba {m['numba']}",
        f"openblas core: {m['openblas_core']} (OPENBLAS_CORETYPE={m['openblas_coretype_env']}); "
        f"load average before/after: {m['loadavg_before'][0]:.2f} / {m['loadavg_after'][0]:.2f}",
        f"matmul 2000x2000 float64, 1 thread: {result['matmul_gflops_1thread']:.1f} GFLOP/s; "
        f"flops per pair: free {FLOPS_PER_PAIR['free']}, wall {FLOPS_PER_PAIR['wall']}",
        "",
        f"{'kernel':6} {'N':>5} {'thr':>3} {'check':>5} {'ms':>9} {'Gpair/s':>8} {'/core':>7} "
        f"{'med/min':>7} {'cpu G/s':>7} {'x oracle':>9} {'flop/matmul':>11}",
    ]
    for r in result["rows"]:
        xo = "" if r["x_oracle"] is None else f"{r['x_oracle']:.0f}"
        spread = r["median_seconds"] / r["seconds"]
        cpu = "" if r["gpairs_per_cpu_s"] is None else f"{r['gpairs_per_cpu_s']:.3f}"
        note = (
            f"  validation +{r['check_overhead_us']:.0f} us = +{100 * r['check_overhead']:.1f}% "
            f"of {1e3 * r['seconds_without_check']:.2f} ms"
            if r["check"]
            else ""
        )
        lines.append(
            f"{r['kernel']:6} {r['n']:>5} {r['threads']:>3} {'on' if r['check'] else 'off':>5} "
            f"{1e3 * r['seconds']:>9.2f} {r['gpairs_per_s']:>8.3f} "
            f"{r['gpairs_per_s_per_core']:>7.3f} {spread:>7.2f} {cpu:>7} {xo:>9} "
            f"{r['flops_over_matmul_per_core']:>11.2f}{note}"
        )
    lines.append("")
    for kind, (per_core, total2, x_or) in TARGETS.items():
        rows = [r for r in result["rows"] if r["kernel"] == kind and not r["check"]]
        best1 = max(r["gpairs_per_s"] for r in rows if r["threads"] == 1)
        best_cpu = max(r["gpairs_per_cpu_s"] for r in rows if r["threads"] == 1)
        best2 = max(r["gpairs_per_s"] for r in rows if r["threads"] == 2)
        worst_x = min(r["x_oracle"] for r in rows if r["x_oracle"] is not None)
        parts = [
            f"1 thread {best1:.3f} G/s ({best_cpu:.3f} per CPU second; target {per_core}), "
            f"{best1 * FLOPS_PER_PAIR[kind]:.1f} GFLOP/s = "
            f"{best1 * FLOPS_PER_PAIR[kind] / result['matmul_gflops_1thread']:.2f} x matmul",
            f"2 threads {best2:.3f} G/s" + ("" if total2 is None else f" (target {total2})"),
            f"x oracle >= {worst_x:.0f} (target {x_or:.0f})",
        ]
        lines.append(f"{kind}: best " + "; ".join(parts))
    lines.append(
        "per-call overhead of mrs.velocity(check=False), 8 targets x 8 sources, wall, u and w: "
        f"{1e6 * result['call_overhead']['seconds']:.1f} us of CPU time"
    )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    """Command line: print the table, optionally save the JSON."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument(
        "--rounds", type=int, default=7, help="interleaved timing rounds (the minimum is kept)"
    )
    parser.add_argument("--json", metavar="PATH", help="also write the results as JSON")
    args = parser.parse_args(argv)
    result = run(args.rounds)
    print(table(result))
    if args.json:
        with open(args.json, "w") as out:
            json.dump(result, out, indent=1)


if __name__ == "__main__":
    main()
