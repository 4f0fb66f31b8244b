"""Many Runge-Kutta steps in one compiled call.

- :mod:`.registry`: which system types have a compiled loop (exact type, no inheritance);
- :mod:`.loop`: the generic loop (any :class:`parastokes.integrate.Scheme` tableau, the per-step
  checks) over four compiled parts that each system supplies for its own data type;
- :mod:`.rod`: the rod system's parts (mechanics, wall kernel, frame rotations, length monitor);
- :mod:`.vesicle`: the vesicle's parts (springs, free-space kernel, shear flow, area monitor).

Importing this package loads only the registry; a system module imports its parts and registers
its type (:mod:`parastokes.system`).
"""

from . import registry

__all__ = ["registry"]
