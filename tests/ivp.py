"""The Prothero-Robinson system of tests/test_stiff.py, its rate evaluations counted."""

from __future__ import annotations

import dataclasses

from test_stiff import Forced


@dataclasses.dataclass(frozen=True)
class Counted(Forced):
    """:class:`Forced` (y' = λ (y - sin t) + cos t, closed form ``exact``) whose ``calls[0]``
    counts the evaluations of the rates."""

    calls: list = dataclasses.field(default_factory=lambda: [0])

    def rates(self, t, x):
        self.calls[0] += 1
        return super().rates(t, x)
