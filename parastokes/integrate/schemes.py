"""The scheme registry: explicit Runge-Kutta tableaux (:class:`Scheme`), with their RKMK
commutator terms on rotating frames, and the linearly implicit schemes of
:mod:`parastokes.stiff`, all by name in :data:`SCHEMES` (the module docstring of
:mod:`parastokes.integrate` says how a tableau is applied)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import stiff
from ..stiff import Rosenbrock

__all__ = [
    "AUTO",
    "RK23",
    "RK45",
    "SCHEMES",
    "AnyScheme",
    "Auto",
    "Bracket",
    "Scheme",
    "embedded_pair",
    "explicit_scheme",
    "lookup",
    "real_stability_boundary",
    "rkmk_brackets",
    "scheme_order",
]

# A bracket term (coefficient, p, q) contributes coefficient * dt * bracket(k_p, k_q).
Bracket = tuple[float, int, int]


@dataclass(frozen=True)
class Scheme:
    """An explicit Runge-Kutta tableau with optional RKMK commutator corrections.

    ``a[i]`` holds the coefficients of stages ``0..i-1`` for stage ``i`` (``a[0] == ()``), ``b`` the
    final weights, ``c`` the stage times; ``stage_brackets[i]`` and ``final_brackets`` are the
    commutator terms ``(coefficient, p, q)`` described in the module docstring.
    """

    name: str
    order: int
    c: tuple[float, ...]
    a: tuple[tuple[float, ...], ...]
    b: tuple[float, ...]
    stage_brackets: tuple[tuple[Bracket, ...], ...]
    final_brackets: tuple[Bracket, ...] = ()
    #: The embedded solution's weights and brackets (an embedded pair: its error estimate).
    b_low: tuple[float, ...] | None = None
    low_brackets: tuple[Bracket, ...] = ()
    #: The embedded solution's order (None: no embedded solution).
    order_low: int | None = None

    #: Explicit: no linear solves (the schemes of :mod:`parastokes.stiff` say True).
    implicit = False

    @property
    def stages(self) -> int:
        return len(self.b)

    @property
    def adaptive(self) -> bool:
        """Whether the scheme has an error estimate (an embedded solution) for ``rtol``/``atol``."""
        return self.b_low is not None

    @property
    def fsal(self) -> bool:
        """First same as last: the last stage is evaluated at the step's result, so it is the
        first stage of the next step."""
        return (self.c[-1] == 1.0 and self.a[-1] == self.b[:-1] and self.b[-1] == 0.0
                and self.stage_brackets[-1] == self.final_brackets)


def rkmk_brackets(a: tuple[tuple[float, ...], ...], weights: tuple[float, ...]
                  ) -> tuple[Bracket, ...]:
    """The first-order RKMK commutator terms of the combination ``weights`` of the stages of the
    tableau ``a``: ``-1/2 Σ_j Σ_l w_j a_jl [k_l, k_j]``.

    RKMK advances by ``Σ_j w_j K_j`` with ``K_j = dexp⁻¹(Θ_j, k_j) = k_j - h/2 [Θ_j, k_j] +
    O(h³)`` and ``Θ_j = Σ_l a_jl K_l`` (Munthe-Kaas 1999; Hairer, Lubich & Wanner, *Geometric
    Numerical Integration*, IV.8): the series cut after one bracket keeps order 3 (a term of
    ``h^k`` brackets is ``O(h^(k+1))``), and writing ``K`` through the raw ``k`` changes the
    argument by ``O(h³)`` only. So a tableau of order >= 3 with these terms is of order 3 at
    least on rotating frames. That is all the theorem (cut after ``p - 2`` brackets) guarantees
    for Dormand-Prince, whose ``[Θ,[Θ,k]]/12`` term is left out; on the helix rod of the tests
    its fitted order is 5 all the same (tests/test_integrate_pairs.py; without these terms, 2).
    """
    return tuple((-0.5 * w * a[j][m], m, j) for j, w in enumerate(weights) if w != 0.0
                 for m in range(len(a[j])) if a[j][m] != 0.0)


def embedded_pair(name: str, order: int, c: tuple[float, ...],
                  a: tuple[tuple[float, ...], ...], b: tuple[float, ...],
                  b_low: tuple[float, ...]) -> Scheme:
    """An embedded pair of orders ``order`` and ``order - 1``, with the RKMK terms of
    :func:`rkmk_brackets` in every stage and in both solutions."""
    return Scheme(name, order, c=c, a=a, b=b,
                  stage_brackets=tuple(rkmk_brackets(a, row) for row in a),
                  final_brackets=rkmk_brackets(a, b), b_low=b_low,
                  low_brackets=rkmk_brackets(a, b_low), order_low=order - 1)


#: Bogacki & Shampine, Appl. Math. Lett. 2 (1989), 321-325: order 3 with an embedded order 2,
#: first same as last (three new evaluations a step); scipy's RK23.
RK23 = embedded_pair(
    "rk23", 3,
    c=(0.0, 1 / 2, 3 / 4, 1.0),
    a=((), (1 / 2,), (0.0, 3 / 4), (2 / 9, 1 / 3, 4 / 9)),
    b=(2 / 9, 1 / 3, 4 / 9, 0.0),
    b_low=(7 / 24, 1 / 4, 1 / 3, 1 / 8),
)

#: Dormand & Prince, J. Comput. Appl. Math. 6 (1980), 19-26 (DOPRI5): order 5 with an embedded
#: order 4, first same as last (six new evaluations a step); scipy's RK45. Order 3 on rotating
#: frames (:func:`rkmk_brackets`).
RK45 = embedded_pair(
    "rk45", 5,
    c=(0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0),
    a=(
        (),
        (1 / 5,),
        (3 / 40, 9 / 40),
        (44 / 45, -56 / 15, 32 / 9),
        (19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729),
        (9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656),
        (35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84),
    ),
    b=(35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84, 0.0),
    b_low=(5179 / 57600, 0.0, 7571 / 16695, 393 / 640, -92097 / 339200, 187 / 2100, 1 / 40),
)

#: A scheme of :data:`SCHEMES`: an explicit tableau or a linearly implicit one.
AnyScheme = Scheme | Rosenbrock

#: Every scheme by name; each says its ``order``, whether it is ``implicit`` and whether it is
#: ``adaptive`` (has an error estimate for ``rtol``/``atol``).
SCHEMES: dict[str, AnyScheme] = {
    "euler": Scheme("euler", 1, c=(0.0,), a=((),), b=(1.0,), stage_brackets=((),)),
    "rk2": Scheme(
        "rk2", 2, c=(0.0, 1.0), a=((), (1.0,)), b=(0.5, 0.5), stage_brackets=((), ())
    ),
    "rk4": Scheme(
        "rk4",
        4,
        c=(0.0, 0.5, 0.5, 1.0),
        a=((), (0.5,), (0.0, 0.5), (0.0, 0.0, 1.0)),
        b=(1 / 6, 1 / 3, 1 / 3, 1 / 6),
        stage_brackets=((), (), ((-1 / 8, 0, 1),), ()),
        final_brackets=((-1 / 12, 0, 3),),
    ),
    "rk23": RK23,
    "rk45": RK45,
    **stiff.ROSENBROCK,
}


@dataclass(frozen=True)
class Auto:
    """The scheme ``"auto"`` (:mod:`.auto`; :func:`lookup` knows it by name): adaptive steps
    only, so not an entry of :data:`SCHEMES`, whose schemes also take fixed steps (and which
    the checks of a system run on fixed steps); ``order``: the lowest of the schemes it runs,
    ``stages``: its explicit phase's (a rough cost)."""

    name: str = "auto"
    order: int = 2
    stages: int = 3
    implicit: bool = False
    adaptive: bool = True


#: The scheme ``"auto"``.
AUTO = Auto()


def lookup(scheme: str | AnyScheme | Auto) -> AnyScheme | Auto:
    """The scheme named ``scheme`` (an entry of :data:`SCHEMES`, or ``"auto"``; a scheme
    object passes through); ValueError naming the known ones."""
    if isinstance(scheme, Scheme | Rosenbrock | Auto):
        return scheme
    if scheme == AUTO.name:
        return AUTO
    try:
        return SCHEMES[scheme]
    except KeyError:
        raise ValueError(
            f"scheme: unknown scheme {scheme!r}; choose one of {sorted(SCHEMES)} or 'auto'"
        ) from None


def explicit_scheme(name: str | AnyScheme | Auto) -> Scheme:
    """The explicit tableau ``name`` (for the compiled and GPU loops, which run tableaux only);
    ValueError naming the scheme for an implicit one."""
    s = lookup(name)
    if not isinstance(s, Scheme):
        explicit = ", ".join(k for k, v in SCHEMES.items() if not v.implicit)
        raise ValueError(f"scheme: {name!r} is linearly implicit; the GPU and compiled loops run "
                         f"the explicit schemes only ({explicit})")
    return s


def scheme_order(name: str | AnyScheme | Auto) -> int:
    """Order of accuracy of the named scheme (used by Richardson extrapolation, eq. 26/27)."""
    return lookup(name).order


def real_stability_boundary(s: Scheme, resolution: float = 1e-4) -> float:
    """Where the stability function ``R(z) = 1 + Σ_k z^k bᵀA^(k-1)𝟙`` of the tableau first
    leaves the unit disc along the negative real axis (``-z``, to ``resolution``): the largest
    ``h|λ|`` of a stable step on a real negative eigenvalue ``λ`` (Hairer & Wanner, *Solving
    ODEs II*, IV.2: 2 for Euler and Heun, 2.51 for Bogacki-Shampine, 2.79 for RK4, 3.31 for
    Dormand-Prince); the first crossing found on a grid of ``resolution``, then bisected to
    round-off."""
    n = s.stages
    a = np.zeros((n, n))
    for i, row in enumerate(s.a):
        a[i, : len(row)] = row
    b = np.asarray(s.b)
    coefs, v = [1.0], np.ones(n)  # coefficients of z^0, z^1, ...: bᵀ A^(k-1) 𝟙
    for _ in range(n):
        coefs.append(float(b @ v))
        v = a @ v
    def unstable(y: np.ndarray | float) -> np.ndarray:
        return np.abs(np.polynomial.polynomial.polyval(-np.asarray(y), coefs)) > 1.0 + 1e-12

    y = np.arange(resolution, 10.0, resolution)
    hi = float(y[np.argmax(unstable(y))])
    lo = hi - resolution
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if unstable(mid) else (mid, hi)
    return lo


def fixed_step_scheme(scheme: str | AnyScheme | Auto) -> AnyScheme:
    """The scheme ``scheme`` (:func:`lookup`) for steps of a given size; ValueError for
    ``"auto"``, which takes adaptive steps only."""
    s = lookup(scheme)
    if isinstance(s, Auto):
        raise ValueError("scheme: 'auto' takes adaptive steps only; give rtol (and atol), or "
                         f"a scheme of fixed steps: one of {sorted(SCHEMES)}")
    return s
