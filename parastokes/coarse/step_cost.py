"""What one step of a scheme costs, in evaluations of the rates: the unit of the operation counts
by which the coarse-solver families estimate γ_G/γ_F for ``parastokes predict``.

An explicit step with fixed size is its stages, each one evaluation of the O(N²) Stokeslet sums.
A linearly implicit step also builds the approximate Jacobian every few steps, factorizes
``I - hγA`` and solves (``ros2-krylov``: GMRES iterations, each one more evaluation), and an
adaptive step may be rejected and taken again: no count says what that costs on a given body (the
sparse algebra grows like N, the sums like N²), so it is measured. The scheme runs over the first
slice of the run from the initial state (the coarse solver's whole work on a slice, its Jacobians
and factorizations included), and its CPU time per nominal step is divided by the CPU time of one
evaluation of the rates of the same system, in the same process (docs/stiff.md, "Parareal").
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from .. import integrate
from ..config.build import build_system
from ..core.contracts import System

__all__ = ["FINE_PROBE_STEPS", "evaluations_per_step", "measured_evaluations"]

#: Steps of an implicit or adaptive fine solver timed (a whole fine slice would take as long as
#: the run's serial part).
FINE_PROBE_STEPS = 20
#: Evaluations of the rates timed for the unit of :func:`measured_evaluations`.
PROBE_EVALUATIONS = 5


def _cpu(work: Callable[[], object]) -> float:
    start = time.process_time()
    work()
    return time.process_time() - start


def measured_evaluations(system: System, scheme: str | integrate.AnyScheme, t0: float,
                         span: float, steps: int, rtol: float | None = None,
                         atol: float | None = None) -> float:
    """The CPU time of ``scheme`` over ``[t0, t0 + span]`` in ``steps`` steps (or adaptive steps
    with ``rtol``, ``steps`` then the nominal count) from ``system``'s initial state, per step, in
    units of one evaluation of ``system.rates`` at that state. One step and one evaluation first
    run untimed (compilation, cached colourings)."""
    x0 = system.initial_state()
    dt = span / steps
    integrate.run(system, x0, t0, t0 + dt, scheme, dt, rtol=rtol, atol=atol)
    system.rates(t0, x0)
    evaluation = _cpu(lambda: [system.rates(t0, x0) for _ in range(PROBE_EVALUATIONS)])
    run = _cpu(lambda: integrate.run(system, x0, t0, t0 + span, scheme, dt, rtol=rtol, atol=atol))
    return run / steps / max(evaluation / PROBE_EVALUATIONS, 1e-9)


def evaluations_per_step(cfg: Any, resolved: Any, scheme: str | integrate.AnyScheme, steps: int,
                         grid: int = 1, rtol: float | None = None, atol: float | None = None,
                         system: System | None = None, probe: int | None = None) -> float:
    """Evaluations of the rates that one of ``steps`` steps per slice of ``scheme`` costs on the
    run's body (on its coarser grid with ``grid`` > 1): the stages of a fixed-step explicit scheme,
    else :func:`measured_evaluations` over the run's first slice, or over its first ``probe``
    steps (a fine solver, too long to run whole); ``system``: the built body, to build it once."""
    s = integrate.lookup(scheme)
    if rtol is None and not s.implicit:  # ("auto" has rtol)
        return float(s.stages)
    body = system if system is not None else build_system(cfg, resolved)
    if grid > 1:
        body = body.coarsened(grid)[0]  # type: ignore[attr-defined]
    timed = steps if probe is None else max(1, min(steps, probe))
    span = (cfg.time.t1 - cfg.time.t0) / cfg.parareal.n_slices * timed / steps
    return measured_evaluations(body, scheme, cfg.time.t0, span, timed, rtol, atol)
