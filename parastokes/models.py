"""Public factories of the paper's model problems (fixed names, design.md), defaults = the paper's.

- :func:`rod_swimmer`: rod-like swimmers above a wall (section 5.1, Table 2, eq. 36).
- :func:`rod`: a general Kirchhoff rod (constant preferred strain, e.g. (κ, 0, τ) for a helix or 0
  for a straight rod at rest; free space or above the wall).
- :func:`vesicle`: the elastic sphere in shear flow (section 5.2), of any radius.

Each lives with its body (:mod:`parastokes.kinds.rod.system`,
:mod:`parastokes.kinds.vesicle.system`); this module is their public address, with the system
classes they return.
"""

from __future__ import annotations

from .kinds.rod.system import TABLE2, RodSystem, rod, rod_swimmer
from .kinds.vesicle.system import VesicleSystem, vesicle

__all__ = ["TABLE2", "RodSystem", "VesicleSystem", "rod", "rod_swimmer", "vesicle"]
