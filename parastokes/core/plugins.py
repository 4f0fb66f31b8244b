"""How a registry finds a plug-in by its ``kind`` string (the body and coarse-solver registries).

A kind is:

- a built-in name: a key of the registry's table, whose value is its ``"module:attribute"``;
- ``"package.module:Name"``: ``Name`` in an importable module;
- an entry point name of the registry's group (installed packages), whose value is a
  ``"package.module:Name"`` as above.

Modules are imported only when a kind is asked for, so a registry imports none of its plug-ins.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from importlib import metadata
from typing import Any

__all__ = ["entry_points", "import_target", "target"]


def entry_points(group: str) -> dict[str, str]:
    """The installed entry points of ``group``: name -> ``"package.module:Name"``."""
    return {ep.name: ep.value for ep in metadata.entry_points(group=group)}


def target(kind: str, builtin: Mapping[str, str], group: str,
           unknown: Callable[[list[str]], Exception]) -> str:
    """The ``"module:attribute"`` that ``kind`` names; ``unknown(known names)`` is raised when it
    names none (a non-empty string is expected)."""
    if kind in builtin:
        return builtin[kind]
    if ":" in kind:
        return kind
    installed = entry_points(group)
    if kind in installed:
        return installed[kind]
    raise unknown(sorted(set(builtin) | set(installed)))


def import_target(target: str, name: str, error: type[Exception]) -> Any:
    """The object at ``"module:attribute.path"``; ``error`` naming ``name`` and what is missing."""
    module_name, _, attribute = target.partition(":")
    if not module_name or not attribute or module_name.startswith("."):
        raise error(f"{name!r}: give it as \"package.module:Name\" (an absolute module path, a "
                    "colon, then the name in the module)")
    try:
        obj: Any = importlib.import_module(module_name)
    except Exception as failure:  # ImportError, or any error raised while the module ran
        raise error(
            f"{name!r}: cannot import module {module_name!r} "
            f"({type(failure).__name__}: {failure})"
        ) from failure
    for part in attribute.split("."):
        try:
            obj = getattr(obj, part)
        except AttributeError:
            raise error(
                f"{name!r}: module {module_name!r} has no attribute {attribute!r}"
            ) from None
    return obj
