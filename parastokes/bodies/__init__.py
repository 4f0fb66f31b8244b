"""What every body kind builds on (the kinds themselves live in :mod:`parastokes.kinds`).

- :mod:`.base`: ``FluidBody`` (a body's fluid and compiled loop), ``PointsInShear`` (points moved
  by their forces in shear flow), ``replace_params``, ``require_positive``;
- :mod:`.frames`: Rodrigues rotation of frames (eq. 13) and re-orthonormalization;
- :mod:`.geometry`: straight rods, icospheres, mesh edges and areas;
- :mod:`.registry`: the body registry (how config, run, output and plots find a kind).
"""

from . import frames, geometry

__all__ = ["frames", "geometry"]
