"""What a run reports to while it works: :class:`Reporter` (silent) and the protocol the
command line's console implements."""

from __future__ import annotations

from typing import Protocol


class ReporterLike(Protocol):
    """What :func:`execute` reports to: a :class:`Reporter`, or any object with its methods (the
    CLI's console)."""

    def note(self, text: str) -> None: ...

    def warn(self, text: str) -> None: ...

    def start(self, what: str, total: int) -> None: ...

    def expect(self, seconds: float) -> None: ...

    def advance(self) -> None: ...

    def finish(self) -> None: ...

    def iteration(self, k: int, increment: float, error: float | None, elapsed: float) -> None: ...


class Reporter:
    """Receives progress from :func:`execute`; this base class stays silent (see the CLI's)."""

    def note(self, text: str) -> None:
        """A line of information."""

    def warn(self, text: str) -> None:
        """A warning about the results (also in summary.json's warnings)."""

    def start(self, what: str, total: int) -> None:
        """A phase of ``total`` steps begins: ``"serial"`` slices or ``"parareal"`` iterations
        (those still to do: a resumed run counts only what is left)."""

    def expect(self, seconds: float) -> None:
        """An estimate of the wall time of one step of the current phase (for an ETA)."""

    def advance(self) -> None:
        """One step of the current phase is done."""

    def finish(self) -> None:
        """The current phase is over."""

    def iteration(self, k: int, increment: float, error: float | None, elapsed: float) -> None:
        """Iteration k of Parareal finished: η̃^k, η^k (None without reference), wall time so
        far."""
