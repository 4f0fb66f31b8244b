"""The options of :func:`parastokes.parareal.run`, grouped as small frozen values.

- :class:`Stopping`: when the iteration stops (eta~^k of eq. 34 below ``tol``, ``max_iterations``,
  a wall-time limit);
- :class:`Checkpoint`: where the state is saved after every iteration, and whether an existing
  file is resumed;
- :class:`Reporting`: what is called after every iteration.

``run`` also takes each option as a flat keyword (``tol=``, ``max_iterations=``,
``wall_time_limit=``, ``checkpoint=PATH``, ``identity=``, ``on_iteration=``);
:func:`resolve` turns either form into the three values, the one place both schedules take them
from, and refuses an option given both ways.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from ..core.values import is_integer, is_real

if TYPE_CHECKING:
    from .algorithm import IterationReport

__all__ = ["Checkpoint", "Reporting", "Stopping", "resolve"]


@dataclass(frozen=True, kw_only=True)
class Stopping:
    """When Parareal stops; checked after every iteration k, in the order of the parameters
    (the tolerance, then k = N, then ``max_iterations``, then the wall time).

    Parameters
    ----------
    tol
        Stop once the relative increment eta~^k (eq. 34) is below ``tol`` (``"tolerance"``);
        0 never stops on it. Finite and >= 0.
    max_iterations
        Stop at k = ``max_iterations`` (``"max_iterations"``); None: no limit but k = N, where the
        iterate is the serial fine solution (``"all_slices"``, checked before ``max_iterations``).
    wall_time_limit
        Stop after the iteration during which this many seconds of the call have passed
        (``"wall_time"``); None: no limit. A later call with the same checkpoint continues.

    Raises
    ------
    ValueError
        On a value out of range, naming the field.
    """

    tol: float
    max_iterations: int | None = None
    wall_time_limit: float | None = None

    def __post_init__(self) -> None:
        if not (is_real(self.tol) and math.isfinite(self.tol) and self.tol >= 0.0):
            raise ValueError(f"tol must be finite and >= 0, got {self.tol!r}")
        if self.max_iterations is not None and not is_integer(self.max_iterations, 1):
            raise ValueError(
                f"max_iterations must be an integer >= 1 (or None), got {self.max_iterations!r}"
            )
        limit = self.wall_time_limit
        if limit is not None and not (is_real(limit) and limit > 0.0):
            raise ValueError(f"wall_time_limit must be positive (or None), got {limit!r}")


@dataclass(frozen=True)
class Checkpoint:
    """Where the state of a run is saved (atomically) after the initial sweep and every iteration.

    Parameters
    ----------
    path
        The ``.npz`` file (:mod:`parastokes.parareal.checkpoint`).
    identity
        JSON values by key, added to the checkpoint's fingerprint: a file whose entries differ is
        refused, naming them (:class:`~parastokes.parareal.checkpoint.CheckpointMismatch`).
    resume
        True: an existing file of the same problem is continued, bit for bit. False: the run
        starts afresh and replaces it.
    """

    path: str | os.PathLike
    identity: Mapping[str, Any] | None = None
    resume: bool = True

    def __post_init__(self) -> None:
        if not isinstance(self.path, str | os.PathLike):
            raise ValueError(f"Checkpoint path must be a file path, got {self.path!r}")
        if self.identity is None:
            return
        if not isinstance(self.identity, Mapping):
            raise ValueError(
                f"Checkpoint identity must be a mapping of names to JSON values, got "
                f"{self.identity!r}"
            )
        try:
            json.dumps(dict(self.identity))
        except (TypeError, ValueError) as exc:
            raise ValueError(
                f"Checkpoint identity must hold JSON values (str, int, float, bool, None, lists "
                f"and dicts of them; convert numpy scalars with .item()): {exc}"
            ) from exc


@dataclass(frozen=True)
class Reporting:
    """What :func:`~parastokes.parareal.run` reports besides its INFO log line per iteration.

    Parameters
    ----------
    on_iteration
        Called after every iteration, once its checkpoint is written, with an
        :class:`~parastokes.parareal.IterationReport` (live progress, per-iteration output).
    """

    on_iteration: Callable[[IterationReport], None] | None = None


def _refuse_both(group: str, flat: dict[str, Any]) -> None:
    given = [name for name, value in flat.items() if value is not None]
    if given:
        names = ", ".join(f"{name}=" for name in given)
        raise TypeError(
            f"run() got {names} and {group}= for the same option; give {group} options once: "
            f"inside {group}={group.capitalize()}(...) or as flat keywords without {group}="
        )


def resolve(
    *,
    tol: float | None,
    max_iterations: int | None,
    wall_time_limit: float | None,
    checkpoint: str | os.PathLike | Checkpoint | None,
    identity: Mapping[str, Any] | None,
    on_iteration: Callable[[IterationReport], None] | None,
    stopping: Stopping | None,
    reporting: Reporting | None,
) -> tuple[Stopping, Checkpoint | None, Reporting]:
    """The three option values of a ``run`` call given flat, grouped or mixed across groups.

    Raises
    ------
    TypeError
        When a group and one of its flat keywords are both given (naming both), when a group is
        not of its type, or when no tolerance is given at all.
    ValueError
        On an out-of-range value (:class:`Stopping`).
    """
    flat_stopping = {"tol": tol, "max_iterations": max_iterations,
                     "wall_time_limit": wall_time_limit}
    if stopping is not None:
        if not isinstance(stopping, Stopping):
            raise TypeError(f"stopping must be a parareal.Stopping, got {stopping!r}")
        _refuse_both("stopping", flat_stopping)
    elif tol is None:
        raise TypeError(
            "run() needs a stopping rule: tol=... (and max_iterations=...), or "
            "stopping=parareal.Stopping(tol=..., max_iterations=...)"
        )
    else:
        stopping = Stopping(
            tol=tol, max_iterations=max_iterations, wall_time_limit=wall_time_limit
        )
    if isinstance(checkpoint, Checkpoint):
        _refuse_both("checkpoint", {"identity": identity})
    elif checkpoint is not None:
        checkpoint = Checkpoint(checkpoint, identity)
    if reporting is not None:
        if not isinstance(reporting, Reporting):
            raise TypeError(f"reporting must be a parareal.Reporting, got {reporting!r}")
        _refuse_both("reporting", {"on_iteration": on_iteration})
    else:
        reporting = Reporting(on_iteration)
    return stopping, checkpoint, reporting
