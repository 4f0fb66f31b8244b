"""The rod system's time loop in compiled code: many Runge-Kutta steps in one call.

:func:`parastokes.integrate.run` takes its steps through ``system.rates`` and
``system.advance``, one Python call each per stage. For the paper's fine solve (one rod, 10^6 RK2
steps) that Python (packing the kernel's input, building the stage states, the per-step checks)
cost as much as 20-40% of the two kernel evaluations of a step. :func:`run_steps` runs the same
tableau (including the RKMK commutator terms of RK4, see :mod:`parastokes.integrate`) with the
same compiled parts, in the same order:

- a stage's rates: the preferred strain (eq. 36), the rod loads (eqs. 10-12), and ``u``, ``w``
  from :func:`parastokes.mrs.compiled.full` on the points padded as ``mrs.velocity`` pads them;
- stage and final states: ``advance_rod`` (eq. 13) of the old state by the combined rates,
  combined as ``integrate`` combines them (zero coefficients skipped, terms added in order);
- after each step: the finiteness check and the length monitor, stopping at the first failure
  with the last good state kept.

So it returns what the Python loop returns, to round-off (the tests compare them). Everything is
allocated once per call; the only Python left is one call per propagation.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .bodies.frames import advance_rod
from .bodies.rod import length_change, preferred_strain, rod_loads
from .integrate import ABOVE, BEYOND, DONE, NON_FINITE, Scheme
from .mrs import compiled
from .mrs.velocity import EIGHT_PI, kernel_threads

__all__ = ["run_steps", "tableau_arrays"]

_OPTS = dict(cache=True, error_model="numpy")


def tableau_arrays(scheme) -> tuple[np.ndarray, ...]:
    """A :class:`parastokes.integrate.Scheme` as arrays: ``c`` (s,), ``a`` (s, s), ``b`` (s,),
    stage brackets (m, 4) rows ``(stage, coefficient, p, q)``, final brackets (m', 3) rows
    ``(coefficient, p, q)``."""
    s = scheme.stages
    a = np.zeros((s, s))
    for i, row in enumerate(scheme.a):
        a[i, : len(row)] = row
    stage = [(i, c, p, q) for i, terms in enumerate(scheme.stage_brackets) for c, p, q in terms]
    return (
        np.array(scheme.c, dtype=float),
        a,
        np.array(scheme.b, dtype=float),
        np.array(stage, dtype=float).reshape(-1, 4),
        np.array(scheme.final_brackets, dtype=float).reshape(-1, 3),
    )


@njit(**_OPTS)
def _rates(t, x, mechanics, kernel, buffers, out):
    """``RodSystem.rates(t, x)`` into ``out`` (n, 6), through the same compiled functions;
    ``mechanics`` is ``RodSystem.mechanics``."""
    n_rods, ds, a, b, table, constant, amplitude, wavenumber, frequency = mechanics
    eps, denom, wall, starts = kernel
    tp, s3, u, w = buffers
    n = x.shape[0]
    omega_hat = preferred_strain(table, t, constant, amplitude, wavenumber, frequency)
    f, tq = rod_loads(x, n_rods, ds, a, b, omega_hat)
    for i in range(tp.shape[2]):
        src = min(i, n - 1)  # padding repeats the last point, as mrs.velocity does
        for j in range(3):
            tp[j, 0, i] = x[src, j]
    for i in range(n):
        for j in range(3):
            s3[0, i, j] = x[i, j]
    compiled.full(tp, s3, f.reshape((1, n, 3)), tq.reshape((1, n, 3)), eps, wall, False, denom,
                  starts, u, w)
    for i in range(n):
        for j in range(3):
            out[i, j] = u[0, i, j]
            out[i, 3 + j] = w[0, i, j]


@njit(**_OPTS)
def _combine(coefs, k, brackets, stage, dt, out):
    """``integrate._combine`` into ``out``: Σ_j coefs[j] k_j (non-zero terms, in order) plus
    ``coefficient * dt * [0, w_p × w_q]`` for the bracket rows of this ``stage`` (-1: final)."""
    first = True
    for j in range(coefs.size):
        c = coefs[j]
        if c == 0.0:
            continue
        for i in range(out.shape[0]):
            for q in range(6):
                out[i, q] = c * k[j, i, q] if first else out[i, q] + c * k[j, i, q]
        first = False
    for row in range(brackets.shape[0]):
        if stage >= 0 and brackets[row, 0] != stage:
            continue
        off = 0 if stage < 0 else 1
        h = brackets[row, off] * dt
        p = int(brackets[row, off + 1])
        q = int(brackets[row, off + 2])
        for i in range(out.shape[0]):
            out[i, 3] += h * (k[p, i, 4] * k[q, i, 5] - k[p, i, 5] * k[q, i, 4])
            out[i, 4] += h * (k[p, i, 5] * k[q, i, 3] - k[p, i, 3] * k[q, i, 5])
            out[i, 5] += h * (k[p, i, 3] * k[q, i, 4] - k[p, i, 4] * k[q, i, 3])


@njit(**_OPTS)
def _finite(x):
    for v in x.flat:
        if not np.isfinite(v):
            return False
    return True


@njit(**_OPTS)
def _run(x, t0, dt, n_steps, tableau, mechanics, kernel, padded, length, limit, stop_above):
    c, a, b, stage_brackets, final_brackets = tableau
    n_rods = mechanics[0]
    n = x.shape[0]
    k = np.empty((b.size, n, 6))
    comb = np.empty((n, 6))
    buffers = (np.empty((3, 1, padded)), np.empty((1, n, 3)), np.empty((1, n, 3)),
               np.empty((1, n, 3)))
    worst = length_change(x, n_rods, length)
    for i in range(n_steps):
        t = t0 + i * dt
        _rates(t, x, mechanics, kernel, buffers, k[0])
        for st in range(1, b.size):
            _combine(a[st, :st], k, stage_brackets, st, dt, comb)
            _rates(t + c[st] * dt, advance_rod(x, comb, dt), mechanics, kernel, buffers, k[st])
        _combine(b, k, final_brackets, -1, dt, comb)
        x_new = advance_rod(x, comb, dt)
        if not _finite(x_new):
            return x, worst, i, NON_FINITE, math.nan
        m = length_change(x_new, n_rods, length)
        if not m <= limit:
            return x, worst, i, BEYOND, m
        worst = max(worst, m)
        x = x_new
        if m > stop_above:
            return x, worst, i + 1, ABOVE, m
    return x, worst, n_steps, DONE, worst


def run_steps(system, scheme: Scheme, x: np.ndarray, t0: float, dt: float, n: int, limit: float,
              stop_above: float) -> tuple[np.ndarray, float, int, int, float]:
    """``n`` steps of ``scheme`` for the :class:`parastokes.system.RodSystem` ``system`` from
    ``(t0, x)``, its kernels on ``system.n_threads`` threads.

    Returns what ``integrate._python_steps`` returns: ``(last state kept, worst monitor, steps
    kept, outcome, monitor that ended the run)``, the outcome one of ``integrate.DONE``,
    ``ABOVE``, ``NON_FINITE``, ``BEYOND`` (``nan`` monitor for a non-finite state).
    """
    padded = -(-(system.n_rods * system.n_points) // compiled.LANES) * compiled.LANES
    with kernel_threads(system.n_threads) as n_threads:
        kernel = (
            np.full(1, float(system.epsilon)),
            np.full(1, EIGHT_PI * system.viscosity),
            bool(system.wall),
            compiled.tile_starts(padded, n_threads),
        )
        return _run(np.ascontiguousarray(x, dtype=float), float(t0), float(dt), int(n),
                    tableau_arrays(scheme), system.mechanics, kernel, padded, float(system.length),
                    float(limit), float(stop_above))
