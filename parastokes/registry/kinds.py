"""The body registry: how config, run, output and plots find a kind of body (docs/extending.md).

A *body kind* is one :class:`BodyKind` value: its config section (a :class:`BodySection`, which
resolves its own units and defaults and builds the system), the parameter names Θ that Lagrangian
extrapolation may vary, the output :class:`BodyLayout` of its state (fields, topology) and its
drawing. Config, run, output and plots ask the registry and never name a kind.

A kind is found by its ``kind`` string (:mod:`parastokes.core.plugins`): a built-in name
(:data:`BUILTIN`: ``"rod"``, ``"vesicle"``, ``"chain"``, one line each), ``"package.module:Name"``
(``Name`` a :class:`BodyKind` or a system class, a frozen dataclass whose kind
:func:`derived_kind` makes from its fields) or an entry point of the group ``parastokes.bodies``.
Modules are imported only when a kind is asked for, so this module imports no body.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import cache
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, create_model

from ..core import plugins
from ..core.contracts import System

__all__ = [
    "BUILTIN",
    "ENTRY_POINT_GROUP",
    "RESERVED_NAMES",
    "BodyKind",
    "BodyLayout",
    "BodyResolution",
    "BodySection",
    "PlannedSize",
    "Positive",
    "UnknownKindError",
    "axis_stretch",
    "derived_kind",
    "draw_over_time",
    "get",
    "kinds",
    "point_layout",
    "polyline",
]

#: The package's own kinds: name -> ``"module:attribute"`` of their :class:`BodyKind`.
BUILTIN: dict[str, str] = {
    "rod": "parastokes.kinds.rod.kind:KIND",
    "vesicle": "parastokes.kinds.vesicle.kind:KIND",
    "chain": "parastokes.kinds.chain:KIND",
    "rigid": "parastokes.kinds.rigid.kind:RIGID",
    "squirmer": "parastokes.kinds.rigid.kind:SQUIRMER",
    "bacterium": "parastokes.kinds.rigid.kind:BACTERIUM",
}

#: The entry point group of installed body packages: ``name = "package.module:Name"``.
ENTRY_POINT_GROUP = "parastokes.bodies"


#: Names a body's layout may not take: they sit beside the bodies' groups in a run's group of
#: ``trajectory.h5`` (:class:`parastokes.output.trajectory.TrajectoryWriter`).
RESERVED_NAMES = ("time",)

#: ``output.tracked_points``: point indices of one body, or by body name in a scene.
Tracked = Sequence[int] | Mapping[str, Sequence[int]] | None

#: A finite number > 0 (for config fields).
Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]


class UnknownKindError(ValueError):
    """A ``kind`` that names no registered, importable or installed body."""


@dataclass(frozen=True)
class PlannedSize:
    """A body's size from its keys alone, before anything is built (the memory check of
    ``check`` and of every run): ``rows`` of its state, ``dense_bytes`` of the dense matrices its
    solves factorize and keep (a rigid surface of N points: its (3N)² matrix and LU factors; 0
    for none), and the ``keys`` that set them (named by the check's message)."""

    rows: int
    dense_bytes: float = 0.0
    keys: str = "n_points"


@dataclass(frozen=True)
class BodyResolution:
    """What a body section resolves to, in absolute units.

    ``theta0``: the parameters Θ⁰ by name (absolute ε⁰ among them); ``n_points``: rows of the
    state; ``grid_spacing`` and ``grid_unit``: the length that ε may be given in units of (rods:
    σ_f, ``"sigma_f"``; vesicles: l_max, ``"l_max"``; ``None`` when the kind has none).
    """

    theta0: dict[str, float]
    n_points: int
    grid_spacing: float = float("nan")
    grid_unit: str | None = None


class BodySection(BaseModel):
    """The base of every body's config section (``[model]``): ``kind`` plus the body's own keys.

    Subclasses set ``kind`` to a ``Literal`` of their name and implement :meth:`resolve` and
    :meth:`build`; a kind with a coarser grid (Remark 4) overrides :meth:`coarse_points`.
    """

    model_config = ConfigDict(extra="forbid", strict=True, validate_default=True)

    kind: str = Field(description="The body kind.")

    def resolve(self) -> BodyResolution:
        """Θ⁰ in absolute units, the number of state rows and the grid length of ε's unit."""
        raise NotImplementedError

    def build(self, threads: int = 1) -> System:
        """The system of this section with Θ⁰, its kernels on ``threads`` threads."""
        raise NotImplementedError

    def planned_size(self) -> PlannedSize | None:
        """The size of this body from its keys alone, for a kind whose :meth:`resolve` builds
        the body (so that too large a body is refused before it is allocated); None (the
        default) when :meth:`resolve` builds nothing large and its rows are the size."""
        return None

    def coarse_points(self, factor: int) -> int:
        """State rows on the grid ``factor`` times coarser; ValueError naming why not."""
        raise ValueError(f"the {self.kind!r} kind has no coarser grid; use 1")

    def parameter_units(self, name: str) -> tuple[str, dict[str, float]]:
        """The unit Lagrange nodes of parameter ``name`` default to (ε: the section's
        ``epsilon_unit``; others: ``"absolute"``), and the grid-length units ε may also be given
        in (name -> length)."""
        if name != "epsilon":
            return "absolute", {}
        body = self.resolve()
        grid = {body.grid_unit: body.grid_spacing} if body.grid_unit is not None else {}
        return getattr(self, "epsilon_unit", "absolute"), grid

    def tables(self) -> dict[str, Any]:
        """The configuration tables this section is written as (``{"model": {...}}``)."""
        return {"model": self.model_dump(mode="json", exclude_none=True)}

    def tracks_points(self) -> bool:
        """Whether ``output.tracked_points`` applies (its kind's ``tracks_points``)."""
        return get(self.kind).tracks_points

    def tracked_issues(self, tracked: Tracked, n_points: int) -> list[str]:
        """What is wrong with ``output.tracked_points = tracked`` for this body of ``n_points``
        rows (empty if nothing): a list of point indices, for a kind that marks points."""
        if isinstance(tracked, Mapping):
            return ["a table by body name is for scenes ([[bodies]]); give a list of point "
                    "indices, e.g. [0, 5]"]
        if tracked and not self.tracks_points():
            return [f"a {self.kind} model marks no points (vesicles only)"]
        if tracked and max(tracked) >= n_points:
            return [f"indices must be below {n_points}, got {max(tracked)}"]
        return []

    def layout(self, system: System, frames: bool, tracked: Tracked) -> list[BodyLayout]:
        """The output layout of ``system`` built from this section (its kind's ``layout``)."""
        if isinstance(tracked, Mapping):
            raise TypeError(self.tracked_issues(tracked, 0)[0])
        return get(self.kind).layout(self, system, frames, tracked)


@dataclass(frozen=True)
class BodyLayout:
    """One body's rows of the state and how to write and show them.

    ``first``/``rows``: its rows of the state (positions in the columns 0-2); ``vectors``: further
    node vectors by name (column slices, e.g. a rod's frames ``D1`` = 3:6); ``rate_vectors``: node
    vectors of its motion by name, column slices of its rows of the system's rates
    ``rates(t, state)`` at the frame (a rigid centre's ``velocity`` U = 0:3 and
    ``angular_velocity`` Ω = 3:6), which the state does not hold: the writer evaluates the rates
    once per frame for all bodies (in a scene the coupled solve gives every body's); ``cells`` and
    ``topology``: the XDMF topology (``"Polyline"``, ``"Triangle"``, ``"Polyvertex"``) and its
    connectivity; ``marks``: static per-node integer arrays (e.g. ``tracked``).
    """

    name: str
    kind: str
    first: int
    rows: int
    topology: str
    cells: np.ndarray
    vectors: Mapping[str, slice] = field(default_factory=dict)
    marks: Mapping[str, np.ndarray] = field(default_factory=dict)
    rate_vectors: Mapping[str, slice] = field(default_factory=dict)


def point_layout(name: str, kind: str, first: int, rows: int) -> BodyLayout:
    """The layout of ``rows`` unconnected points (XDMF Polyvertex, one cell per point)."""
    cells = np.arange(rows, dtype=np.int64).reshape(-1, 1)
    return BodyLayout(name, kind, first, rows, "Polyvertex", cells)


def polyline(n: int) -> np.ndarray:
    """The n - 1 segments (i, i + 1) of a line through n points, (n - 1, 2) int64."""
    return np.stack([np.arange(n - 1), np.arange(1, n)], axis=1).astype(np.int64)


def axis_stretch(fig: Any, ax: Any) -> str:
    """How much the vertical axis of ``ax`` is stretched against the horizontal one."""
    fig.draw_without_rendering()  # final axes sizes and limits
    box = ax.get_window_extent()
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    factor = (box.height / (y1 - y0)) / (box.width / (x1 - x0))
    return "true scale" if abs(factor - 1) < 0.05 else f"vertical axis stretched {factor:.3g}x"


def draw_over_time(fig: Any, bodies: Mapping[str, Mapping[str, np.ndarray]], times: np.ndarray,
                   planes: Sequence[tuple[int, int, str]], run: str, equal: bool = False,
                   **style: Any) -> None:
    """Every frame of every body as a line coloured by time, in one axes per plane
    ``(horizontal axis index, vertical axis index, vertical label)``, stacked with a shared
    horizontal axis; each title names the plane and states how much its vertical axis is
    stretched (``equal``: drawn at true scale)."""
    from matplotlib import colormaps
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    axes = fig.subplots(len(planes), 1, sharex=True, squeeze=False)[:, 0]
    colors = colormaps["viridis"](np.linspace(0, 1, len(times)))
    for ax, (i, j, label) in zip(axes, planes, strict=True):
        for body in bodies.values():
            for color, frame in zip(colors, body["positions"], strict=True):
                ax.plot(frame[:, i], frame[:, j], color=color, **style)
        ax.set_ylabel(label)
        ax.ticklabel_format(axis="y", useOffset=False)  # absolute distances, no "+1e1"
        if equal:
            ax.set_aspect("equal", adjustable="datalim")
    mappable = ScalarMappable(cmap="viridis", norm=Normalize(times[0], times[-1]))
    fig.colorbar(mappable, ax=list(axes), label="t (s)")
    axes[-1].set_xlabel(f"{'xyz'[planes[-1][0]]} (μm)")
    for ax, (i, j, _) in zip(axes, planes, strict=True):
        plane = f"{'xyz'[i]}-{'xyz'[j]}"
        ax.set_title(f"{plane} plane ({run}), {axis_stretch(fig, ax)}", fontsize=8)


#: ``draw(fig, bodies, times, run)``: draw the frames of this kind's ``bodies`` (name -> dict with
#: ``positions`` (F, M, 3), ``connectivity`` and marks) onto the matplotlib ``fig``.
Draw = Callable[[Any, Mapping[str, Mapping[str, np.ndarray]], np.ndarray, str], None]


def _draw_points(fig: Any, bodies: Mapping[str, Mapping[str, np.ndarray]], times: np.ndarray,
                 run: str) -> None:
    """Points of every body projected on x-y and x-z, first frame light, last frame dark."""
    axes = fig.subplots(1, 2)
    for ax, (i, j), label in zip(axes, ((0, 1), (0, 2)), ("y", "z"), strict=True):
        for body in bodies.values():
            for index, color in ((0, "0.7"), (-1, "k")):
                points = body["positions"][index]
                ax.plot(points[:, i], points[:, j], ".", color=color, ms=3)
        ax.set_xlabel("x")
        ax.set_ylabel(label)
        ax.set_aspect("equal", adjustable="datalim")
    axes[0].set_title(f"t = {times[0]:g} (grey), {times[-1]:g} (black); {run}")


@dataclass(frozen=True)
class BodyKind:
    """One kind of body: everything the shell needs to configure, run, write and draw it.

    ``section``: the config section class (its :meth:`BodySection.resolve` gives Θ⁰, whose names
    are those of ``system.params``); ``layout(section, system, frames, tracked)``: the
    :class:`BodyLayout` of every body of the state (``frames``: write node vectors; ``tracked``:
    marked points or None for the kind's default); ``draw``: see :data:`Draw`;
    ``tracks_points``: whether ``output.tracked_points`` applies; ``example()``: a small system, an
    active state of it and a horizon on which the schemes show their orders, for
    :func:`parastokes.testing.check_system` (the contract tests run it for every kind).
    """

    name: str
    section: type[BodySection]
    layout: Callable[[Any, Any, bool, Sequence[int] | None], list[BodyLayout]]
    draw: Draw = _draw_points
    tracks_points: bool = False
    example: Callable[[], tuple[Any, np.ndarray, float | None]] | None = None


# ---- kinds derived from a system class ----------------------------------------------------------
def _field_type(annotation: Any) -> Any:
    """TOML has arrays, not tuples: ``tuple[float, ...]`` fields are read as lists, and
    ``tuple[float, float, float]`` as lists of exactly three."""
    if typing.get_origin(annotation) is tuple:
        args = typing.get_args(annotation)
        if not args:
            return list
        # list[args[0]], built at run time (a subscript of a variable is no static type)
        items = types.GenericAlias(list, (args[0],))
        if Ellipsis in args:
            return items
        return Annotated[items, Field(min_length=len(args), max_length=len(args))]
    return annotation


def _field_default(f: dataclasses.Field) -> Any:
    """The config default of a dataclass field (``...``: required); tuples as lists."""
    if f.default is not dataclasses.MISSING:
        default = f.default
    elif f.default_factory is not dataclasses.MISSING:
        default = f.default_factory()
    else:
        return ...
    return list(default) if isinstance(default, tuple) else default


def derived_kind(cls: type, name: str) -> BodyKind:
    """The :class:`BodyKind` of a system class ``cls`` that is a dataclass: its config section has
    one key per field (same types and defaults; ``n_threads`` comes from ``execution.threads``),
    Θ⁰ is the built system's ``params``, and its state is one body of unconnected points."""
    if not dataclasses.is_dataclass(cls):
        raise UnknownKindError(
            f"{name!r}: {cls!r} is neither a BodyKind nor a dataclass system class"
        )
    fields: dict[str, Any] = {"kind": (Literal[name], Field(description="This body's class."))}
    try:
        hints = typing.get_type_hints(cls)
        for f in dataclasses.fields(cls):
            if f.name == "n_threads" or not f.init:
                continue
            fields[f.name] = (_field_type(hints[f.name]), _field_default(f))
    except Exception as error:  # a hint that does not resolve, a default that fails
        raise UnknownKindError(
            f"{name!r}: cannot derive a config section from the fields of {cls.__name__} "
            f"({type(error).__name__}: {error}); give it a BodyKind (docs/extending.md)"
        ) from error

    class Derived(BodySection):
        def resolve(self) -> BodyResolution:
            system = self.build()
            theta0 = {k: float(v) for k, v in system.params.items()}
            return BodyResolution(theta0, len(system.initial_state()))

        def build(self, threads: int = 1) -> System:
            values = {k: tuple(v) if isinstance(v, list) else v
                      for k, v in self.model_dump(exclude={"kind"}).items()}
            if any(f.name == "n_threads" for f in dataclasses.fields(cls)):
                values["n_threads"] = threads
            return cls(**values)

    try:
        section = create_model(
            f"{cls.__name__}Section",
            __base__=Derived,
            __doc__=cls.__doc__,
            **fields,
        )
    except Exception as error:  # a field type pydantic cannot validate (e.g. an array)
        raise UnknownKindError(
            f"{name!r}: cannot derive a config section from the fields of {cls.__name__} "
            f"({type(error).__name__}: {error}); mark fields that are not configuration with "
            "field(init=False), or give it a BodyKind (docs/extending.md)"
        ) from error

    def layout(section_: Any, system: System, frames: bool, tracked: Sequence[int] | None):
        return [point_layout(f"{cls.__name__.lower()}_0", name, 0, len(system.initial_state()))]

    return BodyKind(name, section, layout)


# ---- lookup ---------------------------------------------------------------------------------
def kinds() -> list[str]:
    """The names of the built-in and installed kinds (``"module:Name"`` kinds are not listed)."""
    return sorted(set(BUILTIN) | set(plugins.entry_points(ENTRY_POINT_GROUP)))


def _load(target: str, name: str) -> BodyKind:
    obj = plugins.import_target(target, name, UnknownKindError)
    if isinstance(obj, BodyKind):
        return obj
    if isinstance(getattr(obj, "body_kind", None), BodyKind):
        return obj.body_kind
    if isinstance(obj, type):
        return derived_kind(obj, name)
    raise UnknownKindError(f"{name!r}: {target} is not a BodyKind or a system class")


def _unknown(kind: str) -> Callable[[list[str]], UnknownKindError]:
    return lambda known: UnknownKindError(
        f"unknown body kind {kind!r}; registered kinds: {', '.join(known)}, or give a class "
        'as "package.module:ClassName" (docs/extending.md)'
    )


def get(kind: str) -> BodyKind:
    """The :class:`BodyKind` of ``kind``; :class:`UnknownKindError` naming the known kinds.

    A kind found under another string than its own name (an entry point, a class's
    ``body_kind``, a built-in's full ``"module:NAME"`` path) is returned renamed to ``kind``,
    its section taking ``kind`` as written in the config."""
    if not isinstance(kind, str) or not kind:
        raise UnknownKindError(f"kind must be a non-empty string, got {kind!r}")
    return _get(kind)


@cache
def _get(kind: str) -> BodyKind:
    found = _load(plugins.target(kind, BUILTIN, ENTRY_POINT_GROUP, _unknown(kind)), kind)
    if found.name == kind:
        return found
    fields: dict[str, Any] = {
        "kind": (Literal[kind], Field(description=f"The body kind ({found.name!r})."))
    }
    renamed = create_model(
        found.section.__name__,
        __base__=found.section,
        __doc__=found.section.__doc__,
        **fields,
    )
    return dataclasses.replace(found, name=kind, section=typing.cast(type[BodySection], renamed))
