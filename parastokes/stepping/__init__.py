"""Many Runge-Kutta steps in one compiled call.

- :mod:`.registry`: which system types have a compiled loop (exact type, no inheritance);
- :mod:`.loop`: the generic loop (any :class:`parastokes.integrate.Scheme` tableau, the per-step
  checks) over four compiled parts that each system supplies for its own data type.

A body's compiled parts live with the body (e.g. :mod:`parastokes.kinds.rod.compiled`); its
system module registers its type here when imported. Importing this package loads only the
registry, so the loop never names a body.
"""

from . import registry

__all__ = ["registry"]
