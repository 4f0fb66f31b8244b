"""The MRS fluid inside compiled parts: the velocity of the loads at all points, as
:func:`parastokes.mrs.velocity` computes it.

:func:`velocity_into` packs the points as ``mrs.velocity`` pads them and calls the kernel
``mrs.velocity`` would call for the same flags: :func:`parastokes.mrs.compiled.free_u_f` for
forces in free space, else :func:`parastokes.mrs.compiled.full` (with the wall, when angular
velocities are wanted, or when a body whose rates have no w exerts torques; zero torques where
a body has none, as ``mrs.velocity`` passes them). So a
compiled loop that uses it gives the bits of a Python ``rates`` that calls ``mrs.velocity``
(or :class:`parastokes.fluid.MRS`) with the same loads. ε is one per system, (1,), or one per
source, (1, N) (a scene: every body's points with their body's ε).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..mrs import compiled

__all__ = ["fluid_workspace", "pack_points", "velocity_into"]

_OPTS = dict(cache=True, error_model="numpy")


@njit(**_OPTS)
def pack_points(x, targets, sources):
    """The positions ``x[:, :3]`` as ``mrs.velocity`` hands them to the kernels: ``targets``
    (3, 1, padded), padded by repeating the last point, and ``sources`` (1, n, 3)."""
    n = x.shape[0]
    for i in range(targets.shape[2]):
        src = min(i, n - 1)
        for j in range(3):
            targets[j, 0, i] = x[src, j]
    for i in range(n):
        for j in range(3):
            sources[0, i, j] = x[i, j]


@njit(**_OPTS)
def fluid_workspace(n, padded):
    """Scratch for :func:`velocity_into` of ``n`` points, ``padded`` targets: ``(targets
    (3, 1, padded), sources, forces, torques, u, w)``, the last five (1, n, 3); forces and
    torques start at zero (rows that no body writes stay zero)."""
    return (np.empty((3, 1, padded)), np.empty((1, n, 3)), np.zeros((1, n, 3)),
            np.zeros((1, n, 3)), np.empty((1, n, 3)), np.empty((1, n, 3)))


@njit(**_OPTS)
def _any_set(a):
    """Whether any entry of the 3-d ``a`` is non-zero (a scan that stops at the first, with no
    temporary array)."""
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            for k in range(a.shape[2]):
                if a[i, j, k] != 0.0:
                    return True
    return False


@njit(**_OPTS)
def velocity_into(x, work, eps, denom, starts, wall, angular, phi):
    """u (and w, with ``wall`` or ``angular``) at the points ``x[:, :3]`` from the forces and
    torques in ``work`` (:func:`fluid_workspace`), into its ``u`` and ``w``; arguments of the
    kernels as :func:`parastokes.mrs.compiled.full` takes them."""
    tp, s3, f, tq, u, w = work
    pack_points(x, tp, s3)
    if wall or angular or _any_set(tq):  # torques of a body whose rates have no w too
        compiled.full(tp, s3, f, tq, eps, wall, phi, denom, starts, u, w)
    else:
        compiled.free_u_f(tp, s3, f, eps, denom, starts, u)
