"""What a solve reports: :class:`SolveInfo` on success, :class:`SolveError` otherwise."""

from __future__ import annotations

from dataclasses import dataclass

from ..core.contracts import StepFailure

#: The likely cause of a solve whose result is not finite.
OVERFLOW = ("loads, slip or background flow beyond what floating point holds (check their "
            "magnitudes and units)")


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


class SolveError(StepFailure):
    """A resistance or mobility solve that did not give a trustworthy answer: GMRES that did not
    converge, a singular / ill-conditioned system, or a result that is not finite or whose
    residual is beyond tolerance. The message says what to change; in a run's step it is a
    blow-up (:class:`~parastokes.core.contracts.StepFailure`)."""
