"""Linearly implicit (Rosenbrock-W) time stepping for stiff bodies (docs/stiff.md).

The stiffness of every body here is its elastic response through its local hydrodynamics: the
bending of a rod (a stable explicit step shrinking like Δs^3.8), the springs of a vesicle. The
schemes of :mod:`.schemes` solve one linear system ``(I - h γ A) k = r`` per stage, with ``A``
an approximation of the Jacobian of the rates in the rates' own coordinates (W-methods keep
their order for any ``A``; Hairer & Wanner, *Solving ODEs II*, section IV.7):

- :mod:`.coloring`: the Jacobian of a body's loads by coloured finite differences;
- :mod:`.local`: the regularized Stokeslet mobility restricted to near pairs (sparse);
- :mod:`.jacobian`: ``A`` of a system (its own ``stiff_jacobian``, else local mobility × load
  Jacobian, else zero);
- :mod:`.banded`: ``A = M K`` in one compiled pass straight into LAPACK's band layout (M never
  stored) or as a block product, and ``I - hγA`` in that layout;
- :mod:`.solve`: the stage solves (banded or sparse LU of ``I - hγA``, or GMRES on the exact
  Jacobian by finite differences of the rates, preconditioned by that LU);
- :mod:`.stepper`: a step of a scheme, and with its embedded solution (the adaptive steps'
  controller is :mod:`parastokes.integrate.controller`).
"""

from .jacobian import jacobian_check, local_jacobian
from .schemes import ROSENBROCK, Rosenbrock
from .solve import StiffSolveError
from .stepper import Stepper

__all__ = [
    "ROSENBROCK",
    "Rosenbrock",
    "Stepper",
    "StiffSolveError",
    "jacobian_check",
    "local_jacobian",
]
