"""A finished run as flow input: its system rebuilt from the stored configuration, its saved frames
as full states.

``trajectory.h5`` stores, per frame, every body's positions and its node vectors (a rod's frames
``D1``-``D3`` with ``output.frames = true``, the default; a rigid body's quaternion and phase on
its centre), and as an attribute the resolved
configuration the run was made from (:mod:`parastokes.output.trajectory`). :func:`load_run` parses
that configuration again (:func:`parastokes.config.parse`), builds the system by its kind's section,
gets the layout of its state rows by the kind (the registry), and puts the saved columns back into
full states. A state whose columns were not saved (a rod run with ``output.frames = false``: no
frames, so no torques) is refused with what to change.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..core.files import CorruptFileError
from ..output import trajectory as io
from ..registry.kinds import BodyLayout

__all__ = ["RunFrames", "load_run"]

TRAJECTORY = "trajectory.h5"


def _drop_none(value: Any) -> Any:
    """The configuration without its None values (TOML has none: they are the defaults)."""
    if isinstance(value, dict):
        return {k: _drop_none(v) for k, v in value.items() if v is not None}
    if isinstance(value, list):
        return [_drop_none(v) for v in value]
    return value


def config_tables(stored: dict[str, Any]) -> dict[str, Any]:
    """The tables of a stored resolved configuration, as a configuration file would hold them
    (a scene's model as ``[scene]`` and ``[[bodies]]``; no ``resolved``)."""
    data = {k: v for k, v in _drop_none(stored).items() if k != "resolved"}
    model = data.get("model", {})
    if model.get("kind") == "scene":
        data.pop("model")
        data["scene"] = {k: model[k] for k in ("viscosity", "wall", "shear_rate")}
        data["bodies"] = [{"name": name, **body}
                          for name, body in zip(model["names"], model["bodies"], strict=True)]
    return data


@dataclass
class RunFrames:
    """A run's system, the layout of its state rows and its saved frames (``data``: what
    :func:`parastokes.output.trajectory.read_trajectory` returns)."""

    directory: Path
    system: Any
    layout: list[BodyLayout]
    data: dict[str, Any]

    @property
    def times(self) -> np.ndarray:
        return np.asarray(self.data["time"], dtype=float)

    @property
    def wall(self) -> bool:
        return bool(getattr(self.system, "wall", False))

    def state(self, index: int) -> np.ndarray:
        """The full state of frame ``index`` (its saved columns back in place)."""
        template = np.asarray(self.system.initial_state(), dtype=float)
        state = np.zeros_like(template)
        for body in self.layout:
            saved = self.data["bodies"][body.name]
            rows = slice(body.first, body.first + body.rows)
            state[rows, :3] = saved["positions"][index]
            for name, columns in body.vectors.items():
                state[rows, columns] = saved[name][index]
        return state

    def positions(self, index: int) -> np.ndarray:
        """All bodies' points of frame ``index`` (N, 3)."""
        return np.concatenate([self.data["bodies"][b.name]["positions"][index]
                               for b in self.layout])

    def frame(self, index: int | None = None, time: float | None = None) -> int:
        """The frame of ``index`` (negative from the end; default the last) or nearest to
        ``time``; ValueError naming the saved range otherwise."""
        times = self.times
        n = len(times)
        if time is not None:
            if not math.isfinite(time) or not (times[0] - 1e-9 * max(1, abs(times[0])) <= time
                                               <= times[-1] + 1e-9 * max(1, abs(times[-1]))):
                raise ValueError(f"--time {time:g}: outside the saved frames, t = {times[0]:g} .. "
                                 f"{times[-1]:g}; choose a time in that range")
            return int(np.argmin(np.abs(times - time)))
        index = -1 if index is None else index
        if not -n <= index < n:
            raise ValueError(f"--frame {index}: the run saved {n} frames; choose an index from 0 "
                             f"to {n - 1} (or -1 for the last)")
        return index % n


def _body_entries(body: Any) -> np.ndarray:
    """The entries of ``body``'s state that carry data: its ``state_entries()`` where it has
    one (a rigid body's surface rows are zero beyond their points), else all."""
    entries = getattr(body, "state_entries", None)
    if entries is not None:
        return np.asarray(entries(), dtype=bool)
    return np.ones(np.shape(body.initial_state()), dtype=bool)


def _needed(system: Any) -> np.ndarray:
    """The entries of the state that a rebuilt state needs from the trajectory (a scene: its
    bodies', not its padding)."""
    shapes, bodies = getattr(system, "shapes", None), getattr(system, "bodies", None)
    if shapes is None or bodies is None:
        return _body_entries(system)
    needed = np.zeros(np.shape(system.initial_state()), dtype=bool)
    for body, (first, rows, cols) in zip(bodies, shapes, strict=True):
        needed[first : first + rows, :cols] = _body_entries(body)
    return needed


def _check_datasets(path: Path, data: dict[str, Any], layout: list[BodyLayout]) -> None:
    """:class:`~parastokes.core.files.CorruptFileError` naming ``path`` and the datasets its run
    lacks of those the layout of its own configuration says it wrote (a body's frames ``D1``-
    ``D3``, a rigid body's ``orientation`` and ``phase``: a damaged or edited file)."""
    bodies = data["bodies"]
    lacking = [f"body {body.name!r} lacks its {', '.join(names)}" for body in layout
               if (names := [n for n in ("positions", *body.vectors)
                            if n not in bodies.get(body.name, {})])]
    if lacking:
        raise CorruptFileError(path, f"run {data['run']!r}: {'; '.join(lacking[:3])}",
                               "rerun the run that wrote it")


def _columns_saved(system: Any, layout: list[BodyLayout]) -> list[str]:
    """What the state needs that the trajectory does not hold (empty if it holds everything)."""
    needed = _needed(system)
    saved = np.zeros_like(needed)
    for body in layout:
        rows = slice(body.first, body.first + body.rows)
        saved[rows, :3] = True
        for columns in body.vectors.values():
            saved[rows, columns] = True
    return [body.name for body in layout
            if np.any(needed[body.first : body.first + body.rows]
                      & ~saved[body.first : body.first + body.rows])]


def load_run(directory: str | Path, run: str | None = None, threads: int = 1) -> RunFrames:
    """The run in ``directory`` (its ``trajectory.h5``): ``run`` is ``"parareal"`` or ``"serial"``
    (default: parareal when it was computed). ValueError naming what to change when the directory
    holds no trajectory or the trajectory lacks columns of the state."""
    from ..config import parse

    directory = Path(directory)
    path = directory / TRAJECTORY
    if not directory.is_dir():
        raise ValueError(f"{directory} is not a directory: give the output directory of a run")
    if not path.exists():
        raise ValueError(f"{directory} holds no {TRAJECTORY}: give the directory of a finished run "
                         "made with output.trajectory = true")
    data = io.read_trajectory(path, run)
    cfg = parse(config_tables(data["config"]), str(path))
    system = cfg.model.build(threads)
    layout = cfg.model.layout(system, cfg.output.frames, cfg.output.tracked_points)
    _check_datasets(path, data, layout)
    missing = _columns_saved(system, layout)
    if missing:
        raise ValueError(f"{path}: the frames of {', '.join(missing)} lack columns of the state "
                         "(a rod's frames D1-D3, which its torques need, or a rigid body's pose, "
                         "which trajectories written before it was saved lack); rerun with "
                         "output.frames = true")
    return RunFrames(directory, system, layout, data)
