"""The coarse-solver registry: how config, check, run and predict find a family (docs/extending.md).

A *coarse-solver family* is one :class:`CoarseSection` subclass: the ``[coarse]`` section of its
``kind`` (pydantic, ``extra="forbid"``), which resolves itself against the run
(:meth:`CoarseSection.resolve`: step counts, N_G, weights, grid points, issues in the config's
format), builds the propagator G (:meth:`CoarseSection.build`) and estimates γ_G/γ_F for
``parastokes predict`` (:meth:`CoarseSection.gamma_ratio`). Config, checks and CLI ask the
registry and never name a family.

A family is found by its ``kind`` string as a body is (:mod:`parastokes.core.plugins`): a built-in
name (:data:`BUILTIN`: ``"extrapolated"``, the default; ``"hodmd"``, HODMD-Parareal),
``"package.module:Name"`` (the section class) or an entry point of the group
``parastokes.coarse``; none is imported before it is asked for.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cache
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from ..core import plugins
from ..core.contracts import System

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
    "hodmd": "parastokes.coarse.hodmd.family:Hodmd",
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
        :class:`~parastokes.registry.kinds.BodyResolution`) and compute the coarse values;
        append ``("coarse.key", message)`` to ``issues`` and notes to ``warnings``."""
        raise NotImplementedError

    def build(self, cfg: Any, resolved: Any, system: System) -> Any:
        """The coarse propagator G of this section for ``system`` (a propagator; with
        ``n_auxiliary`` and ``with_executor`` for a
        :class:`~parastokes.core.contracts.CoarseSolver`)."""
        raise NotImplementedError

    def gamma_ratio(self, cfg: Any, resolved: Any, cores: int) -> float:
        """γ_G/γ_F estimated from operation counts, for ``parastokes predict``."""
        raise ValueError(
            f"the coarse-solver family {self.kind!r} gives no cost estimate; pass --ratio or "
            "--measured"
        )


def families() -> list[str]:
    """The names of the built-in and installed families (``"module:Name"`` ones are not listed)."""
    return sorted(set(BUILTIN) | set(plugins.entry_points(ENTRY_POINT_GROUP)))


@cache
def get(kind: str) -> type[CoarseSection]:
    """The section class of family ``kind``; :class:`UnknownFamilyError` naming the known ones."""
    if not isinstance(kind, str) or not kind:
        raise UnknownFamilyError(f"kind must be a non-empty string, got {kind!r}")

    def unknown(known: list[str]) -> UnknownFamilyError:
        return UnknownFamilyError(
            f"unknown coarse-solver family {kind!r}; registered families: {', '.join(known)}, "
            'or give a section class as "package.module:ClassName" (docs/extending.md)'
        )

    target = plugins.target(kind, BUILTIN, ENTRY_POINT_GROUP, unknown)
    section = plugins.import_target(target, kind, UnknownFamilyError)
    if not (isinstance(section, type) and issubclass(section, CoarseSection)):
        raise UnknownFamilyError(f"{kind!r}: {target} is not a CoarseSection subclass")
    return section
