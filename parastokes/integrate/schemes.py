"""The scheme registry: explicit Runge-Kutta tableaux (:class:`Scheme`), with their RKMK
commutator terms on rotating frames, and the linearly implicit schemes of
:mod:`parastokes.stiff`, all by name in :data:`SCHEMES` (the module docstring of
:mod:`parastokes.integrate` says how a tableau is applied)."""

from __future__ import annotations

from dataclasses import dataclass

from .. import stiff
from ..stiff import Rosenbrock

__all__ = ["SCHEMES", "AnyScheme", "Bracket", "Scheme", "explicit_scheme", "lookup",
           "scheme_order"]

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

    #: Explicit: no linear solves (the schemes of :mod:`parastokes.stiff` say True).
    implicit = False

    @property
    def stages(self) -> int:
        return len(self.b)


#: A scheme of :data:`SCHEMES`: an explicit tableau or a linearly implicit one.
AnyScheme = Scheme | Rosenbrock

#: Every scheme by name; each says its ``order`` and whether it is ``implicit``.
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
    **stiff.ROSENBROCK,
}


def lookup(scheme: str | AnyScheme) -> AnyScheme:
    """The scheme named ``scheme`` (a scheme object passes through); ValueError naming the
    known ones."""
    if isinstance(scheme, Scheme | Rosenbrock):
        return scheme
    try:
        return SCHEMES[scheme]
    except KeyError:
        raise ValueError(
            f"scheme: unknown scheme {scheme!r}; choose one of {sorted(SCHEMES)}"
        ) from None


def explicit_scheme(name: str) -> Scheme:
    """The explicit tableau ``name`` (for the compiled and GPU loops, which run tableaux only);
    ValueError naming the scheme for an implicit one."""
    s = lookup(name)
    if not isinstance(s, Scheme):
        explicit = ", ".join(k for k, v in SCHEMES.items() if not v.implicit)
        raise ValueError(f"scheme: {name!r} is linearly implicit; the GPU and compiled loops run "
                         f"the explicit schemes only ({explicit})")
    return s


def scheme_order(name: str) -> int:
    """Order of accuracy of the named scheme (used by Richardson extrapolation, eq. 26/27)."""
    return lookup(name).order
