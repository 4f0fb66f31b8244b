"""Configuration errors that name the key they are about, and the translation of pydantic's."""

from __future__ import annotations

import difflib
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


def _describe(value: Any) -> str:
    text = repr(value)
    return f"{text[:60]}..." if len(text) > 60 else text


def _message(error: ErrorDetails, loc: tuple[Any, ...], data: Any) -> str:
    kind = error["type"]
    if kind == "extra_forbidden":
        cls = _section_class(loc[:-1], data)
        known = sorted(cls.model_fields) if cls is not None else []
        close = difflib.get_close_matches(str(loc[-1]), known, n=1)
        hint = f"did you mean {close[0]!r}?" if close else f"known keys: {', '.join(known)}"
        return f"unknown key ({hint})"
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
    issues = []
    for item in error.errors():
        loc = (*prefix, *item["loc"])
        issues.append((key_path(loc), _message(item, loc, data)))
    return ConfigError(issues, source)
