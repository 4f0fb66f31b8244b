"""Configuration errors that name the key they are about, and the translation of pydantic's."""

from __future__ import annotations

import difflib
import types
import typing
from collections.abc import Iterable, Sequence
from typing import Any

from pydantic import BaseModel, ValidationError
from pydantic_core import ErrorDetails

from ..registry import coarse as coarse_registry
from ..registry import kinds as registry
from . import schema

__all__ = ["ConfigError", "from_validation_error", "key_path"]

# The schema class of every section, by key path (the model and coarse sections' are their
# kind's: the registries).
_SECTIONS: dict[tuple[str, ...], type[BaseModel]] = {
    (): schema.Config,
    ("time",): schema.Time,
    ("fine",): schema.Fine,
    ("coarse", "richardson"): schema.Richardson,
    ("parareal",): schema.Parareal,
    ("execution",): schema.Execution,
    ("output",): schema.Output,
    ("run",): schema.RunSection,
}


class ConfigError(ValueError):
    """An invalid configuration; ``issues`` lists ``(key path, message)`` pairs.

    ``str(error)`` has one line per issue, ``"coarse.lagrange.epsilon: nodes must be strictly
    increasing"``, under a heading naming the source file.
    """

    def __init__(self, issues: Sequence[tuple[str, str]], source: str = "") -> None:
        self.issues = list(issues)
        self.source = source
        where = f" in {source}" if source else ""
        lines = [f"invalid configuration{where}:"]
        lines += [f"  {path or '(top level)'}: {message}" for path, message in self.issues]
        super().__init__("\n".join(lines))

    @property
    def paths(self) -> list[str]:
        """The key paths of all issues."""
        return [path for path, _ in self.issues]


def key_path(loc: Iterable[Any]) -> str:
    """The key path of a location: ``("coarse", "lagrange", "x")`` -> ``coarse.lagrange.x``."""
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def _section_class(loc: tuple[Any, ...], data: Any) -> type[BaseModel] | None:
    if loc == ("model",):
        if not isinstance(data, dict):
            return None
        try:
            return registry.get(data["model"]["kind"]).section
        except (TypeError, KeyError, registry.UnknownKindError):
            return None
    if len(loc) == 2 and loc[0] == "bodies":  # a [[bodies]] table: its kind's section
        try:
            return registry.get(data["bodies"][loc[1]]["kind"]).section
        except (TypeError, KeyError, IndexError, registry.UnknownKindError):
            return None
    if loc == ("coarse",):  # its family's section
        table = data.get("coarse") if isinstance(data, dict) else None
        if not isinstance(table, dict):
            return None
        try:
            return coarse_registry.get(table.get("kind", coarse_registry.DEFAULT))
        except (AttributeError, coarse_registry.UnknownFamilyError):
            return None
    if len(loc) == 2 and loc[0] == "coarse":  # a nested section of the family ([coarse.g1])
        family = _section_class(("coarse",), data)
        field = None if family is None else family.model_fields.get(str(loc[1]))
        nested = None if field is None else field.annotation
        if isinstance(nested, type) and issubclass(nested, BaseModel):
            return nested
    if len(loc) == 3 and loc[0] == "suspensions" and loc[2] == "body":  # its body's kind
        try:
            return registry.get(data["suspensions"][loc[1]]["body"]["kind"]).section
        except (TypeError, KeyError, IndexError, registry.UnknownKindError):
            return None
    if len(loc) == 2 and loc[0] == "suspensions":
        return schema.Suspension
    if loc == ("scene",):
        return schema.SceneSettings
    if len(loc) == 3 and loc[:2] == ("coarse", "lagrange"):
        return schema.LagrangeNodes
    return _SECTIONS.get(loc)


def _models(annotation: Any) -> list[type[BaseModel]]:
    """The schema classes in a field's ``annotation`` (``X``, ``X | None``, ``list[X]``, ...)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    return [m for arg in typing.get_args(annotation) for m in _models(arg)]


def _field(loc: tuple[Any, ...], data: Any) -> tuple[type[BaseModel] | None, Any]:
    """The schema class that holds the key ``loc[-1]`` and that key's field (None for either
    when unknown): the section of ``loc[:-1]`` (:func:`_section_class`), or a class nested in
    the nearest known one by its fields' annotations (``scene.repulsion`` in ``scene``)."""
    for start in range(len(loc) - 1, -1, -1):
        cls = _section_class(loc[:start], data)
        for key in loc[start:-1]:
            if cls is None:
                break
            if isinstance(key, int):
                continue  # (an item of a list of tables)
            field = cls.model_fields.get(str(key))
            found = _models(field.annotation) if field is not None else []
            cls = found[0] if len(found) == 1 else None
        if cls is not None:
            return cls, cls.model_fields.get(str(loc[-1]))
    return None, None


def _union_tag(loc: tuple[Any, ...], data: Any) -> int | None:
    """The position in ``loc`` of pydantic's tag of a union member (``constrained-float`` after
    ``spacing``, whose values may be one number or a list), or None."""
    for i in range(1, len(loc)):
        if not isinstance(loc[i], str) or isinstance(loc[i - 1], int):
            continue
        _, field = _field(loc[:i], data)
        origin = None if field is None else typing.get_origin(field.annotation)
        members = [a for a in typing.get_args(field.annotation) if a is not type(None)] \
            if origin in (typing.Union, types.UnionType) else []
        if len(members) > 1 and loc[i] not in getattr(field.annotation, "model_fields", {}):
            return i
    return None


def _merged_unions(items: list[ErrorDetails], data: Any,
                   prefix: tuple[Any, ...]) -> list[tuple[tuple[Any, ...], str]]:
    """(location, message) of each error, those of the members of one union value merged into
    one: the member that got furthest into the value (an item of a list) when one did, else what
    the key holds (its description) and what it got."""
    out: list[tuple[tuple[Any, ...], str]] = []
    groups: dict[tuple[Any, ...], list[tuple[int, tuple[Any, ...], ErrorDetails]]] = {}
    for item in items:
        loc = (*prefix, *item["loc"])
        tag = _union_tag(loc, data)
        if tag is None:
            out.append((loc, _message(item, loc, data)))
            continue
        if loc[:tag] not in groups:
            groups[loc[:tag]] = []
            out.append((loc[:tag], ""))  # (its place in the order of the errors)
        groups[loc[:tag]].append((tag, loc, item))
    for i, (loc, message) in enumerate(out):
        if message or loc not in groups:
            continue
        members = groups[loc]
        deepest = max(len(at) - tag for tag, at, _ in members)
        inner = [(at[:tag] + at[tag + 1:], e) for tag, at, e in members if len(at) - tag == deepest]
        if deepest > 1 and len(inner) == 1:
            out[i] = (inner[0][0], _message(inner[0][1], inner[0][0], data))
            continue
        _, field = _field(loc, data)
        what = (field.description or "").rstrip(".") if field is not None else ""
        got = _describe(members[0][2].get("input"))
        out[i] = (loc, f"got {got}; expected {what}" if what else
                  f"{'; or '.join(dict.fromkeys(e['msg'] for _, _, e in members))} (got {got})")
    return out


def _describe(value: Any) -> str:
    text = repr(value)
    return f"{text[:60]}..." if len(text) > 60 else text


def _message(error: ErrorDetails, loc: tuple[Any, ...], data: Any) -> str:
    kind = error["type"]
    if kind == "extra_forbidden":
        cls, _ = _field(loc, data)
        known = sorted(cls.model_fields) if cls is not None else []
        close = difflib.get_close_matches(str(loc[-1]), known, n=1)
        hint = (f"did you mean {close[0]!r}?" if close else f"known keys: {', '.join(known)}"
                if known else "")
        return f"unknown key ({hint})" if hint else "unknown key"
    if kind == "missing":
        return "required key is missing"
    if kind == "value_error" and "error" in error.get("ctx", {}):
        return str(error["ctx"]["error"])  # a validator's own message, which says what it got
    return f"{error['msg']} (got {_describe(error.get('input'))})"


def from_validation_error(
    error: ValidationError, data: Any, source: str = "", prefix: tuple[str | int, ...] = ()
) -> ConfigError:
    """A :class:`ConfigError` from pydantic's error, with key paths instead of pydantic's locations.

    ``prefix`` is the key path of the validated section within ``data`` (``("model",)`` for a body
    section validated on its own). Unknown keys get a "did you mean" hint from the keys of their
    section.
    """
    merged = _merged_unions(error.errors(), data, prefix)
    return ConfigError([(key_path(loc), message) for loc, message in merged], source)
