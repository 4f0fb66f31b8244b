"""The HODMD-Parareal coarse solver (Liu, arXiv 2503.03109, section 3; docs/hodmd.md).

A coarse step on slice [T_{n-1}, T_n] from x runs two coarse solvers, on S equal snapshot intervals
of length h = (T_n − T_{n-1}) / S:

- G2, the cheap one, over the whole slice (S intervals; on a coarser grid it stays there and every
  snapshot is prolonged, eq. 33);
- G1, the accurate one, over the window of the first W = r_s S intervals only;

and keeps their difference D_j = G1(x)_j − G2(x)_j at the snapshots j = 0..W. That record, with
G2's end value, is the *trace* of the step (:class:`~parastokes.core.contracts.TracingCoarse`).

- Initial sweep (k = 0): X_n^0 = project(G2(x)_S + H[D](T_n)), H[·](t) the HODMD extrapolation of
  the window's snapshots to t (:func:`.dmd.hodmd`): G1's accuracy carried over the whole slice.
- Iteration k (the authors' correction, not eq. 11's G(X^k) − G(X^{k-1})):

      X_n^k = project(F(X_{n-1}^{k-1}) + [G2(x_new)_S − G2(x_old)_S] + H[D(x_new) − D(x_old)](T_n))

  with x_new = X_{n-1}^k, x_old = X_{n-1}^{k-1}: HODMD extrapolates the *difference of the
  corrections* G1 − G2 over the window, since the difference between two nearby starts is a smooth
  low-rank signal where D itself need not be.

HODMD runs on each group of three state columns separately (rods: X, D1, D2, D3 as the authors do;
vesicles, chains: the positions), so that positions and unit directors are truncated at their own
scales. The window may grow with k (``windows[k-1]`` in iteration k; the authors' r_s = 0.48,
0.52, 0.96): the trace of iteration k covers the windows of iterations k and k + 1, so that it can
serve as x_old in the next correction.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ...core.contracts import PropagatorLike, System
from ...mobility.threads import blas_threads
from ...parareal.dmd import hodmd
from ...parareal.extrapolation import Extrapolated
from ...parareal.transfer import OnCoarseGrid

__all__ = ["HodmdCoarse"]


def _groups(shape: tuple[int, ...]) -> list[slice]:
    """The column groups HODMD treats separately: blocks of three columns of a 2-D state whose
    width is a multiple of 3, else the whole state."""
    if len(shape) == 2 and shape[1] % 3 == 0 and shape[1] > 3:
        return [slice(c, c + 3) for c in range(0, shape[1], 3)]
    return [slice(None)]


@dataclass(frozen=True)
class HodmdCoarse:
    """The coarse solver of the module docstring; picklable when its parts are.

    ``g1``, ``g2``: the accurate and the cheap coarse propagators (any ``P(t0, t1, x)``; an
    :class:`~parastokes.parareal.OnCoarseGrid` G2 stays on its grid across snapshots);
    ``snapshots``: S; ``windows``: W per iteration (k >= 1 uses ``windows[min(k, len) - 1]``, the
    initial sweep ``windows[0]``); ``d``, ``svd_tolerance`` (ε1), ``amplitude_tolerance`` (ε): of
    :func:`.dmd.hodmd`; ``system``: for ``project``; ``initial``: None (the initial sweep of
    HODMD coarse steps) or (fraction, snapshots per slice, d) of the authors' global initial guess
    (:meth:`initial_guess`).
    """

    system: System
    g1: PropagatorLike
    g2: PropagatorLike
    snapshots: int
    windows: tuple[int, ...]
    d: int
    svd_tolerance: float = 1e-8
    amplitude_tolerance: float = 1e-8
    initial: tuple[float, int, int] | None = None

    def __post_init__(self) -> None:
        if not self.windows or min(self.windows) < self.d or max(self.windows) > self.snapshots:
            raise ValueError(
                f"every window must hold at least d + 1 = {self.d + 1} snapshots and lie in the "
                f"slice's {self.snapshots} intervals, got windows {self.windows}"
            )

    # ---- the trace ---------------------------------------------------------------------------
    def window(self, k: int) -> int:
        """W of the correction of iteration k (k = 0: the initial sweep)."""
        return window_of(self.windows, k)

    @property
    def width(self) -> int:
        """Rows of a trace: G2's end value, then D_0..D_{max W}."""
        return max(self.windows) + 2

    def trace(self, t_start: float, t_end: float, x: np.ndarray, k: int) -> np.ndarray:
        """The trace of the coarse step of iteration k from ``x`` (module docstring)."""
        h = (t_end - t_start) / self.snapshots
        last = traced_window(self.windows, k)
        g2 = trajectory(self.g2, t_start, h, self.snapshots, x)
        g1 = trajectory(self.g1, t_start, h, last, x)
        out = np.zeros((self.width, *np.shape(x)))
        out[0] = g2[-1]
        for j in range(last + 1):
            out[j + 1] = g1[j] - g2[j]
        return out

    # ---- the extrapolation -------------------------------------------------------------------
    def extrapolate(self, differences: np.ndarray, window: int, d: int | None = None,
                    at: float | None = None) -> np.ndarray:
        """H[·](T_n): the HODMD extrapolation (``d`` delayed copies, default ``self.d``) of the
        snapshots 0, ..., ``window`` of ``differences`` (rows 1.. of a trace, or a difference of
        two) to snapshot time ``at`` (default S, the end of the slice), group by group."""
        snaps = differences[: window + 1]
        out = np.zeros(snaps.shape[1:])
        target = float(self.snapshots if at is None else at)
        # the SVDs on one BLAS thread: the workers and kernels share the cores (a 1926 x 63 SVD
        # took 6.0 s instead of 0.04 s with OpenBLAS's own threads on a loaded machine)
        with blas_threads(1):
            for group in _groups(snaps.shape[1:]):
                index = (slice(None), slice(None), group) if snaps.ndim == 3 else (slice(None),)
                block = snaps[index]
                fit = hodmd(block.reshape(window + 1, -1).T, self.d if d is None else d,
                            svd_tolerance=self.svd_tolerance,
                            amplitude_tolerance=self.amplitude_tolerance)
                out[index[1:]] = fit.reconstruct(target).reshape(block.shape[1:])
        return out

    def initial_guess(self, times: np.ndarray, x0: np.ndarray) -> np.ndarray | None:
        """X^0 at every T_n at once, the authors' initial guess, when ``initial`` is given (else
        None: the engine's sweep of HODMD coarse steps). G1 runs from x0 over the first
        ``fraction`` of the slices and G2 over all of them, each in one run with
        ``per_slice`` snapshots per slice; HODMD (``d``) of G1 − G2 over G1's span extrapolates
        to the later slice ends: X_n^0 = project(G2_n + H(T_n)), and X_n^0 = G1_n where G1 ran.
        """
        if self.initial is None:
            return None
        fraction, per_slice, d = self.initial
        n_slices = len(times) - 1
        ran = min(n_slices, max(1, round(fraction * n_slices)))
        h = (times[1] - times[0]) / per_slice
        g1 = trajectory(self.g1, times[0], h, ran * per_slice, x0)
        g2 = trajectory(self.g2, times[0], h, n_slices * per_slice, x0)
        span = ran * per_slice
        difference = np.array(g1) - np.array(g2[: span + 1])
        states = np.empty((n_slices + 1, *np.shape(x0)))
        states[0] = x0
        for n in range(1, n_slices + 1):
            if n <= ran:
                states[n] = g1[n * per_slice]
            else:
                extra = self.extrapolate(difference, span, d, at=n * per_slice)
                states[n] = self.system.project(g2[n * per_slice] + extra)
        return states

    def end_state(self, t_start: float, t_end: float, trace: np.ndarray) -> np.ndarray:
        """X_n^0 = project(G2(x)_S + H[D](T_n)) (initial sweep)."""
        return self.system.project(trace[0] + self.extrapolate(trace[1:], self.window(0)))

    def correction(self, t_start: float, t_end: float, new: np.ndarray, old: np.ndarray,
                   k: int) -> np.ndarray:
        """G2(x_new)_S − G2(x_old)_S + H[D(x_new) − D(x_old)](T_n) (module docstring)."""
        return (new[0] - old[0]) + self.extrapolate(new[1:] - old[1:], self.window(k))

    def __call__(self, t_start: float, t_end: float, x: np.ndarray) -> np.ndarray:
        """The HODMD coarse propagator on its own: the initial sweep's step from ``x``."""
        return self.end_state(t_start, t_end, self.trace(t_start, t_end, x, 0))


def trajectory(propagator: PropagatorLike, t_start: float, h: float, count: int,
               x: np.ndarray) -> list[np.ndarray]:
    """The states of ``propagator`` from ``x`` at t_start + j h, j = 0, ..., ``count``, in one run:

    - on a coarser grid (:class:`OnCoarseGrid`) the run stays there, each snapshot prolonged;
    - an extrapolated solver (eq. 30) runs each auxiliary solver on through the snapshots, one
      after the other in the same task, and combines them at each one (weights of the steps
      taken per interval h), so its snapshot j is the combination of j h-long solves, as stable
      as the solver over a slice (a restart of the combination every h, with few steps per
      restart, is not: docs/validation.md);
    - any other propagator is called interval by interval.
    """
    x = np.asarray(x, dtype=float)
    if isinstance(propagator, OnCoarseGrid):
        coarse = trajectory(propagator.propagator, t_start, h, count,
                            propagator.transfer.restrict(x))
        return [propagator.transfer.prolong(y) for y in coarse]
    out = [x]
    if isinstance(propagator, Extrapolated):
        weights = propagator.coefficients(t_start, t_start + h)
        solvers = [p for row in propagator.auxiliary for p in row]
        states = [x] * len(solvers)
        for j in range(1, count + 1):
            t0, t1 = t_start + (j - 1) * h, t_start + j * h
            states = [p(t0, t1, y) for p, y in zip(solvers, states, strict=True)]
            out.append(propagator.combine(t_start, t1, x, weights, states))
        return out
    for j in range(1, count + 1):
        out.append(propagator(t_start + (j - 1) * h, t_start + j * h, out[-1]))
    return out


def window_of(windows: Sequence[int], k: int) -> int:
    """W of the correction of iteration k (k = 0: the initial sweep, as iteration 1)."""
    return windows[min(max(k, 1), len(windows)) - 1]


def traced_window(windows: Sequence[int], k: int) -> int:
    """The snapshots a trace of iteration k covers: its own window and the next iteration's."""
    return max(window_of(windows, k), window_of(windows, k + 1))


def as_windows(fractions: Sequence[float], snapshots: int) -> tuple[int, ...]:
    """W = round(r_s S) for each window fraction r_s."""
    return tuple(round(r * snapshots) for r in fractions)
