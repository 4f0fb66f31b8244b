"""From a validated configuration to the values of a run: the system, F and G (pure: starting the
executor and warming up are the run layer's, :mod:`parastokes.session`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from .. import integrate, parareal
from ..contracts import PropagatorLike, System
from .checks import Resolved
from .schema import Config

__all__ = ["Setup", "build", "build_system"]


def build_system(cfg: Config, resolved: Resolved) -> System:
    """The system of ``cfg.model`` with the correct parameters Θ⁰ (its kind's section builds it)."""
    return cfg.model.build(cfg.execution.threads)


def build_coarse(cfg: Config, resolved: Resolved, system: System) -> PropagatorLike:
    """The coarse solver G of the family ``coarse.kind`` (:data:`COARSE`)."""
    return COARSE[cfg.coarse.kind](cfg, resolved, system)


def build_extrapolated(
    cfg: Config, resolved: Resolved, system: System
) -> parareal.Extrapolated | parareal.OnCoarseGrid:
    """G of eq. 30 with the base step τ = τ_c / r^m (``resolved.coarse_base_dt``)."""
    coarse = cfg.coarse
    richardson = coarse.richardson
    return parareal.extrapolated(
        system,
        coarse.scheme,
        resolved.coarse_base_dt,
        lagrange=resolved.lagrange or None,
        richardson={"m": richardson.m, "r": richardson.r} if richardson.m else None,
        grid=coarse.grid_factor if coarse.grid_factor > 1 else None,
    )


#: Coarse-solver families by ``coarse.kind``: ``build(cfg, resolved, system) -> G``.
COARSE: dict[str, Callable[[Config, Resolved, System], PropagatorLike]] = {
    "extrapolated": build_extrapolated,
}


@dataclass(frozen=True)
class Setup:
    """What a configuration builds: values only (no process, thread or executor is started).

    The run layer (:func:`parastokes.session.start`) starts the executor and warms up the workers.
    """

    config: Config
    resolved: Resolved
    system: System
    fine: integrate.Propagator
    coarse: PropagatorLike


def build(cfg: Config, resolved: Resolved) -> Setup:
    """Build the system, the fine propagator F and the coarse propagator G of ``cfg``.

    Pure: constructs values and starts nothing (no workers, no warm-up); see
    :func:`parastokes.session.start` for that.
    """
    system = build_system(cfg, resolved)
    fine = integrate.Propagator(system, cfg.fine.scheme, cfg.fine.dt)
    return Setup(cfg, resolved, system, fine, build_coarse(cfg, resolved, system))
