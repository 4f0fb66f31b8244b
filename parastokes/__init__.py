"""parastokes: Parareal with extrapolated coarse solvers for elastic structures in Stokes flow.

Subpackages (import them as ``from parastokes import mrs, models, integrate, parareal, parallel``):

- :mod:`parastokes.mrs`: regularized Stokeslet kernels (free space and plane wall).
- :mod:`parastokes.models`: Kirchhoff rods and spring-network vesicles (public factories); each
  body kind lives in one folder of :mod:`parastokes.kinds`, what they share in
  :mod:`parastokes.bodies`.
- :mod:`parastokes.integrate`: explicit Runge-Kutta schemes and propagators.
- :mod:`parastokes.parareal`: Algorithm 1 of Liu & Rostami with extrapolated coarse solvers.
- :mod:`parastokes.parallel`: executors (serial, process pool, MPI).
"""

__version__ = "0.5.3"

#: Modules that moved into a folder, under the names the documentation of earlier rounds imported
#: them by (``from parastokes import io``): loaded on first use, each the module itself.
_MOVED = {"io": "parastokes.output.trajectory", "spatial": "parastokes.parallel.spatial"}


def __getattr__(name: str):
    """``parastokes.io`` and ``parastokes.spatial``: the modules of :data:`_MOVED`."""
    if name in _MOVED:
        import importlib

        return importlib.import_module(_MOVED[name])
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
