"""From a validated configuration to the values of a run: the system, F and G (pure: starting the
executor and warming up are the run layer's, :mod:`parastokes.run.session`)."""

from __future__ import annotations

from dataclasses import dataclass

from .. import integrate
from ..core.contracts import PropagatorLike, System
from .checks import Resolved
from .schema import Config

__all__ = ["Setup", "build", "build_system"]


def build_system(cfg: Config, resolved: Resolved) -> System:
    """The system of ``cfg.model`` with the correct parameters Θ⁰ (its kind's section builds it),
    on ``resolved.threads`` kernel threads (:func:`~parastokes.config.checks.kernel_threads`)."""
    return cfg.model.build(resolved.threads)


def build_coarse(cfg: Config, resolved: Resolved, system: System) -> PropagatorLike:
    """The coarse solver G of ``cfg.coarse``, built by its family's section
    (:mod:`parastokes.registry.coarse`)."""
    return cfg.coarse.build(cfg, resolved, system)


@dataclass(frozen=True)
class Setup:
    """What a configuration builds: values only (no process, thread or executor is started).

    The run layer (:func:`parastokes.run.session.start`) starts the executor and warms up the
    workers.
    """

    config: Config
    resolved: Resolved
    system: System
    fine: integrate.Propagator
    coarse: PropagatorLike


def build(cfg: Config, resolved: Resolved) -> Setup:
    """Build the system, the fine propagator F and the coarse propagator G of ``cfg``.

    Pure: constructs values and starts nothing (no workers, no warm-up); see
    :func:`parastokes.run.session.start` for that.
    """
    system = build_system(cfg, resolved)
    fine = integrate.Propagator(system, cfg.fine.scheme, cfg.fine.dt, rtol=cfg.fine.rtol,
                                atol=cfg.fine.atol)
    return Setup(cfg, resolved, system, fine, build_coarse(cfg, resolved, system))
