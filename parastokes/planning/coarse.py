"""The coarse solver of ``plan``'s Parareal routes: where ``tune`` looks first, on what pilot,
and the cost ratio α = γ_G/γ_F each route rests on (docs/planning.md, "Round 5, fourth session").

- **Leading candidates.** Where ``plan`` adds the implicit coarse scheme (F near its stability
  limit), the plain implicit solver at a ladder of fractions of the pilot's safe step,
  :data:`IMPLICIT_FRACTIONS`, is searched before every other candidate (``Space.leading``):
  the frontier's winners (docs/benchmarks.md, "The target table") are plain ``ros34pw2`` at
  0.15-0.3 of the safe step, which an order by the explicit cost model reached late or never.
- **The pilot's size.** A rod's pilot is the full problem where F over the pilot window costs at
  most :data:`FULL_PILOT_SHARE` of tune's budget (:func:`full_pilot`); otherwise the shortened
  rod of ``tuning.command.PILOT_POINTS`` nodes.
- **α on the full problem.** A shortened pilot's γ_G/γ_F does not carry to the full rod for an
  implicit G (its banded linear algebra is a larger share of a short rod's step): each accepted
  candidate's α is measured again on the full problem (:func:`full_alpha`), G and F run from
  the initial state over a few of their steps, in this process, one after the other; the
  routes rank the candidates by that α and the pilot's K (:func:`ranked`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["ALPHA_SECONDS", "ALPHA_STEPS", "FULL_PILOT_SHARE", "IMPLICIT_FRACTIONS", "Coarse",
           "confirmed", "cpu_per_time", "full_alpha", "full_pilot", "leading", "ranked"]

#: Fractions of the pilot's safe step of the plain implicit coarse solver searched first: the
#: space's own 1 and 0.6, and the frontier's winners (the rod of 601 points: 1.25e-4 s, 0.18 of
#: the 61-point pilot's safe 6.94e-4; Table 5: 1.25e-3 s, 0.3 of its safe 4.2e-3).
IMPLICIT_FRACTIONS = (1.0, 0.6, 0.3, 0.15)

#: The pilot is the full problem where F over the pilot window takes at most this share of
#: tune's budget: the baseline (its step-limit bisection and ρ(DG), some 25 fine slices) and
#: the ladder (each about 3 fine slices and its ρ(DG)) need some 25 windows, and a given budget
#: is wall time on a shared machine (a third of a core at the loads of docs/planning.md).
FULL_PILOT_SHARE = 0.01

#: α on the full problem: G and F each first run over this many of their own steps ...
ALPHA_STEPS = 20
#: ... and the span is doubled until the run takes this much CPU (or covers a slice).
ALPHA_SECONDS = 0.2


def leading(scheme: str) -> tuple[Any, ...]:
    """The plain ``scheme`` at each of :data:`IMPLICIT_FRACTIONS` of the safe step."""
    from ..tuning import Settings

    return tuple(Settings(scheme, step_fraction=f) for f in IMPLICIT_FRACTIONS)


def full_pilot(fine_cpu: float, n_slices: int, pilot_slices: int, budget: float) -> bool:
    """Whether tune's pilot can be the full problem: F over ``pilot_slices`` of the run's
    ``n_slices`` slices (``fine_cpu`` its CPU over the whole interval) costs at most
    :data:`FULL_PILOT_SHARE` of ``budget``."""
    return fine_cpu * pilot_slices / n_slices <= FULL_PILOT_SHARE * budget


def cpu_per_time(propagate: Callable[[float, float, np.ndarray], Any], x0: np.ndarray,
                 t0: float, step: float, longest: float,
                 clock: Callable[[], float] = time.process_time,
                 whole: bool = False) -> tuple[float, float]:
    """(CPU seconds per unit of simulated time, span measured) of ``propagate`` from ``(t0,
    x0)``: :data:`ALPHA_STEPS` steps of ``step`` once untimed (its loops loaded; as many steps
    as the timed run's first, so that Richardson's auxiliary steps r^q τ round to distinct
    counts there too), then timed, the span doubled until the run takes :data:`ALPHA_SECONDS`
    or reaches ``longest``; ``whole``: timed over ``longest`` at once."""
    steps = ALPHA_STEPS
    propagate(t0, t0 + min(longest, steps * step), x0)
    if whole:
        steps = math.ceil(longest / step)
    while True:
        span = min(longest, steps * step)
        start = clock()
        propagate(t0, t0 + span, x0)
        seconds = clock() - start
        if seconds >= ALPHA_SECONDS or span >= longest:
            return seconds / span, span
        steps *= 2


def full_alpha(settings: Any, system: Any, fine: Any, x0: np.ndarray, t0: float,
               slice_length: float, cores: int,
               clock: Callable[[], float] = time.process_time,
               whole: bool = False) -> tuple[float, dict[str, float]]:
    """γ_G/γ_F of the coarse solver ``settings`` on the full ``system`` against the fine
    propagator ``fine`` (eq. 14's α): both CPU rates of :func:`cpu_per_time` times the slice,
    G's N_G auxiliary solvers in waves on ``cores`` workers as tune counts them
    (``tuning.cost.gamma_ratio``); with the spans measured. ``whole``: G over a whole slice
    (its stability over a slice of the full problem checked too; a blow-up raises)."""
    from ..tuning import cost

    g_rate, g_span = cpu_per_time(settings.build(system), x0, t0, settings.dt, slice_length,
                                  clock, whole)
    f_rate, f_span = cpu_per_time(fine, x0, t0, fine.dt, slice_length, clock)
    alpha = cost.gamma_ratio(settings, slice_length, g_rate * slice_length,
                             f_rate * slice_length, cores)
    return alpha, {"coarse_span": g_span, "fine_span": f_span,
                   "coarse_cpu_per_time": g_rate, "fine_cpu_per_time": f_rate}


@dataclass
class Coarse:
    """One coarse solver accepted by tune, with the α and K the routes use and what they rest
    on."""

    candidate: Any  # tune's Candidate (settings, pilot η^k, the pilot's γ_G/γ_F)
    alpha: float | None  # None: not usable (alpha_source says why)
    alpha_source: str
    iterations: int
    measured: dict[str, float] | None = None  # full_alpha's spans and rates

    @property
    def settings(self) -> Any:
        return self.candidate.settings

    def as_dict(self) -> dict[str, Any]:
        c = self.candidate
        return {"label": c.settings.label(), "dt": c.settings.coarse_dt, "alpha": self.alpha,
                "alpha_source": self.alpha_source, "pilot_alpha": c.gamma_ratio,
                "iterations": self.iterations, "pilot_eta": c.pilot_errors,
                "full_problem": self.measured}


def _order(wall: Callable[[float, int], float]) -> Callable[[Coarse], tuple[bool, float]]:
    """The ranking's key: usable rows first, by ``wall(α, K)``."""
    return lambda row: (row.alpha is None,
                        0.0 if row.alpha is None else wall(row.alpha, row.iterations))


def ranked(accepted: Sequence[Any],
           alpha_of: Callable[[Any], tuple[float | None, str, Any]],
           wall: Callable[[float, int], float]) -> list[Coarse]:
    """The accepted candidates as :class:`Coarse`, α from ``alpha_of(candidate)`` = (α, where
    from, measurements), K tune's (the pilot's η^k scaled to the run's slices), ordered by
    ``wall(α, K)`` (the least first; ties in tune's order); those without an α (None: it blew
    up on the full problem, the source says so) last."""
    rows = []
    for cand in accepted:
        alpha, source, measured = alpha_of(cand)
        rows.append(Coarse(cand, alpha, source, cand.iterations, measured))
    return sorted(rows, key=_order(wall))


def confirmed(rows: list[Coarse], again: Callable[[Coarse], tuple[float | None, str, Any]],
              wall: Callable[[float, int], float]) -> list[Coarse]:
    """The ranking once its first row has been measured ``again`` (its G over a whole slice of
    the full problem: (α, where from, measurements), α None where it blew up), repeated until
    the first row is one so measured or none is usable; each row at most once."""
    done: set[int] = set()
    while rows and rows[0].alpha is not None and id(rows[0]) not in done:
        top = rows[0]
        done.add(id(top))
        top.alpha, top.alpha_source, top.measured = again(top)
        rows = sorted(rows, key=_order(wall))
    return rows
