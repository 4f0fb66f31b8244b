"""The coarse-solver registry: how config, check, run and predict find a family (docs/extending.md).

A *coarse-solver family* is one :class:`CoarseSection` subclass: the ``[coarse]`` section of its
``kind`` (pydantic, ``extra="forbid"``), which resolves itself against the run
(:meth:`CoarseSection.resolve`: step counts, N_G, weights, grid points, issues in the config's
format), builds the propagator G (:meth:`CoarseSection.build`) and estimates γ_G/γ_F for
``parastokes predict`` (:meth:`CoarseSection.gamma_ratio`). Config, checks and CLI ask the
registry and never name a family.

A family is found by its ``kind`` string:

- a built-in name (:data:`BUILTIN`: ``"extrapolated"``, the default), one line each;
- ``"package.module:Name"``: the section class ``Name`` in an importable module;
- an entry point name of the group ``parastokes.coarse`` (installed packages), whose value is a
  ``"package.module:Name"`` as above.

Modules are imported only when a family is asked for, so this module imports no family.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from functools import cache
from importlib import metadata
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

__all__ = [
    "BUILTIN",
    "DEFAULT",
    "ENTRY_POINT_GROUP",
    "CoarseResolution",
    "CoarseSection",
    "UnknownFamilyError",
    "families",
    "get",
]

#: The package's own families: name -> ``"module:attribute"`` of their section class.
BUILTIN: dict[str, str] = {
    "extrapolated": "parastokes.coarse.extrapolated:Extrapolated",
}

#: The family of a ``[coarse]`` section without ``kind``.
DEFAULT = "extrapolated"

#: The entry point group of installed coarse-solver packages: ``name = "package.module:Name"``.
ENTRY_POINT_GROUP = "parastokes.coarse"


class UnknownFamilyError(ValueError):
    """A ``kind`` that names no registered, importable or installed coarse-solver family."""


@dataclass(frozen=True)
class CoarseResolution:
    """What a coarse section resolves to: the coarse fields of :class:`parastokes.config.Resolved`.

    ``coarse_dt``: τ_c (the smallest step taken); ``coarse_base_dt``: the τ of eq. 26 (τ_c for a
    family without Richardson steps); ``coarse_steps``: steps per slice of each step size;
    ``coarse_points``: state rows of G's grid; ``lagrange``: absolute nodes by parameter;
    ``n_auxiliary``: N_G, the solves that run at once; ``weight_sum``: Σ|w| of the combination.
    """

    coarse_dt: float
    coarse_base_dt: float
    coarse_steps: list[int]
    coarse_points: int
    lagrange: dict[str, list[float]] = field(default_factory=dict)
    n_auxiliary: int = 1
    weight_sum: float = 1.0


class CoarseSection(BaseModel):
    """The base of every coarse-solver family's config section (``[coarse]``).

    Subclasses set ``kind`` to their name (a ``Literal`` for a built-in one) and implement
    :meth:`resolve` and :meth:`build`; :meth:`gamma_ratio` is optional (``predict`` then needs
    ``--ratio`` or ``--measured``).
    """

    model_config = ConfigDict(extra="forbid", strict=True, validate_default=True)

    kind: str = Field(description="The coarse-solver family.")

    def resolve(self, cfg: Any, body: Any, slice_length: float, issues: list[tuple[str, str]],
                warnings: list[str]) -> CoarseResolution:
        """Check this section against the validated ``cfg`` (its body resolved to ``body``, a
        :class:`~parastokes.bodies.registry.BodyResolution`) and compute the coarse values;
        append ``("coarse.key", message)`` to ``issues`` and notes to ``warnings``."""
        raise NotImplementedError

    def build(self, cfg: Any, resolved: Any, system: Any) -> Any:
        """The coarse propagator G of this section for ``system`` (a propagator; with
        ``n_auxiliary`` and ``with_executor`` for a :class:`~parastokes.contracts.CoarseSolver`)."""
        raise NotImplementedError

    def gamma_ratio(self, cfg: Any, resolved: Any, cores: int) -> float:
        """γ_G/γ_F estimated from operation counts, for ``parastokes predict``."""
        raise ValueError(
            f"the coarse-solver family {self.kind!r} gives no cost estimate; pass --ratio or "
            "--measured"
        )


def _entry_points() -> dict[str, str]:
    return {ep.name: ep.value for ep in metadata.entry_points(group=ENTRY_POINT_GROUP)}


def families() -> list[str]:
    """The names of the built-in and installed families (``"module:Name"`` ones are not listed)."""
    return sorted(set(BUILTIN) | set(_entry_points()))


def _load(target: str, name: str) -> type[CoarseSection]:
    module_name, _, attribute = target.partition(":")
    try:
        obj: Any = importlib.import_module(module_name)
        for part in attribute.split("."):
            obj = getattr(obj, part)
    except (ImportError, AttributeError) as error:
        raise UnknownFamilyError(f"{name!r}: cannot load {target} ({error})") from None
    if not (isinstance(obj, type) and issubclass(obj, CoarseSection)):
        raise UnknownFamilyError(f"{name!r}: {target} is not a CoarseSection subclass")
    return obj


@cache
def get(kind: str) -> type[CoarseSection]:
    """The section class of family ``kind``; :class:`UnknownFamilyError` naming the known ones."""
    if not isinstance(kind, str) or not kind:
        raise UnknownFamilyError(f"kind must be a non-empty string, got {kind!r}")
    if kind in BUILTIN:
        return _load(BUILTIN[kind], kind)
    if ":" in kind:
        return _load(kind, kind)
    installed = _entry_points()
    if kind in installed:
        return _load(installed[kind], kind)
    raise UnknownFamilyError(
        f"unknown coarse-solver family {kind!r}; registered families: {', '.join(families())}, "
        'or give a section class as "package.module:ClassName" (docs/extending.md)'
    )
