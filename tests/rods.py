"""Rods shared by the tests of the rod model and of the time stepping."""

from parastokes import models


def helix_rod(**kw):
    """A short free rod relaxing toward a helix: fully 3D frame dynamics (w changes direction).

    Keyword arguments override the defaults (e.g. ``preferred=(κ, 0, τ)``).
    """
    args = dict(
        n_points=21,
        length=4.0,
        epsilon=0.4,
        preferred=(1.0, 0.0, 0.5),
        wall=False,
        viscosity=1.0,
        shear=(10.0, 10.0, 10.0),
    )
    return models.rod(**(args | kw))
