"""The problem a configuration solves, as a serial baseline depends on it: the body with every
parameter, the interval and F (:func:`parastokes.parareal.best_serial.problem`), and its
fingerprint, which ``predict --serial``, the baseline cache of ``parastokes plan`` and the run's
speedup report compare."""

from __future__ import annotations

from typing import Any

from ..parareal import best_serial
from .schema import Config

__all__ = ["problem_key", "problem_of"]


def problem_of(cfg: Config) -> dict[str, Any]:
    """The problem of ``cfg``: its model section, [t0, t1] and [fine] (JSON values)."""
    return best_serial.problem(cfg.model.model_dump(mode="json", exclude_none=True),
                               cfg.time.t0, cfg.time.t1,
                               cfg.fine.model_dump(mode="json", exclude_none=True))


def problem_key(cfg: Config) -> str:
    """The fingerprint of :func:`problem_of` (equal for the same problem)."""
    return best_serial.fingerprint(problem_of(cfg))
