"""A small Parareal rod problem solved on any executor (shared by pytest and the MPI script).

A 21-point swimmer above the wall, 4 slices of 1e-4 s, fine RK2 (dt 1e-6) and a coarse solver
extrapolated from 4 auxiliary Euler solvers (Lagrange in epsilon x Richardson m = 1), so both the
parallel sweep and the auxiliary solvers of the serial sweep go through the executor. With more
solvers than workers (2 processes) they are batched per worker (``allow_oversubscribe=True``), so
the comparison also covers batching: 4 single tasks (serial, 1 MPI worker) == 2 batches of 2.
"""

from __future__ import annotations

import numpy as np

from parastokes import integrate, models, parareal

N_SLICES = 4
T1 = 4e-4


def solve(executor, schedule: str = "standard") -> tuple[np.ndarray, np.ndarray]:
    """Parareal iterates at T_0..T_N after 3 iterations, and the increments eta~^k."""
    rod = models.rod_swimmer(n_points=21)
    fine = integrate.Propagator(rod, "rk2", 1e-6)
    coarse = parareal.extrapolated(
        rod, "euler", 1e-5, lagrange={"epsilon": [1.03, 1.06]}, richardson={"m": 1, "r": 0.83}
    )
    result = parareal.run(
        fine,
        coarse,
        rod.initial_state(),
        t0=0.0,
        t1=T1,
        n_slices=N_SLICES,
        tol=0.0,
        max_iterations=3,
        executor=executor,
        allow_oversubscribe=True,
        schedule=schedule,
    )
    return result.states, np.asarray(result.increments)
