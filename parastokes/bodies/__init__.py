"""Elastic bodies: Kirchhoff rods, spring-network vesicles, their geometry and grid transfer.

- :mod:`.rod`: discrete Kirchhoff rod mechanics (paper eqs. 10-12, 36), compiled.
- :mod:`.vesicle`: Hookean spring network on a triangulated surface (physics.md (14)), compiled.
- :mod:`.frames`: Rodrigues rotation of frames (eq. 13) and re-orthonormalization.
- :mod:`.geometry`: straight rods, icospheres, mesh edges and areas.
- :mod:`.rod_transfer`: cubic-spline restriction/prolongation between rod grids (Remark 4).
- :mod:`.reference`: plain-numpy oracles of the compiled functions (for tests).

The systems built from them live in :mod:`parastokes.system`; the public factories in
:mod:`parastokes.models`.
"""

from . import frames, geometry, reference, rod, rod_transfer, vesicle

__all__ = ["frames", "geometry", "reference", "rod", "rod_transfer", "vesicle"]
