"""The Method of Regularized Stokeslets: point forces and torques -> fluid velocity.

- :func:`velocity`: the public entry (free space, eq. 6, or above a plane wall; forces and torques;
  linear and angular velocity; batched systems).
- :mod:`parastokes.mrs.compiled`: the numba kernels behind it.
- :mod:`parastokes.mrs.reference`: the plain-numpy oracle the tests compare against.
- :class:`StokesletOperator` (:mod:`parastokes.mrs.operator`): the force -> velocity map as a
  linear operator, matrix-free or assembled (the rigid-body solves of :mod:`parastokes.mobility`).
"""

from . import reference
from .operator import StokesletOperator
from .velocity import velocity

__all__ = ["StokesletOperator", "reference", "velocity"]
