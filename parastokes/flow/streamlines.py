"""Streamlines of one frame's flow in 3-D, from seed points (as SkellySim's listener offers them).

A streamline through x0 solves dx/ds = u(x)/|u(x)| in arclength s (the frame frozen:
:func:`.evaluate.velocity` at time t), forwards and, with ``both_ways``, backwards, over
``length`` each way. All seeds are integrated together by scipy's adaptive Runge-Kutta (RK45),
one evaluation of the flow at all current points per stage; points where |u| vanishes (a
stagnation point, below the wall) stay where they are.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from .evaluate import velocity

__all__ = ["streamlines"]


def streamlines(system: object, state: np.ndarray, seeds: np.ndarray, length: float,
                t: float = 0.0, background: bool = True, both_ways: bool = True,
                samples: int = 101, rtol: float = 1e-8, atol: float = 1e-10,
                n_threads: int | None = None) -> list[np.ndarray]:
    """The streamline through every seed (K, 3) of the flow of ``system`` in ``state`` at ``t``:
    ``samples`` points (a second ``samples - 1`` before the seed with ``both_ways``) evenly
    spaced in arclength over ``length`` each way, seed included; one (P, 3) array per seed."""
    seeds = np.atleast_2d(np.asarray(seeds, dtype=float))
    if seeds.ndim != 2 or seeds.shape[1] != 3 or not np.all(np.isfinite(seeds)):
        raise ValueError(f"seeds: need finite (K, 3) points, got shape {seeds.shape}")
    if not (np.isfinite(length) and length > 0) or samples < 2:
        raise ValueError(f"length must be > 0 and samples >= 2, got {length!r}, {samples!r}")
    state = np.asarray(state, dtype=float)

    def run(sign: float) -> np.ndarray:
        def direction(_s: float, y: np.ndarray) -> np.ndarray:
            x = y.reshape(-1, 3)
            u = velocity(system, state, x, t, background, n_threads)
            speed = np.linalg.norm(u, axis=1, keepdims=True)
            return (sign * np.divide(u, speed, out=np.zeros_like(u), where=speed > 0)).ravel()

        s = np.linspace(0.0, length, samples)
        solution = solve_ivp(direction, (0.0, length), seeds.ravel(), method="RK45", t_eval=s,
                             rtol=rtol, atol=atol)
        if not solution.success:
            raise ValueError(f"streamlines: the integration failed ({solution.message})")
        return solution.y.reshape(len(seeds), 3, samples).transpose(0, 2, 1)

    forward = run(1.0)
    if not both_ways:
        return list(forward)
    backward = run(-1.0)
    return [np.concatenate([b[:0:-1], f]) for b, f in zip(backward, forward, strict=True)]
