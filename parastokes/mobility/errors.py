"""What a solve reports: :class:`SolveInfo` on success, :class:`SolveError` otherwise."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class SolveInfo:
    """How a resistance or mobility solve went.

    ``method``: ``"dense"`` (LU factorization) or ``"gmres"``; ``iterations``: GMRES iterations
    (0 for a direct solve); ``residual``: the relative residual ||b - A x|| / ||b|| of the
    (scaled, docs/design.md) linear system actually reached; ``reused``: whether a cached
    body-frame factorization was used.
    """

    method: str
    iterations: int
    residual: float
    reused: bool = False


class SolveError(RuntimeError):
    """A resistance or mobility solve that did not give a trustworthy answer: GMRES that did not
    converge, or a singular / ill-conditioned system. The message says what to change."""
