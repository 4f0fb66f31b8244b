"""From a validated configuration to the objects of a run: system, F, G and the executor."""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Executor
from dataclasses import dataclass

from .. import integrate, parallel, parareal
from ..contracts import PropagatorLike, System, oversubscription
from ..warmup import WarmUp
from .checks import Resolved
from .errors import ConfigError
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


@dataclass
class Setup:
    """Everything a run needs; a context manager that shuts the executor down on exit."""

    config: Config
    resolved: Resolved
    system: System
    fine: integrate.Propagator
    coarse: PropagatorLike
    executor: Executor | None

    def __enter__(self) -> Setup:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def close(self) -> None:
        """Shut the executor down (idempotent)."""
        if self.executor is not None:
            self.executor.shutdown()
            self.executor = None


def build(cfg: Config, resolved: Resolved, *, executor: bool = True) -> Setup:
    """Build system, fine propagator F, coarse propagator G and (with ``executor``) the executor.

    The executor's workers and this process are warmed up here (numba caches loaded), so timings
    that follow measure work. Raises :class:`~.errors.ConfigError` when an MPI launch provides fewer
    workers than the coarse solver needs and oversubscription is not allowed.
    """
    system = build_system(cfg, resolved)
    fine = integrate.Propagator(system, cfg.fine.scheme, cfg.fine.dt)
    coarse = build_coarse(cfg, resolved, system)
    pool = None
    if executor and cfg.run.mode != "serial":
        ex = cfg.execution
        options = {} if ex.executor in ("serial", "gpu") else {"threads_per_worker": ex.threads}
        pool = parallel.make_executor(
            ex.executor,
            resolved.workers,
            warmup=WarmUp(system),
            **options,
        )
        problem = oversubscription(resolved.n_auxiliary, pool.workers, cfg.parareal.schedule)
        if resolved.workers is None and problem and not ex.allow_oversubscribe:
            pool.shutdown()
            raise ConfigError(
                [
                    (
                        "execution.workers",
                        f"{problem} in this MPI launch; start more ranks or set "
                        "execution.allow_oversubscribe = true",
                    )
                ]
            )
    if executor:
        # this process too: its serial fine run is timed, and must not include loading (or, on
        # a fresh install, compiling) the kernels and the compiled loop of steps
        WarmUp(system)()
    return Setup(cfg, resolved, system, fine, coarse, pool)
