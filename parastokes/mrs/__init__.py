"""The Method of Regularized Stokeslets: point forces and torques -> fluid velocity.

- :func:`velocity`: the public entry (free space, eq. 6, or above a plane wall; forces and torques;
  linear and angular velocity; batched systems).
- :mod:`parastokes.mrs.compiled`: the numba kernels behind it.
- :mod:`parastokes.mrs.reference`: the plain-numpy oracle the tests compare against.
"""

from . import reference
from .velocity import velocity

__all__ = ["reference", "velocity"]
