"""A propagator on a coarser spatial grid (Remark 4, eqs. 32-33).

A model plugs in its own grids through a ``transfer`` object with two methods:

- ``restrict(x_fine) -> x_coarse``: the map I_sigma^{sigma_c} of eq. 32 (fine grid to coarse grid);
- ``prolong(x_coarse) -> x_fine``: the map I_{sigma_c}^sigma of eq. 33 (coarse grid to fine grid),
  returning a valid fine-grid state (e.g. with re-orthonormalized frames).

Models expose them as ``system.coarsened(factor) -> (coarse_system, transfer)`` (rods: cubic splines
in arclength, ``parastokes/kinds/rod/transfer.py``).
"""

from __future__ import annotations

from concurrent.futures import Executor
from typing import Any, Protocol

import numpy as np

from ..core.contracts import PropagatorLike

__all__ = ["OnCoarseGrid", "Transfer", "take_step_counts"]


class Transfer(Protocol):
    """Grid transfer between a fine and a coarse discretization (eqs. 32-33)."""

    def restrict(self, x_fine: np.ndarray) -> np.ndarray: ...

    def prolong(self, x_coarse: np.ndarray) -> np.ndarray: ...


class OnCoarseGrid:
    """The propagator x -> prolong(G(t_start, t_end, restrict(x))) of eq. 33.

    ``propagator`` works on the coarse grid (a plain propagator or an extrapolated combinator, whose
    auxiliary solvers then all start from the same restricted state, eq. 32). Picklable when both
    parts are.
    """

    def __init__(self, propagator: PropagatorLike, transfer: Transfer) -> None:
        self.propagator = propagator
        self.transfer = transfer

    def __call__(self, t_start: float, t_end: float, x: np.ndarray) -> np.ndarray:
        coarse_end = self.propagator(t_start, t_end, self.transfer.restrict(x))
        return self.transfer.prolong(coarse_end)

    def split(self, t_start: float, t_end: float, x: np.ndarray):
        """The wrapped combinator's ``split`` on the restricted state, its combination prolonged
        (see :meth:`Extrapolated.split`); None when the wrapped propagator cannot be split."""
        split = getattr(self.propagator, "split", None)
        parts = None if split is None else split(t_start, t_end, self.transfer.restrict(x))
        if parts is None:
            return None
        tasks, combine = parts
        return tasks, lambda values: self.transfer.prolong(combine(values))

    @property
    def executor(self) -> Executor | None:
        """The executor of the wrapped combinator (None for a plain propagator)."""
        return getattr(self.propagator, "executor", None)

    def take_step_counts(self) -> dict[str, int] | None:
        """The wrapped combinator's adaptive step counts (:func:`take_step_counts`)."""
        return take_step_counts(self.propagator)

    def with_executor(self, executor: Executor) -> OnCoarseGrid:
        """A copy whose wrapped combinator runs its auxiliary solvers on ``executor``."""
        bind = getattr(self.propagator, "with_executor", None)
        return self if bind is None else OnCoarseGrid(bind(executor), self.transfer)


def take_step_counts(coarse: Any) -> dict[str, int] | None:
    """The steps ``{accepted, rejected, switches}`` taken by ``coarse``'s adaptive solves since
    the last call (then reset), or None for a coarse solver on fixed steps or one that does not
    count them (:meth:`parastokes.parareal.Extrapolated.take_step_counts`)."""
    take = getattr(coarse, "take_step_counts", None)
    return None if take is None else take()
