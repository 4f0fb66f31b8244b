"""Scenes from a config file: ``[[bodies]]`` tables and the scene-wide ``[scene]`` fluid settings.

Each ``[[bodies]]`` table is one body, validated by the section of its ``kind`` (the registry), as
``[model]`` is; an optional ``name`` labels it in Θ (default: its kind, numbered when the kind
repeats: ``rod0``, ``rod1``; :class:`parastokes.scene.Scene`). ``[scene]`` holds what the bodies
share: ``viscosity``, ``wall``, ``shear_rate`` (one fluid, one background flow). A body table that
omits one of these keys gets the scene's; one that states a different value is an error naming
both keys. A ``[scene]`` key left out is taken from the bodies (the first that states it, else the
first whose section has it, with that section's default), else ``wall = false`` and
``shear_rate = 0``. ``[scene] coarse_bodies`` names the bodies that ``coarse.grid_factor`` puts on
their coarser grid (default: every body that has one, :meth:`Scene.coarsened`); ``[scene]
repulsion = { range, force }`` a short-range push apart between the rigid bodies (and from the
wall; off by default, :mod:`parastokes.scene.repulsion`).

:func:`scene_section` turns the tables into one :class:`SceneModel`, the ``model`` of the
configuration: its Θ⁰ names parameters as :attr:`parastokes.scene.Scene.params` does
(``"viscosity"``, ``"rod.epsilon"``, ``"vesicle.stiffness"``), its output layout is the layouts of
all bodies with their rows offset, and it builds a :class:`~parastokes.scene.Scene`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, Literal

from pydantic import Field, PrivateAttr, SerializeAsAny, ValidationError

from ..core.contracts import System
from ..registry import kinds as registry
from ..registry.kinds import (
    RESERVED_NAMES,
    BodyLayout,
    BodyResolution,
    BodySection,
    PlannedSize,
    Positive,
    Tracked,
)
from .errors import from_validation_error
from .placement import PlacementError
from .schema import RepulsionSettings, SceneSettings, Suspension
from .suspension import expand

if TYPE_CHECKING:  # the scene (and the fluid's kernels) are imported on use
    from ..scene import Scene

__all__ = ["FLUID", "SceneModel", "SceneSettings", "scene_section"]

#: The scene-wide keys: one fluid (μ, wall) and one background shear flow.
FLUID = ("viscosity", "wall", "shear_rate")
_DEFAULTS = {"wall": False, "shear_rate": 0.0}


class SceneModel(BodySection):
    """Several bodies in one fluid (:class:`parastokes.scene.Scene`), made from ``[[bodies]]``."""

    kind: Literal["scene"] = Field("scene", description="A scene of ``[[bodies]]``.")
    bodies: list[SerializeAsAny[BodySection]] = Field(min_length=1)
    names: list[str]
    viscosity: Positive
    wall: bool
    shear_rate: float = Field(allow_inf_nan=False)
    coarse_bodies: list[str] | None = None
    repulsion: RepulsionSettings | None = None
    #: For each body, the index of the body it copies (a suspension's copies differ in their
    #: poses only: one of them is resolved for all); None: every body on its own.
    _copy_of: list[int] | None = PrivateAttr(None)

    def resolve(self) -> BodyResolution:
        """Θ⁰ named as :attr:`Scene.params`; the rows of all bodies. The scene is built once
        here, so that a body that cannot join a scene is named by ``check``, not by a run's
        first step (ValueError). A suspension's copies are resolved once (the rigid kinds'
        trial solve, :func:`parastokes.kinds.rigid.kind.check_solvable`, on its first body)."""
        self.build()
        copy_of = self._copy_of or list(range(len(self.bodies)))
        found: dict[int, BodyResolution] = {}
        parts = [found.setdefault(k, self.bodies[k].resolve()) if k not in found else found[k]
                 for k in copy_of]
        theta0 = {"viscosity": float(self.viscosity)}
        for name, part in zip(self.names, parts, strict=True):
            theta0 |= {f"{name}.{k}": v for k, v in part.theta0.items() if k != "viscosity"}
        return BodyResolution(theta0, sum(part.n_points for part in parts))

    def planned_size(self) -> PlannedSize:
        """The bodies' sizes together (each from its keys where its kind says, else from its
        cheap :meth:`resolve`), named ``bodies``."""
        parts = [body.planned_size() or PlannedSize(body.resolve().n_points)
                 for body in self.bodies]
        return PlannedSize(sum(p.rows for p in parts), sum(p.dense_bytes for p in parts),
                           "bodies")

    def build(self, threads: int = 1) -> Scene:
        from ..scene import Repulsion, Scene

        coarse = None if self.coarse_bodies is None else tuple(self.coarse_bodies)
        repulsion = (None if self.repulsion is None
                     else Repulsion(self.repulsion.range, self.repulsion.force))
        return Scene(tuple(self._built(i, threads) for i in range(len(self.bodies))),
                     self.viscosity,
                     self.wall, self.shear_rate, tuple(self.names), n_threads=threads,
                     coarse_bodies=coarse, repulsion=repulsion)

    def _built(self, index: int, threads: int) -> System:
        """Body ``index`` built; its ValueError (a body on the wall, too coarse a surface)
        names it."""
        try:
            return self.bodies[index].build(threads)
        except ValueError as error:
            raise ValueError(f"bodies[{index}] ({self.names[index]!r}): {error}") from None

    def coarse_points(self, factor: int) -> int:
        """Rows of the scene on the grid of ``coarse.grid_factor``: each body that has a coarser
        grid on it, the others as they are (:meth:`Scene.coarsened`, whose ValueError names
        the body that does not fit, or says that none has one)."""
        coarse, _ = self.build().coarsened(factor)
        return len(coarse.initial_state())

    def parameter_units(self, name: str) -> tuple[str, dict[str, float]]:
        """Those of the body that ``name`` (``"body.param"``) belongs to."""
        body, _, param = name.partition(".")
        if param and body in self.names:
            return self.bodies[self.names.index(body)].parameter_units(param)
        return "absolute", {}

    def tracks_points(self) -> bool:
        return any(body.tracks_points() for body in self.bodies)

    def tracked_issues(self, tracked: Tracked, n_points: int) -> list[str]:
        """A table by body name, each body's indices checked by its own section (bodies left
        out keep their kind's default points)."""
        marking = [n for n, body in zip(self.names, self.bodies, strict=True)
                   if body.tracks_points()]
        example = f"{{{marking[0] if marking else 'vesicle0'} = [0, 5]}}"
        if not isinstance(tracked, Mapping):
            return [] if tracked is None else [
                f"a scene names the body of its points: give a table, e.g. {example}"]
        out = []
        for name, indices in tracked.items():
            if name not in self.names:
                out.append(f"no body is named {name!r}; the bodies that mark points: "
                           f"{', '.join(marking) or 'none (vesicles only)'}")
                continue
            body = self.bodies[self.names.index(name)]
            out += [f"{name}: {issue}"
                    for issue in body.tracked_issues(indices, body.resolve().n_points)]
        return out

    def tables(self) -> dict[str, Any]:
        """``[scene]`` and one ``[[bodies]]`` table per body, named."""
        fluid = {key: getattr(self, key) for key in FLUID}
        if self.coarse_bodies is not None:
            fluid["coarse_bodies"] = list(self.coarse_bodies)
        if self.repulsion is not None:
            fluid["repulsion"] = self.repulsion.model_dump()
        bodies = [{"name": name, **body.tables()["model"]}
                  for name, body in zip(self.names, self.bodies, strict=True)]
        return {"scene": fluid, "bodies": bodies}

    def layout(self, system: System, frames: bool, tracked: Tracked) -> list[BodyLayout]:
        """Every body's layout, rows offset by the bodies before it, named after its body;
        ``tracked``: the marked points by body name (bodies left out: their kind's default)."""
        from ..scene import Scene

        if not isinstance(system, Scene):
            raise TypeError(f"a scene's layout needs a Scene, got {type(system).__name__}")
        issues = self.tracked_issues(tracked, 0)
        if issues:
            raise TypeError(issues[0])
        by_body = tracked if isinstance(tracked, Mapping) else {}
        out, first = [], 0
        for name, section, body in zip(self.names, self.bodies, system.bodies, strict=True):
            parts = section.layout(body, frames, by_body.get(name))
            for part in parts:
                label = name if len(parts) == 1 else f"{name}_{part.name}"
                out.append(dataclasses.replace(part, name=label, first=first + part.first))
            first += len(body.initial_state())
        return out


def _default_names(kinds: list[str]) -> list[str]:
    """The kinds' last parts, lower case and without a "System" suffix (as ``Scene`` names its
    bodies), numbered where repeated."""
    short = [k.rpartition(":")[2].lower().removesuffix("system") or "body" for k in kinds]
    return [k if short.count(k) == 1 else f"{k}{short[:i].count(k)}" for i, k in enumerate(short)]


def _fluid(tables: list[dict[str, Any]], sections: list[type[BodySection]],
           settings: SceneSettings, issues: list[tuple[str, str]], paths: list[str]
           ) -> dict[str, Any]:
    """The scene's fluid values; fills them into the body tables that omit them, and appends an
    issue for each body table that contradicts them (``paths``: each table's key path)."""
    out: dict[str, Any] = {}
    for key in FLUID:
        value, where = getattr(settings, key), f"scene.{key}"
        if value is None:
            stated = [(i, t[key]) for i, t in enumerate(tables) if key in t]
            having = [i for i, s in enumerate(sections)
                      if key in s.model_fields and not s.model_fields[key].is_required()]
            if stated:
                value, where = stated[0][1], f"{paths[stated[0][0]]}.{key}"
            elif having:
                value, where = sections[having[0]].model_fields[key].default, where
            elif key in _DEFAULTS:
                value = _DEFAULTS[key]
            else:
                issues.append((where, "required key is missing (give it here or in a body "
                                      "table)"))
                continue
        out[key] = value
        for path, table, section in zip(paths, tables, sections, strict=True):
            if key not in section.model_fields:
                continue
            if key not in table:
                table[key] = value
            elif table[key] != value:
                issues.append((f"{path}.{key}",
                               f"{table[key]!r} differs from {where} = {value!r} (the bodies "
                               "share one fluid and one background flow); remove one or make "
                               "them agree"))
    return out


def _tables(data: dict[str, Any], key: str, issues: list[tuple[str, str]]) -> list[dict] | None:
    """The array of tables ``data[key]`` (empty when absent; None, with an issue, if it is not
    one)."""
    tables = data.get(key, [])
    if key in data and (not isinstance(tables, list) or not tables
                        or not all(isinstance(t, dict) for t in tables)):
        issues.append((key, f"must be one or more [[{key}]] tables"))
        return None
    return tables


def _suspensions(data: dict[str, Any], issues: list[tuple[str, str]], source: str
                 ) -> list[Suspension] | None:
    """The validated ``[[suspensions]]`` tables (their bodies not yet; None, with issues, if
    one is not valid)."""
    tables = _tables(data, "suspensions", issues)
    if tables is None:
        return None
    specs = []
    for j, table in enumerate(tables):
        try:
            specs.append(Suspension.model_validate(table))
        except ValidationError as error:
            issues += from_validation_error(error, data, source, ("suspensions", j)).issues
        if isinstance(table.get("body"), dict) and "name" in table["body"]:
            issues.append((f"suspensions[{j}].body.name", "the suspension names its bodies: "
                                                          "give name in [[suspensions]]"))
    return specs if len(specs) == len(tables) else None


def _placed(specs: list[Suspension], templates: list[BodySection], wall: bool,
            issues: list[tuple[str, str]], first: int
            ) -> tuple[list[BodySection], list[str], list[str], list[int]]:
    """Every suspension's copies, their names, the key path of each name (its table's
    ``name``, :func:`.suspension.expand`) and the index of each suspension's first copy among
    the scene's bodies (counted from ``first``); an issue naming the table's key for each
    suspension that cannot be placed."""
    bodies: list[BodySection] = []
    names: list[str] = []
    paths: list[str] = []
    copied: list[int] = []
    for j, (spec, template) in enumerate(zip(specs, templates, strict=True)):
        prefix = spec.name if spec.name is not None else _default_names([template.kind])[0]
        try:
            copies = expand(spec, template, prefix, wall)
        except PlacementError as error:
            issues.append((f"suspensions[{j}].{error.key}", str(error)))
            continue
        except ValueError as error:  # the body's own table, built to measure it
            issues.append((f"suspensions[{j}].body", str(error)))
            continue
        copied += [first + len(bodies)] * len(copies)
        bodies += copies
        names += [f"{prefix}{i}" for i in range(len(copies))]
        paths += [f"suspensions[{j}].name"] * len(copies)
    return bodies, names, paths, copied


def _name_issues(names: list[str], paths: list[str]) -> list[tuple[str, str]]:
    """One issue per key path whose (first) name is not distinct or not allowed."""
    count: dict[str, int] = {}
    for n in names:
        count[n] = count.get(n, 0) + 1
    rule = (f"names must be distinct strings without '.' or '/', and not "
            f"{' or '.join(map(repr, RESERVED_NAMES))}")
    out: dict[str, str] = {}
    for path, n in zip(paths, names, strict=True):
        if path in out:
            continue
        if not isinstance(n, str) or not n or "." in n or "/" in n or n in RESERVED_NAMES:
            out[path] = f"{rule}, got {n!r}"
        elif count[n] > 1:
            out[path] = f"{rule}: {n!r} names more than one body"
    return list(out.items())


def scene_section(data: dict[str, Any], issues: list[tuple[str, str]], source: str
                  ) -> SceneModel | None:
    """The :class:`SceneModel` of ``data``'s ``[[bodies]]``, ``[[suspensions]]`` and ``[scene]``
    (None, with issues, if they are not valid)."""
    found = len(issues)
    tables = _tables(data, "bodies", issues)
    specs = _suspensions(data, issues, source)
    if tables is None or specs is None:
        return None
    try:
        settings = SceneSettings.model_validate(data.get("scene", {}))
    except ValidationError as error:
        issues += from_validation_error(error, data, source, ("scene",)).issues
        return None
    tables = [dict(t) for t in tables]
    names = [t.pop("name", None) for t in tables]
    every = tables + [{k: v for k, v in spec.body.items() if k != "name"} for spec in specs]
    paths = [f"bodies[{i}]" for i in range(len(tables))] + [
        f"suspensions[{j}].body" for j in range(len(specs))]
    locations = [("bodies", i) for i in range(len(tables))] + [
        ("suspensions", j, "body") for j in range(len(specs))]
    sections: list[type[BodySection]] = []
    for path, table in zip(paths, every, strict=True):
        try:
            sections.append(registry.get(table.get("kind", "")).section)
        except registry.UnknownKindError as error:
            issues.append((f"{path}.kind",
                           "required key is missing" if "kind" not in table else str(error)))
    if len(sections) < len(every):
        return None
    fluid = _fluid(every, sections, settings, issues, paths)
    validated = []
    for location, table, section in zip(locations, every, sections, strict=True):
        try:
            validated.append(section.model_validate(table))
        except ValidationError as error:
            issues += from_validation_error(error, data, source, location).issues
    if len(validated) < len(every) or len(fluid) < len(FLUID) or len(issues) > found:
        return None
    bodies, templates = validated[:len(tables)], validated[len(tables):]
    default = _default_names([t["kind"] for t in tables])
    names = [n if n is not None else d for n, d in zip(names, default, strict=True)]
    placed, generated, origins, copied = _placed(specs, templates, fluid["wall"], issues,
                                                 len(bodies))
    issues += _name_issues(names + generated, [f"bodies[{i}].name" for i in range(len(tables))]
                           + origins)
    if len(issues) > found:
        return None
    all_names = names + generated
    unknown = sorted(set(settings.coarse_bodies or ()) - set(all_names))
    if unknown:
        issues.append(("scene.coarse_bodies", f"no body is named {', '.join(map(repr, unknown))}; "
                                              f"the bodies: {_listed(all_names)}"))
        return None
    model = SceneModel(bodies=bodies + placed, names=all_names,
                       coarse_bodies=settings.coarse_bodies, repulsion=settings.repulsion,
                       **fluid)
    model._copy_of = list(range(len(bodies))) + copied
    return model


def _listed(names: list[str], most: int = 12) -> str:
    """``names`` joined, the middle of a long list left out."""
    if len(names) <= most:
        return ", ".join(names)
    return f"{', '.join(names[:most // 2])}, ... ({len(names)} bodies), {names[-1]}"
