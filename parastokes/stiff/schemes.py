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
- ``ros34pw2``: the four-stage Rosenbrock-W method ROS34PW2 of Rang & Angermann (BIT 45, 2005),
  γ = 0.4358665215084590, order 3 for any ``A`` (a W-method), embedded order 2, stiffly
  accurate, L-stable for the exact Jacobian. Its coefficients are those of the standard form
  (:func:`from_standard`) as PETSc's TSROSW lists them (``TSROSWRA34PW2`` in
  ``src/ts/impls/rosw/rosw.c``), converted to the form above. At order 3 the commutator terms
  of Munthe-Kaas enter on rotating frames: the stage rates are corrected by ``dexp⁻¹`` to first
  order (``f_i - h/2 [Σ_j a_ij k_j, f_i]``, the system's ``bracket``; :mod:`.stepper`).
- ``ros34pw2-krylov``: ROS34PW2 with the stage systems on the exact Jacobian, as
  ``ros2-krylov``: on a stiff rod the order of the W-methods with the local ``A`` falls to about
  1 at large steps, with the exact Jacobian it stays near 3 (docs/benchmarks.md, "Stiff bodies:
  cheaper implicit steps").
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

__all__ = ["ROS34PW2_STANDARD", "ROSENBROCK", "Rosenbrock", "from_standard", "refreshed_every"]


import numpy as np


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
    #: The steps ``h / h_f`` that a factorization of ``I - h_f γ A`` serves: it is that of
    #: ``I - hγ A'`` with ``A' = (h_f / h) A``, and a W-method keeps its order for any ``A'``;
    #: the range keeps one step on y' = λy with ``A' = (h_f / h) λ`` from amplifying any λ < 0
    #: (tested; ROS34PW2 amplifies from ``h = 1.67 h_f`` on, ROS2 not up to ``3 h_f``).
    reuse: tuple[float, float] = (0.5, 2.0)
    #: Steps between rebuilds of ``A`` in a run of this scheme (None: the stepper's default,
    #: :data:`.stepper.REFRESH`); :func:`refreshed_every` sets it (``coarse.jacobian_every``).
    refresh: int | None = None
    #: Take f_t with ``A`` and hold it until ``A`` is rebuilt (one rate evaluation less per
    #: step; the time column of the W-matrix, :mod:`.stepper`), instead of at every step.
    hold_time_derivative: bool = False

    #: Every scheme of this module solves linear systems (``integrate.SCHEMES`` says so).
    implicit = True

    @property
    def stages(self) -> int:
        return len(self.b)

    @property
    def adaptive(self) -> bool:
        """Whether the scheme has an error estimate (``b_low``) for adaptive steps."""
        return self.b_low is not None


def from_standard(name: str, order: int, alpha: list[list[float]], gamma: list[list[float]],
                  b: list[float], b_low: list[float], **kw: object) -> Rosenbrock:
    """A :class:`Rosenbrock` from the standard form of a Rosenbrock-W method (Hairer & Wanner,
    *Solving ODEs II*, IV.7, (7.4); PETSc's TSROSW): ``(I - hγ_ii A) K_i = h f(y + Σ α_ij K_j) +
    h A Σ_{j<i} γ_ij K_j + h² (Σ_j γ_ij) f_t``, ``y1 = y + Σ b_i K_i``, with one diagonal γ.

    With ``G = gamma`` (lower triangular) and our stage rates ``k_i = (G K)_i / (h γ)``:
    ``a = γ α G⁻¹``, ``d = -γ G⁻¹`` below the diagonal, ``b = γ b G⁻¹``, ``c`` the row sums of
    ``alpha`` and ``g`` those of ``G``."""
    alpha_, g_ = np.asarray(alpha, dtype=float), np.asarray(gamma, dtype=float)
    diagonal = float(g_[0, 0])
    if not np.allclose(np.diag(g_), diagonal) or np.any(np.triu(g_, 1)) or np.any(
            np.triu(alpha_)):
        raise ValueError(f"{name}: gamma must be lower triangular with one diagonal value and "
                         "alpha strictly lower triangular")
    inverse = np.linalg.inv(g_)
    a, d = diagonal * alpha_ @ inverse, -diagonal * inverse
    s = len(b)
    return Rosenbrock(
        name, order, diagonal, c=tuple(float(v) for v in alpha_.sum(axis=1)),
        a=tuple(tuple(float(v) for v in a[i, :i]) for i in range(s)),
        d=tuple(tuple(float(v) for v in d[i, :i]) for i in range(s)),
        b=tuple(float(v) for v in diagonal * np.asarray(b) @ inverse),
        b_low=tuple(float(v) for v in diagonal * np.asarray(b_low) @ inverse),
        g=tuple(float(v) for v in g_.sum(axis=1)), **kw)  # type: ignore[arg-type]


#: ROS34PW2 in the standard form, as PETSc's TSROSW lists it (TSROSWRA34PW2; Rang & Angermann,
#: BIT 45, 2005, Table 4.1).
ROS34PW2_STANDARD = dict(
    alpha=[[0, 0, 0, 0],
           [8.7173304301691801e-01, 0, 0, 0],
           [8.4457060015369423e-01, -1.1299064236484185e-01, 0, 0],
           [0, 0, 1.0, 0]],
    gamma=[[4.3586652150845900e-01, 0, 0, 0],
           [-8.7173304301691801e-01, 4.3586652150845900e-01, 0, 0],
           [-9.0338057013044082e-01, 5.4180672388095326e-02, 4.3586652150845900e-01, 0],
           [2.4212380706095346e-01, -1.2232505839045147e+00, 5.4526025533510214e-01,
            4.3586652150845900e-01]],
    b=[2.4212380706095346e-01, -1.2232505839045147e+00, 1.5452602553351020e+00,
       4.3586652150845900e-01],
    b_low=[3.7810903145819369e-01, -9.6042292212423178e-02, 5.0000000000000000e-01,
           2.1793326075422950e-01],
)

_GAMMA2 = 1.0 + 1.0 / math.sqrt(2.0)
_ROS2 = dict(order=2, gamma=_GAMMA2, c=(0.0, 1.0), a=((), (1.0,)), d=((), (-2.0,)),
             b=(1.5, 0.5), b_low=(1.0, 0.0), g=(_GAMMA2, -_GAMMA2))

#: The linearly implicit schemes, by name (joined into ``parastokes.integrate.SCHEMES``).
ROSENBROCK: dict[str, Rosenbrock] = {
    "lieuler": Rosenbrock("lieuler", 1, 1.0, c=(0.0,), a=((),), d=((),), b=(1.0,), g=(1.0,),
                          reuse=(0.5, 1.5)),
    "ros2": Rosenbrock("ros2", **_ROS2),  # type: ignore[arg-type]
    "ros2-krylov": Rosenbrock("ros2-krylov", krylov=True, **_ROS2),  # type: ignore[arg-type]
    "ros34pw2": from_standard("ros34pw2", 3, reuse=(0.5, 1.25),
                              **ROS34PW2_STANDARD),  # type: ignore[arg-type]
    "ros34pw2-krylov": from_standard("ros34pw2-krylov", 3, krylov=True, reuse=(0.5, 1.25),
                                     **ROS34PW2_STANDARD),  # type: ignore[arg-type]
}


def refreshed_every(scheme: Rosenbrock, steps: int | None, hold_time_derivative: bool = False
                    ) -> Rosenbrock:
    """``scheme`` whose runs rebuild ``A`` every ``steps`` steps (None: the stepper's default;
    ValueError below 1), with f_t held with ``A`` if ``hold_time_derivative``."""
    if steps is not None and (isinstance(steps, bool) or not isinstance(steps, int) or steps < 1):
        raise ValueError(f"jacobian_every: must be an integer >= 1, got {steps!r}")
    return dataclasses.replace(scheme, refresh=steps, hold_time_derivative=hold_time_derivative)
