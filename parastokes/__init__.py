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

__version__ = "0.1.0"
