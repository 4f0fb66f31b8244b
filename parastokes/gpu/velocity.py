"""The batched GPU kernels on host arrays: :func:`velocity` (the GPU twin of ``mrs.velocity``)
and :class:`Evaluation` (inputs kept on the device, for repeated launches in benchmarks)."""

from __future__ import annotations

import numpy as np
from numba import cuda

from ..mrs.velocity import EIGHT_PI, validated
from . import device
from .kernels import DENOM, EPS, RUNNING, THETA, launch_shape, velocity_kernels
from .stepping import Launch

__all__ = ["Evaluation", "velocity"]


class Evaluation:
    """One batched kernel call with its inputs on the device: ``launch()`` runs it (asynchronously),
    ``result()`` waits and copies u (and w) back. Arrays are (B, M, 3) / (B, N, 3); ``epsilon``
    is (B,) (one per member) or (B, N) (one per source), ``mu`` (B,). The free-space force-only
    case runs the vesicle's kernel, every other case the full kernel (as ``mrs.velocity``
    chooses)."""

    def __init__(self, targets, sources, forces, torques, epsilon, mu, wall, launch=None):
        device.require()
        self.launch_shape = launch or Launch.default()
        nb, m = targets.shape[:2]
        self.fast = torques is None and not wall
        eps = np.asarray(epsilon, dtype=float)
        per_source = eps.ndim == 2
        mf = np.zeros((nb, THETA))
        mf[:, EPS] = 0.0 if per_source else eps  # (per source: the kernels read ``eps``)
        mf[:, DENOM] = EIGHT_PI * np.asarray(mu)
        self._args = [cuda.to_device(np.ascontiguousarray(a, dtype=float))
                      for a in (targets, sources, forces)]
        if not self.fast:
            n = np.zeros_like(sources) if torques is None else torques
            self._args.append(cuda.to_device(np.ascontiguousarray(n, dtype=float)))
        self._mf = cuda.to_device(mf)
        self._eps = cuda.to_device(np.ascontiguousarray(eps) if per_source else np.zeros((1, 1)))
        self._mi = cuda.to_device(np.full((nb, 3), RUNNING, dtype=np.int64))
        self._wall = bool(wall)
        self._out = cuda.device_array((nb, m, 3 if self.fast else 6))
        lau = self.launch_shape
        self._kernels = velocity_kernels(lau.tx, lau.sy, per_source)
        self._grid, self._block = launch_shape(nb, m, lau.tx, lau.sy)

    def launch(self) -> None:
        full, free_u_f = self._kernels
        if self.fast:
            free_u_f[self._grid, self._block](*self._args, self._mf, self._mi, 0.0, self._eps,
                                              self._out)
        else:
            full[self._grid, self._block](*self._args, self._mf, self._mi, self._wall, 0.0,
                                          self._eps, self._out)

    def result(self) -> tuple[np.ndarray, np.ndarray | None]:
        out = self._out.copy_to_host()
        return out[..., :3], None if self.fast else out[..., 3:]


def velocity(targets, sources, forces, *, epsilon, mu, torques=None, wall: bool = False,
             angular: bool = False, launch: Launch | None = None):
    """``mrs.velocity`` on the GPU, for (N, 3) or batched (B, N, 3) input with per-member ε (or
    one per source) and μ: the same arguments (validated the same way) and results to round-off
    (the torque blob is ψ, variant L, the default of ``mrs.velocity``). Returns u, or (u, w)
    with ``angular``."""
    targets, sources, forces, torques, eps, visc = validated(
        targets, sources, forces, torques, epsilon, mu, wall
    )
    batch = targets.shape[0] if targets.ndim == 3 else 0
    if not batch:
        targets, sources, forces = targets[None], sources[None], forces[None]
        torques = None if torques is None else torques[None]
    if angular and torques is None and not wall:
        torques = np.zeros_like(sources)  # w needs the full kernel
    evaluation = Evaluation(targets, sources, forces, torques, eps, visc, wall, launch)
    evaluation.launch()
    u, w = evaluation.result()
    if not batch:
        u = u[0]
        w = None if w is None else w[0]
    return (u, w) if angular else u
