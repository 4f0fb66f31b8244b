"""Rigid surfaces in Stokes flow: the resistance and mobility problems.

- :mod:`.rigid`: :class:`RigidSurface` (body-frame points, ε), :class:`PlacedSurface`,
  :func:`rigid_motion` (K [U, Ω] = U + Ω × (x - c));
- :mod:`.resistance`: :func:`solve_resistance`, :func:`resistance_matrix`;
- :mod:`.motion`: :func:`solve_mobility` (the augmented system of Khatri & Cortez);
- :mod:`.direct` (LU, reused body-frame factorization), :mod:`.krylov` (GMRES),
  :mod:`.precondition` (its preconditioner: body blocks swept with the couplings of near
  bodies), :mod:`.rigid_modes` (the resistance problem's coarse correction on the rigid
  modes), :mod:`.choice` (which one), :mod:`.selfsolve` (the factorizations),
  :mod:`.scaling` (the dimensionless system), :mod:`.system` (several bodies in one fluid);
- :mod:`.checks`: the input checks; :mod:`.errors`: :class:`SolveInfo`, :class:`SolveError`;
- :mod:`.sphere`, :mod:`.wall_series`, :mod:`.two_spheres`: sphere points, the exact wall
  corrections and the two-sphere series used by the validation.
"""

from .checks import check_surface
from .errors import SolveError, SolveInfo
from .motion import MobilityResult, solve_mobility
from .resistance import ResistanceResult, resistance_matrix, solve_resistance
from .rigid import PlacedSurface, RigidSurface, rigid_motion

__all__ = [
    "MobilityResult",
    "PlacedSurface",
    "ResistanceResult",
    "RigidSurface",
    "SolveError",
    "SolveInfo",
    "check_surface",
    "resistance_matrix",
    "rigid_motion",
    "solve_mobility",
    "solve_resistance",
]
