"""Many Runge-Kutta steps in one compiled call (the systems' ``run_steps``).

- :mod:`.loop`: the generic loop (any :class:`parastokes.integrate.Scheme` tableau, the per-step
  checks) over four compiled parts that each system supplies for its own data type;
- :mod:`.rod`: the rod system's parts (mechanics, wall kernel, frame rotations, length monitor);
- :mod:`.vesicle`: the vesicle's parts (springs, free-space kernel, shear flow, area monitor).

Importing this package registers the parts of both systems.
"""

from . import loop, rod, vesicle

__all__ = ["loop", "rod", "vesicle"]
