"""Run configurations: TOML files validated against a typed schema (reference: docs/config.md).

>>> cfg, resolved = load("experiments/quick/table4_g3.toml")      # doctest: +SKIP
>>> setup = build(cfg, resolved)                                   # doctest: +SKIP
>>> setup.system, setup.fine, setup.coarse                         # doctest: +SKIP

:func:`load` reads TOML with :mod:`tomllib`, applies ``--set key=value`` overrides, validates the
schema (:mod:`.schema`, unknown keys are errors) and the rules across keys (:mod:`.checks`), and
raises :class:`ConfigError` whose lines each name a key path. :func:`build` makes the system, the
fine propagator and the coarse propagator of eq. 30; :func:`preflight` builds them and calls a
user's body once (what ``parastokes check`` and every run do before any worker starts). This
package is pure data: nothing here starts a process or an executor (the run layer does,
:mod:`parastokes.run.session`). :data:`DEMO` is the built-in configuration of ``parastokes demo``.
"""

from __future__ import annotations

import os
import tomllib
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from ..core.files import InputFileError, describe_os_error, read_input
from ..registry import coarse as coarse_registry
from ..registry import kinds as registry
from .build import Setup, build, build_system
from .checks import Resolved, resolve, resolved_dict
from .errors import ConfigError, from_validation_error
from .preflight import preflight
from .problem import problem_key, problem_of
from .scene import scene_section
from .schema import Config

__all__ = [
    "DEMO",
    "Config",
    "ConfigError",
    "Resolved",
    "Setup",
    "apply_overrides",
    "build",
    "build_body",
    "build_system",
    "load",
    "loads",
    "merge",
    "parse",
    "preflight",
    "problem_key",
    "problem_of",
    "resolve",
    "resolved_dict",
]

#: The configuration of ``parastokes demo``: the paper's rod swimmer (section 5.1) in miniature.
#: The rod is a fifth of the paper's (L = 12 μm, M = 61) at the paper's grid spacing σ_f = 0.2 μm
#: and ε⁰ = 5 σ_f, so the time-step limits of Tables 3-4 carry over (τ_f = 1e-6 for F; plain
#: forward Euler at ε⁰ is stable up to ~12 τ_f, at ε = 5.6 σ_f up to ~18 τ_f, docs/validation.md).
#: Two slices on two workers, a coarse solver of two auxiliary solvers (N_G = N_c = 2, Algorithm
#: 1's rule), one Parareal iteration to reach the tolerance: the setting in which two cores can
#: show a speedup. T = 0.02 s is 2/5 of a beat period 2π/f = 0.05 s. About a minute on two cores.
DEMO = """\
title = "demo: a short rod swimmer (section 5.1 in miniature), Lagrange extrapolation in eps"

[model]
kind = "rod"
n_points = 61          # sigma_f = length / (n_points - 1) = 0.2, the paper's spacing
length = 12.0          # a fifth of the paper's 60 um rod
epsilon = 5.0          # epsilon0 = 5 sigma_f (sections 5.1.1-5.1.2)
epsilon_unit = "sigma_f"

[time]
t1 = 0.02              # 2/5 of a beat period 2 pi / f = 0.05 s

[fine]
scheme = "rk2"
dt = 1e-6              # the paper's tau_f

[coarse]
scheme = "euler"
dt_ratio = 16          # tau_c = 16 tau_f: unstable at epsilon0, stable at the nodes below
lagrange = { epsilon = { nodes = [5.6, 5.65], unit = "sigma_f" } }   # N_G = 2

[parareal]
n_slices = 2
tol = 1e-4             # relative increment of eq. 34
max_iterations = 2

[execution]
executor = "processes"
workers = 2

[run]
mode = "both"          # also the serial fine run: true errors and measured speedup
"""


#: Deepest nesting of arrays and tables accepted in a file or a ``--set`` value.
MAX_DEPTH = 32


def _depth(text: str) -> int:
    """The deepest nesting of brackets and braces in TOML ``text`` (outside strings, roughly:
    an upper bound is all that is needed to refuse what the parser's recursion cannot read)."""
    deepest = depth = 0
    for char in text:
        if char in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif char in "]}":
            depth = max(depth - 1, 0)
    return deepest


def _toml(text: str, path: str, source: str = "") -> dict[str, Any]:
    """``tomllib.loads(text)`` with nesting beyond :data:`MAX_DEPTH` refused (a ConfigError on
    ``path``) instead of ending in a RecursionError."""
    if _depth(text) > MAX_DEPTH:
        raise ConfigError([(path, f"arrays or tables nested more than {MAX_DEPTH} deep: no "
                                  "configuration needs that; check the value")], source)
    try:
        return tomllib.loads(text.removeprefix("\ufeff"))  # (a BOM, as some editors write)
    except RecursionError:
        raise ConfigError([(path, "nested too deep to be read")], source) from None


def _value(text: str, path: str = "--set") -> Any:
    """The TOML value ``text`` (``4``, ``1e-6``, ``[1, 2]``, ``true``, ``"rk4"``), else a string."""
    try:
        return _toml(f"v = {text}", path)["v"]
    except tomllib.TOMLDecodeError:
        return text


def _key_path(path: str, item: str) -> list[str]:
    """The keys of a TOML dotted key (``coarse.lagrange."rod.epsilon"``, ``bodies.0.name``)."""
    try:
        node: Any = _toml(f"{path} = 0", path)
    except tomllib.TOMLDecodeError:
        raise ConfigError([(path, f"--set expects KEY=VALUE with KEY a TOML dotted key (quote a "
                                  f"key that holds a dot: a.\"b.c\"), got {item!r}")]) from None
    keys = []
    while isinstance(node, dict):
        ((key, node),) = node.items()
        keys.append(key)
    return keys


def _assign(node: Any, keys: list[str], value: Any, path: str) -> Any:
    """A copy of ``node`` with the value at ``keys`` replaced by ``value`` (tables on the way
    made as needed; a digit key indexes an array of tables, e.g. ``bodies.0``)."""
    if not keys:
        return value
    key, rest = keys[0], keys[1:]
    if isinstance(node, list) and node and all(isinstance(item, dict) for item in node):
        if not (key.isdigit() and int(key) < len(node)):
            raise ConfigError([(path, f"--set: {key!r} is not an index of this array of "
                                      f"{len(node)} tables (0 to {len(node) - 1})")])
        items = list(node)
        items[int(key)] = _assign(items[int(key)], rest, value, path)
        return items
    table = dict(node) if isinstance(node, dict) else {}
    table[key] = _assign(table.get(key), rest, value, path)
    return table


def _split(item: str) -> tuple[str, str, str]:
    """``item`` split at its first ``=`` outside a quoted key part (``a."b=c"=1``)."""
    quote, escaped = "", False
    for i, char in enumerate(item):
        if quote:
            if char == quote and not escaped:
                quote = ""
            escaped = not escaped and quote == '"' and char == "\\"
        elif char in "\"'":
            quote = char
        elif char == "=":
            return item[:i], "=", item[i + 1:]
    return item, "", ""


def apply_overrides(data: dict[str, Any], overrides: Iterable[str]) -> dict[str, Any]:
    """``data`` with ``"section.key=value"`` assignments (values in TOML syntax) applied: the
    value replaces what is at the key, a table included (``coarse.lagrange={}`` removes every
    node). The key is a TOML dotted key: quoted parts hold dots and ``=``, digits index arrays
    of tables."""
    out = data
    for item in overrides:
        path, sep, text = _split(item)
        path = path.strip()
        if not sep or not path:
            raise ConfigError([(path, f"--set expects KEY=VALUE, got {item!r}")])
        out = _assign(out, _key_path(path, item), _value(text.strip(), path), path)
    return out


def merge(base: dict[str, Any], update: dict[str, Any]) -> dict[str, Any]:
    """``base`` updated by ``update``: tables merge key by key, other values are replaced."""
    out = dict(base)
    for key, value in update.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = merge(out[key], value)
        else:
            out[key] = value
    return out


def _anchor_files(data: dict[str, Any], folder: Path) -> None:
    """Make the relative ``file`` of every ``[[suspensions]]`` table of ``data`` relative to
    ``folder``, the folder of the file that names it (so a variant through ``base`` finds it)."""
    tables = data.get("suspensions")
    for table in tables if isinstance(tables, list) else []:
        name = table.get("file") if isinstance(table, dict) else None
        if isinstance(name, str) and name and not Path(name).is_absolute():
            table["file"] = str(folder / name)


def _read(path: Path, chain: tuple[Path, ...] = ()) -> dict[str, Any]:
    """The TOML table of ``path``, merged onto its ``base`` file (a path relative to it), if any."""
    source = str(path)
    if path.resolve() in chain:
        raise ConfigError([("base", f"circular reference to {path}")], source)
    try:
        data = _toml(read_input(path, "configuration").decode("utf-8"), "", source)
    except InputFileError as error:
        raise ConfigError([("", f"{error.problem}; {error.remedy}")], source) from None
    except OSError as error:
        reason = describe_os_error(error)
        raise ConfigError([("", f"cannot read the file: {reason}")], source) from None
    except UnicodeDecodeError as error:
        raise ConfigError([("", f"not UTF-8 text, as TOML must be ({error})")], source) from None
    except tomllib.TOMLDecodeError as error:
        raise ConfigError([("", f"TOML syntax error: {error}")], source) from None
    _anchor_files(data, path.parent)
    base = data.pop("base", None)
    if base is None:
        return data
    if not isinstance(base, str) or not base.strip() or "\0" in base:
        raise ConfigError([("base", f"must be a file name, got {base!r}")], source)
    return merge(_kinds_switched(_read(path.parent / base, (*chain, path.resolve())), data), data)


#: The tables whose ``kind`` selects their keys, and the kind each has without one.
_KINDED = {"model": None, "coarse": coarse_registry.DEFAULT}


def _kinds_switched(base: dict[str, Any], data: dict[str, Any]) -> dict[str, Any]:
    """``base`` without the tables whose ``kind`` ``data`` changes (``[coarse] kind = "hodmd"``
    over a base of the extrapolated family): the keys of another kind are not inherited."""
    out = dict(base)
    for table, default in _KINDED.items():
        mine, theirs = data.get(table), base.get(table)
        if isinstance(mine, dict) and isinstance(theirs, dict) and "kind" in mine and \
                mine["kind"] != theirs.get("kind", default):
            del out[table]
    return out


def build_body(table: dict[str, Any], threads: int = 1, source: str = "body table") -> Any:
    """One body built from its configuration table alone (what a ``[model]`` table holds, e.g.
    ``{"kind": "rigid", "shape": "sphere", "n_points": 400}``), without a whole run
    configuration: validated by its kind's section, resolved (its checks: a surface too coarse, a
    body on the wall, a singular system), and built with its kernels on ``threads`` threads.
    :class:`ConfigError` names what is wrong."""
    issues: list[tuple[str, str]] = []
    section = _model_section({"model": dict(table)}, issues, source)
    if section is None:
        raise ConfigError(issues, source)
    try:
        section.resolve()
    except ValueError as error:
        raise ConfigError([("model", str(error))], source) from None
    return section.build(threads)


def _model_section(data: dict[str, Any], issues: list[tuple[str, str]], source: str) -> Any:
    """The ``[model]`` table validated by its kind's section (None, with issues, if it is not)."""
    if "kind" not in data["model"]:
        issues.append(("model.kind", "required key is missing"))
        return None
    return _section_of_kind(data, "model", lambda kind: registry.get(kind).section, issues, source)


def _section_of_kind(data: dict[str, Any], key: str, section_of: Any,
                     issues: list[tuple[str, str]], source: str) -> Any:
    """The ``data[key]`` table validated by ``section_of(its kind)`` (None, with issues, if it is
    not); a ``[coarse]`` table without ``kind`` is of the default family."""
    table = data[key]
    try:
        section = section_of(table.get("kind", coarse_registry.DEFAULT))
    except (registry.UnknownKindError, coarse_registry.UnknownFamilyError) as error:
        issues.append((f"{key}.kind", str(error)))
        return None
    try:
        return section.model_validate(table)
    except ValidationError as error:
        issues += from_validation_error(error, data, source, (key,)).issues
        return None


#: The top-level tables of a scene: its bodies, its suspensions (many copies of one body,
#: :mod:`.suspension`) and its fluid.
SCENE_KEYS = ("bodies", "suspensions", "scene")


def _scene_data(data: dict[str, Any], issues: list[tuple[str, str]], source: str
                ) -> dict[str, Any]:
    """``data`` with its ``[[bodies]]``, ``[[suspensions]]`` and ``[scene]`` replaced by their
    scene section as the ``model`` (:mod:`.scene`); issues for a ``[scene]`` without bodies or
    both forms at once."""
    rest = {k: v for k, v in data.items() if k not in SCENE_KEYS}
    if "bodies" not in data and "suspensions" not in data:
        issues.append(("scene", "[scene] sets the fluid of [[bodies]] tables; add them, or move "
                                "its keys into [model]"))
        return rest
    if "model" in data:
        issues.append(("model", "give either [model] (one body) or [[bodies]] tables (a scene), "
                                "not both; move [model] into a [[bodies]] table"))
        issues += [(key, "given together with [model]; keep one of the two")
                   for key in ("bodies", "suspensions") if key in data]
        return rest
    section = scene_section(data, issues, source)
    return rest | {"model": section} if section is not None else rest


def parse(data: dict[str, Any], source: str = "") -> Config:
    """Validate the schema of a configuration dictionary; raise :class:`ConfigError`.

    The ``[model]`` table is validated by the section of its kind
    (:mod:`parastokes.registry.kinds`; an unknown kind is an error listing the registered ones),
    the ``[coarse]`` table by the section of its family (:mod:`parastokes.registry.coarse`),
    ``[[bodies]]`` and ``[[suspensions]]`` tables and ``[scene]`` make one scene section
    (:mod:`.scene`), the rest is
    validated by :class:`Config`, and the issues of all are reported together.
    """
    issues: list[tuple[str, str]] = []
    if isinstance(data, dict) and any(key in data for key in SCENE_KEYS):
        data = _scene_data(data, issues, source)
    elif isinstance(data, dict) and isinstance(data.get("model"), dict):
        section = _model_section(data, issues, source)
        data = {**data, "model": section} if section is not None else data
    if isinstance(data, dict) and isinstance(data.get("coarse"), dict):
        section = _section_of_kind(data, "coarse", coarse_registry.get, issues, source)
        data = {**data, "coarse": section} if section is not None else data
    try:
        cfg = Config.model_validate(data)
    except ValidationError as error:
        found = from_validation_error(error, data, source).issues
        issues += [(path, text) for path, text in found  # each once, not again as a section's
                   if (path, text) not in issues and not (issues and path in ("model", "coarse"))]
        raise ConfigError(issues, source) from None
    if issues:
        raise ConfigError(issues, source)
    return cfg


def loads(
    text: str, source: str = "<string>", overrides: Iterable[str] = ()
) -> tuple[Config, Resolved]:
    """Parse and fully validate TOML text; returns the configuration and its derived values."""
    try:
        data = _toml(text, "", source)
    except tomllib.TOMLDecodeError as error:
        raise ConfigError([("", f"TOML syntax error: {error}")], source) from None
    cfg = parse(apply_overrides(data, overrides), source)
    return cfg, resolve(cfg, source)


def load(path: str | os.PathLike, overrides: Iterable[str] = ()) -> tuple[Config, Resolved]:
    """Read, parse and fully validate a TOML file.

    A top-level ``base = "other.toml"`` (relative to the file) reads that file first and applies
    this one on top of it (tables merge key by key), so that a variant states only what differs.
    ``overrides`` (``"section.key=value"``) are applied last.
    """
    path = Path(path)
    cfg = parse(apply_overrides(_read(path), overrides), str(path))
    return cfg, resolve(cfg, str(path))
