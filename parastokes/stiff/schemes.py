"""The linearly implicit schemes: Rosenbrock-W tableaux in the rates' own coordinates.

A stage ``i`` of a scheme solves

    (I - h γ A) k_i = rates(t + c_i h, advance(x, Σ_j a_ij k_j, h)) + Σ_j d_ij k_j,

and the step ends with ``advance(x, Σ_i b_i k_i, h)``; ``b_low`` gives an embedded solution of
one order less, whose difference is the error estimate of the adaptive steps. ``A`` is any
approximation of the Jacobian of the rates (a W-method: the order holds for every ``A``; Hairer &
Wanner, *Solving ODEs II*, section IV.7); with ``A = 0`` linearly implicit Euler is forward Euler
and ROS2 is Heun's RK2. On rotating frames (``advance`` rotates, rates carry angular velocities)
the commutator terms of Runge-Kutta-Munthe-Kaas enter at order 3 only, as for RK2
(:mod:`parastokes.integrate`), so both schemes keep their order there.

- ``lieuler``: linearly implicit Euler, order 1, L-stable for the exact Jacobian.
- ``ros2``: the two-stage Rosenbrock-W method of Verwer, Spee, Blom & Hundsdorfer (SIAM J. Sci.
  Comput. 20, 1999), γ = 1 + 1/√2, order 2 for any ``A``, L-stable for the exact one; the
  embedded first-order solution is ``advance(x, k_1, h)``.
- ``ros2-krylov``: ROS2 whose stage systems use the exact Jacobian of the rates, applied
  matrix-free by finite differences of the rates and solved by GMRES preconditioned by the
  local ``A`` (:mod:`.solve`): the nonlocal flow enters the solve.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["ROSENBROCK", "Rosenbrock"]


@dataclass(frozen=True)
class Rosenbrock:
    """A Rosenbrock-W tableau (see the module docstring); ``krylov``: stage solves on the exact
    Jacobian by GMRES (else on the approximate ``A`` by sparse LU)."""

    name: str
    order: int
    gamma: float
    c: tuple[float, ...]
    a: tuple[tuple[float, ...], ...]
    d: tuple[tuple[float, ...], ...]
    b: tuple[float, ...]
    b_low: tuple[float, ...] | None = None
    krylov: bool = False
    #: Coefficients of ``h f_t`` in the stages' right-hand sides (f_t: the rates' derivative in
    #: time at the step's start, the time column of the Jacobian of the autonomous form).
    g: tuple[float, ...] = ()

    #: Every scheme of this module solves linear systems (``integrate.SCHEMES`` says so).
    implicit = True

    @property
    def stages(self) -> int:
        return len(self.b)

    @property
    def adaptive(self) -> bool:
        """Whether the scheme has an error estimate (``b_low``) for adaptive steps."""
        return self.b_low is not None


_GAMMA2 = 1.0 + 1.0 / math.sqrt(2.0)
_ROS2 = dict(order=2, gamma=_GAMMA2, c=(0.0, 1.0), a=((), (1.0,)), d=((), (-2.0,)),
             b=(1.5, 0.5), b_low=(1.0, 0.0), g=(_GAMMA2, -_GAMMA2))

#: The linearly implicit schemes, by name (joined into ``parastokes.integrate.SCHEMES``).
ROSENBROCK: dict[str, Rosenbrock] = {
    "lieuler": Rosenbrock("lieuler", 1, 1.0, c=(0.0,), a=((),), d=((),), b=(1.0,), g=(1.0,)),
    "ros2": Rosenbrock("ros2", **_ROS2),  # type: ignore[arg-type]
    "ros2-krylov": Rosenbrock("ros2-krylov", krylov=True, **_ROS2),  # type: ignore[arg-type]
}
