"""Picklable tasks for the executor tests, importable by worker processes and MPI ranks.

The pytest process imports this module as ``mpi_scripts.parallel_tasks`` and the MPI scripts as
``parallel_tasks``; either way workers import it by the same name as their manager.
"""

from __future__ import annotations

import json
import os
import pathlib
import time

import numpy as np

# (sigma, rho, beta, x0) of the Lorenz runs compared bit for bit between executors.
LORENZ_CASES = [
    (10.0, 28.0, 8.0 / 3.0, (1.0, 1.0, 1.0)),
    (10.0, 24.5, 8.0 / 3.0, (-3.0, 2.0, 20.0)),
    (12.0, 30.0, 2.5, (0.5, -1.0, 10.0)),
    (9.0, 28.0, 3.0, (2.0, 2.0, 2.0)),
    (10.0, 99.0, 8.0 / 3.0, (0.0, 1.0, 0.0)),
]
LORENZ_T = 2.0
LORENZ_STEPS = 4000


def _lorenz_rates(y: np.ndarray, sigma: float, rho: float, beta: float) -> np.ndarray:
    return np.array([sigma * (y[1] - y[0]), y[0] * (rho - y[2]) - y[1], y[0] * y[1] - beta * y[2]])


def lorenz(sigma: float, rho: float, beta: float, x0, t_end: float, n_steps: int) -> np.ndarray:
    """RK4 trajectory (n_steps + 1, 3) of the Lorenz system: chaotic, so any change shows."""
    dt = t_end / n_steps
    out = np.empty((n_steps + 1, 3))
    y = out[0] = np.asarray(x0, dtype=np.float64)
    for n in range(n_steps):
        k1 = _lorenz_rates(y, sigma, rho, beta)
        k2 = _lorenz_rates(y + 0.5 * dt * k1, sigma, rho, beta)
        k3 = _lorenz_rates(y + 0.5 * dt * k2, sigma, rho, beta)
        k4 = _lorenz_rates(y + dt * k3, sigma, rho, beta)
        y = out[n + 1] = y + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return out


def lorenz_args() -> list[tuple]:
    """Arguments of the reference Lorenz runs, one tuple per task."""
    return [(*case, LORENZ_T, LORENZ_STEPS) for case in LORENZ_CASES]


def record_worker(directory: str) -> None:
    """Warm-up: write this process's pid and numba thread count to ``directory/<pid>.json``."""
    import numba

    info = {"pid": os.getpid(), "numba_threads": numba.get_num_threads()}
    (pathlib.Path(directory) / f"{os.getpid()}.json").write_text(json.dumps(info))


def failing_warmup() -> None:
    """A warm-up that raises."""
    raise OSError("no numba cache here")


def slow_warmup() -> None:
    """A warm-up that takes 20 s (a first compilation, say)."""
    time.sleep(20.0)


def pid_after(seconds: float) -> int:
    """Sleep, then return this process's pid (spreads tasks over the workers)."""
    time.sleep(seconds)
    return os.getpid()


def fail_on(index: int, bad: int) -> int:
    """Return ``index``, or raise ValueError when it is ``bad``."""
    if index == bad:
        raise ValueError(f"negative length at node {index}")
    return index


def die_on(index: int, bad: int, seconds: float) -> int:
    """Sleep ``seconds``, then return ``index``; task ``bad`` instead exits its process (code 7)."""
    time.sleep(seconds)
    if index == bad:
        os._exit(7)
    return index


def exercise(executor, out_dir: str) -> None:
    """Run the checks shared by the MPI scripts; write ``results.npy`` and ``report.json``.

    ``results.npy``: the Lorenz runs stacked; ``report.json``: the executor's ``workers``, the pids
    that ran tasks, and the label, type and message of the TaskError of a raising task.
    """
    from parastokes import parallel

    args = lorenz_args()
    results = parallel.run_labelled(executor, lorenz, args, [f"case {i}" for i in range(len(args))])
    np.save(pathlib.Path(out_dir) / "results.npy", np.stack(results))
    pids = parallel.run_labelled(executor, pid_after, [(0.05,)] * 4, ["pid"] * 4)
    try:
        parallel.run_labelled(
            executor, fail_on, [(i, 2) for i in range(4)], [f"slice {i}" for i in range(4)]
        )
    except parallel.TaskError as exc:
        error = {"label": exc.label, "type": type(exc.original).__name__, "message": str(exc)}
    else:
        error = None
    report = {"workers": executor.workers, "task_pids": pids, "error": error}
    (pathlib.Path(out_dir) / "report.json").write_text(json.dumps(report))


def fail_after(seconds: float, message: str) -> None:
    """Sleep, then raise RuntimeError(message)."""
    time.sleep(seconds)
    raise RuntimeError(message)


def mark_and_sleep(directory: str, index: int, seconds: float) -> int:
    """Write ``directory/index`` (the task started), sleep ``seconds``, return ``index``."""
    (pathlib.Path(directory) / str(index)).write_text("")
    time.sleep(seconds)
    return index
