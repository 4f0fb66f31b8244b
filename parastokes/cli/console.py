"""The console of a command: notes, the per-iteration table and progress bars (tqdm, on a
terminal, manager only); it is what a run reports to (:class:`parastokes.run.ReporterLike`)."""

from __future__ import annotations

import sys
import threading
import time

from .launch import is_manager

_TICK_SECONDS = 0.5


class Console:
    """Prints notes and the per-iteration table; draws tqdm bars on a terminal (manager only)."""

    def __init__(self, quiet: bool) -> None:
        self.quiet = quiet
        self.bars = not quiet and is_manager() and sys.stderr.isatty()
        self._bar = None
        self._times: list[float] = []  # start of the phase, then the end of every step
        self._expected: float | None = None
        self._ticking = threading.Event()

    def print(self, text: str = "") -> None:
        if self.quiet:
            return
        if self._bar is not None:
            self._bar.write(text)
        else:
            print(text, flush=True)

    # the interface of parastokes.run.Reporter
    def note(self, text: str) -> None:
        self.print(text)

    def warn(self, text: str) -> None:
        """A warning on standard error, even with ``--quiet`` (manager only)."""
        if is_manager():
            if self._bar is not None:
                self._bar.write(f"warning: {text}", file=sys.stderr)
            else:
                print(f"warning: {text}", file=sys.stderr, flush=True)

    def start(self, what: str, total: int) -> None:
        if what == "parareal":
            self.print(f"{'k':>3}  {'increment η̃^k':>14}  {'error η^k':>10}  {'elapsed [s]':>11}")
        else:
            self.print(f"serial fine run over {total} slices ...")
        self._times, self._expected = [time.monotonic()], None
        if self.bars:
            from tqdm import tqdm

            unit = "slice" if what == "serial" else "iteration"
            self._bar = tqdm(total=total, desc=what, unit=unit, leave=False, file=sys.stderr)
            self._ticking.clear()
            threading.Thread(target=self._tick, daemon=True).start()

    def expect(self, seconds: float) -> None:
        """An estimate of one step of the current phase, used until a step has been timed."""
        self._expected = seconds

    def progress(self, now: float) -> float:
        """Steps of the current phase done by ``now``, the running one counted by its elapsed
        time over the expected time of a step (the mean of those done, else the estimate), so
        that a bar moves, and gives an ETA, inside long slices; always below the next step."""
        done = len(self._times) - 1
        expected = (self._times[-1] - self._times[0]) / done if done else self._expected
        if not expected:
            return float(done)
        return done + min(0.99, (now - self._times[-1]) / expected)

    def _tick(self) -> None:
        while not self._ticking.wait(_TICK_SECONDS):
            bar = self._bar
            if bar is not None:
                bar.n = self.progress(time.monotonic())
                bar.refresh()

    def advance(self) -> None:
        self._times.append(time.monotonic())
        if self._bar is not None:
            self._bar.n = len(self._times) - 1
            self._bar.refresh()

    def finish(self) -> None:
        self._ticking.set()
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def iteration(self, k: int, increment: float, error: float | None, elapsed: float) -> None:
        err = "-" if error is None else f"{error:.3e}"
        self.print(f"{k:>3}  {increment:>14.3e}  {err:>10}  {elapsed:>11.2f}")
