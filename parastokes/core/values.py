"""Type checks of plain numbers given by users, shared by the input checks of the package.

A bool is an ``int`` to Python but never a count or a quantity here; numpy's scalars are numbers
(``numbers.Integral`` and ``numbers.Real`` include them).
"""

from __future__ import annotations

import numbers

__all__ = ["is_integer", "is_real"]


def is_integer(value: object, least: int | None = None) -> bool:
    """An integer (numpy's included), not a bool, and at least ``least`` when given."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        return False
    return least is None or int(value) >= least


def is_real(value: object) -> bool:
    """A real number (numpy's included), not a bool."""
    return not isinstance(value, bool) and isinstance(value, numbers.Real)
