"""Coarse solvers built by extrapolation (section 4): eqs. 18, 21/25, 28 and 30.

``extrapolated(system, scheme, dt, lagrange=..., richardson=...)`` combines auxiliary propagators
G_{Theta^j, r^q tau} = ``integrate.Propagator(system.with_params(**Theta^j), scheme, r^q dt)`` into

    G = sum_j w_j sum_q v_q G_{Theta^j, r^q tau}                                         (eq. 30)

followed by ``system.project``. The w_j are the tensor-product Lagrange weights (eqs. 22, 25) over
the nodes of every parameter named in ``lagrange``; the v_q the Richardson weights (eq. 27). A
propagator takes ``n_q = max(1, round(slice / (r^q dt)))`` equal steps, so it actually uses
h_q = slice / n_q; the v_q are computed for those h_q (``weights.step_weights``), which cancels the
error terms tau^alpha .. tau^(alpha+m-1) exactly even when r^q dt does not divide the slice.

On an executor the N_G = N_theta1 N_theta2 N_theta3 (m + 1) auxiliary solvers of one call run
concurrently (Algorithm 1, steps 4 and 15), one task each. Algorithm 1 requires N_G <= N_c
(its input condition) so that they all run at once: `check_workers` enforces it, unless
oversubscription is allowed explicitly; the solvers are then batched, one batch per worker, and
each coarse step of the serial sweep takes ceil(N_G / N_c) rounds.
"""

from __future__ import annotations

import copy
import functools
import itertools
import logging
import math
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Executor
from typing import Any, Required, TypedDict

import numpy as np

from .. import integrate
from ..core.contracts import System, check_workers
from ..integrate import AnyScheme
from ..parallel import Task, run_tasks
from .transfer import OnCoarseGrid
from .weights import check_nodes, lagrange_weights, step_weights, validate_richardson

__all__ = ["Extrapolated", "RichardsonSpec", "adaptive_tolerances", "extrapolated"]


class RichardsonSpec(TypedDict, total=False):
    """The ``richardson`` of :func:`extrapolated`: the depth m, and the ratio r (m >= 1)."""

    m: Required[int]
    r: float | None

logger = logging.getLogger(__name__)


def _run_batch(
    solvers: tuple[integrate.Propagator, ...], t_start: float, t_end: float, x: np.ndarray,
    counted: bool = False,
) -> list[Any]:
    """Run several auxiliary solvers one after the other on one worker (oversubscription)."""
    return [(p.counted if counted else p)(t_start, t_end, x) for p in solvers]


class Extrapolated:
    """The propagator of eq. 30 (eq. 18/25 when m = 0, eq. 28 without Lagrange nodes).

    Build it with :func:`extrapolated`, which validates the inputs. ``auxiliary[j][q]`` is
    G_{Theta^j, r^q tau}; ``thetas[j]`` is Theta^j; ``lagrange_weights[j]`` is w_j. With an
    ``executor`` the auxiliary solvers of one call run concurrently on it (Algorithm 1, steps 4 and
    15), one labelled task each (:func:`parastokes.parallel.run_tasks`: a failure names the
    solver), or one batch per worker when there are more solvers than workers (see
    `check_workers`). The executor stays with the manager: it is dropped when the combinator
    is pickled.
    """

    def __init__(
        self,
        system: System,
        scheme: str | AnyScheme,
        dt: float,
        thetas: list[dict[str, float]],
        lagrange: np.ndarray,
        r: float,
        m: int,
        executor: Executor | None = None,
        tolerances: tuple[float, float] | None = None,
    ) -> None:
        self.system = system
        self.order = integrate.scheme_order(scheme)
        self.thetas = thetas
        self.lagrange_weights = lagrange
        self.auxiliary = [
            [integrate.Propagator(variant, scheme, dt * r**q,
                                  **(dict(zip(("rtol", "atol"), tolerances, strict=True))
                                     if tolerances else {}))
             for q in range(m + 1)]
            for variant in (system.with_params(**theta) if theta else system for theta in thetas)
        ]
        self.executor = executor
        #: The steps h_q actually taken in the most recent call (None before the first call).
        self.steps_used: tuple[float, ...] | None = None
        #: Adaptive auxiliary solvers (``rtol``, or ``scheme = "auto"``) report step counts.
        self.adaptive = tolerances is not None
        #: Their steps since :meth:`take_step_counts`: accepted, rejected, auto's switches.
        self.step_counts = [0, 0, 0]

    @property
    def n_auxiliary(self) -> int:
        """N_G = N_theta1 N_theta2 N_theta3 (m + 1): the auxiliary solvers (Algorithm 1, 5.1.1)."""
        return len(self.auxiliary) * len(self.auxiliary[0])

    def _label(self, index: int) -> str:
        j, q = divmod(index, len(self.auxiliary[0]))
        theta = ", ".join(f"{name}={value:.6g}" for name, value in self.thetas[j].items())
        step = self.auxiliary[j][q].dt
        return f"auxiliary coarse solver {index} ({theta + ', ' if theta else ''}step {step:.6g})"

    def _run_on_executor(self, t_start: float, t_end: float, x: np.ndarray) -> list[np.ndarray]:
        """The auxiliary solvers' values, one task per solver, or one batch per worker when there
        are more solvers than workers (oversubscription, see `check_workers`)."""
        solvers = [p for row in self.auxiliary for p in row]
        executor = self.executor
        assert executor is not None  # __call__ comes here with an executor only
        workers = getattr(executor, "workers", None)
        if workers is None or workers == 1 or len(solvers) <= workers:
            return run_tasks(executor, self.auxiliary_tasks(t_start, t_end, x))
        batches = np.array_split(np.arange(len(solvers)), workers)
        tasks = [
            Task(
                _run_batch,
                (tuple(solvers[i] for i in batch), t_start, t_end, x, self.adaptive),
                f"batch of auxiliary coarse solvers {batch[0]}-{batch[-1]}",
            )
            for batch in batches
        ]
        return [value for batch in run_tasks(executor, tasks) for value in batch]

    def _states(self, results: list[Any]) -> list[np.ndarray]:
        """The auxiliary solvers' states from their results; the step counts of adaptive ones
        (``Propagator.counted``) are added to :attr:`step_counts` on the way."""
        if not self.adaptive:
            return results
        for _, counts in results:
            self.step_counts = [a + b for a, b in zip(self.step_counts, counts, strict=True)]
        return [state for state, _ in results]

    def take_step_counts(self) -> dict[str, int] | None:
        """The adaptive auxiliary solvers' steps since the last call ``{accepted, rejected,
        switches}`` (then reset), or None for fixed steps."""
        if not self.adaptive:
            return None
        accepted, rejected, switches = self.step_counts
        self.step_counts = [0, 0, 0]
        return {"accepted": accepted, "rejected": rejected, "switches": switches}

    def plan(self, t_start: float, t_end: float) -> tuple[np.ndarray, np.ndarray]:
        """The steps h_q = (t_end - t_start) / n_q actually taken on a slice, and their weights v_q.

        Raises ValueError when two steps coincide after rounding to whole step counts.
        """
        steps = np.array([(t_end - t_start) / p.n_steps(t_start, t_end) for p in self.auxiliary[0]])
        return steps, step_weights(steps, self.order)

    def coefficients(self, t_start: float, t_end: float) -> np.ndarray:
        """The weights w_j v_q of eq. 30 on a slice, flat in the order of ``auxiliary_tasks``.

        Logs the steps at INFO when they change; raises ValueError (from :meth:`plan`) before any
        solver runs when two steps coincide after rounding.
        """
        steps, v = self.plan(t_start, t_end)
        if tuple(steps) != self.steps_used:
            logger.info(
                "extrapolated coarse solver: steps %s (requested %s), Richardson weights %s",
                np.array2string(steps, precision=6),
                np.array2string(np.array([p.dt for p in self.auxiliary[0]]), precision=6),
                np.array2string(v, precision=6),
            )
            self.steps_used = tuple(steps)
        return np.multiply.outer(self.lagrange_weights, v).ravel()

    def auxiliary_tasks(self, t_start: float, t_end: float, x: np.ndarray) -> list[Task]:
        """The N_G auxiliary solves G_{Theta^j, r^q tau}(t_start, t_end, x), one task each."""
        solvers = [p for row in self.auxiliary for p in row]
        if self.adaptive:
            return [Task(p.counted, (t_start, t_end, x), self._label(i))
                    for i, p in enumerate(solvers)]
        return [Task(p, (t_start, t_end, x), self._label(i)) for i, p in enumerate(solvers)]

    def combine(
        self,
        t_start: float,
        t_end: float,
        x: np.ndarray,
        coefficients: np.ndarray,
        values: list[np.ndarray],
    ) -> np.ndarray:
        """Eq. 30 from the auxiliary solvers' ``values``: the weighted sum, checked, projected."""
        combined = sum(c * g for c, g in zip(coefficients, values, strict=True))
        self._check_combination(t_start, t_end, x, combined, coefficients)
        try:
            return self.system.project(combined)
        except ValueError as error:
            raise integrate.BlowUpError(
                t_end, 0, math.nan, np.array(x),
                f"the extrapolated combination of {len(coefficients)} auxiliary solvers is not a "
                f"valid state ({error})",
            ) from None

    def split(
        self, t_start: float, t_end: float, x: np.ndarray
    ) -> tuple[list[Task], Callable[[list[np.ndarray]], np.ndarray]] | None:
        """One call as separate work: its auxiliary tasks, and the function that combines their
        values (in task order) into exactly what the call returns. Used by the pipelined schedule
        (:mod:`parastokes.parareal.pipelined`) to run every auxiliary solve as its own task.
        None on an empty interval, where the call itself is the (projected) state."""
        if t_end == t_start:
            return None
        coefficients = self.coefficients(t_start, t_end)
        tasks = self.auxiliary_tasks(t_start, t_end, x)
        return tasks, functools.partial(self._combine_results, t_start, t_end, x, coefficients)

    def _combine_results(self, t_start: float, t_end: float, x: np.ndarray,
                         coefficients: np.ndarray, results: list[Any]) -> np.ndarray:
        """:meth:`combine` of the auxiliary tasks' results (step counts taken off)."""
        return self.combine(t_start, t_end, x, coefficients, self._states(results))

    def __call__(self, t_start: float, t_end: float, x: np.ndarray) -> np.ndarray:
        if t_end == t_start:  # no step: the state, projected (as a plain propagator gives it)
            return self.system.project(np.array(x, dtype=float))
        coefficients = self.coefficients(t_start, t_end)
        if self.executor is None:
            results = _run_batch(tuple(p for row in self.auxiliary for p in row), t_start,
                                 t_end, x, self.adaptive)
        else:
            results = self._run_on_executor(t_start, t_end, x)
        return self._combine_results(t_start, t_end, x, coefficients, results)

    def _check_combination(
        self,
        t_start: float,
        t_end: float,
        x: np.ndarray,
        combined: np.ndarray,
        coefficients: np.ndarray,
    ) -> None:
        """The blow-up test of the auxiliary solvers, applied to their weighted sum (eq. 30).

        Each auxiliary solver checks its own steps; the combination can still be far off when
        the slice holds too few coarse steps for the auxiliaries' barely damped stiff modes to
        decay (the Lagrange weights amplify them, docs/validation.md): say so, instead of letting
        the next slice's auxiliaries fail on a state they never produced.
        """
        limit = integrate.BLOWUP_FACTOR * self.system.monitor_limit
        value = self.system.monitor(combined) if np.isfinite(combined).all() else math.nan
        if not value <= limit:
            steps = self.auxiliary[0][0].n_steps(t_start, t_end)
            raise integrate.BlowUpError(
                t_end,
                steps - 1,
                value,
                x,
                f"the extrapolated combination of {len(coefficients)} auxiliary solvers "
                f"(sum |w_j v_q| = {np.abs(coefficients).sum():.3g}) is beyond "
                f"{integrate.BLOWUP_FACTOR:g} x the monitor limit although each auxiliary "
                f"stayed within it: too few coarse steps per slice ({steps} here; "
                "see docs/validation.md)",
            )

    def with_executor(self, executor: Executor | None) -> Extrapolated:
        """A copy whose auxiliary solvers run on ``executor``.

        This only binds: the N_G <= N_c rule is checked by :func:`extrapolated` and by
        :func:`parastokes.parareal.run`, whichever hands the executor over (`check_workers`).
        """
        clone = copy.copy(self)
        clone.executor = executor
        clone.step_counts = [0, 0, 0]
        return clone

    def __getstate__(self) -> dict:
        return {**self.__dict__, "executor": None}


def _lagrange_nodes(system: System, lagrange: Mapping[str, Sequence[float]] | None):
    """Validate the Lagrange nodes; return (Theta^j list, flat weights w_j)."""
    if not lagrange:
        return [{}], np.ones(1)
    if not isinstance(lagrange, Mapping):
        raise ValueError("lagrange must map parameter names to node lists")
    known = system.params
    unknown = sorted(set(lagrange) - set(known))
    if unknown:
        raise ValueError(
            f"lagrange: unknown parameter(s) {unknown}; this system has {sorted(known)}"
        )
    names = list(lagrange)
    nodes = [list(lagrange[name]) for name in names]
    for name, node_set in zip(names, nodes, strict=True):
        check_nodes(known[name], node_set, f"lagrange[{name!r}]")
    weights = lagrange_weights([known[name] for name in names], nodes)
    thetas = [dict(zip(names, combo, strict=True)) for combo in itertools.product(*nodes)]
    return thetas, weights.ravel()


def adaptive_tolerances(scheme: str | AnyScheme, rtol: float | None, atol: float | None, m: int
                        ) -> tuple[float, float] | None:
    """``(rtol, atol)`` of adaptive auxiliary solvers, checked (None without them): finite and
    positive, a scheme with an error estimate, no Richardson extrapolation (ValueError naming the
    key)."""
    if rtol is None and atol is None:
        return None
    if rtol is None:
        raise ValueError("rtol: required with atol (adaptive steps)")
    if m:
        raise ValueError("rtol: Richardson extrapolation (m >= 1) needs the fixed steps r^q tau "
                         "of eq. 26; use m = 0 with adaptive steps")
    return integrate.tolerances(scheme, rtol, atol)


def extrapolated(
    system: System,
    scheme: str | AnyScheme,
    dt: float,
    lagrange: Mapping[str, Sequence[float]] | None = None,
    richardson: RichardsonSpec | None = None,
    grid: int | None = None,
    executor: Executor | None = None,
    allow_oversubscribe: bool = False,
    rtol: float | None = None,
    atol: float | None = None,
) -> Extrapolated | OnCoarseGrid:
    """The extrapolated coarse solver G of eq. 30 (section 4), a picklable propagator.

    - ``lagrange``: ``{name: [theta^1, ..., theta^N]}`` for parameters of ``system.params``; the
      nodes of each must increase strictly and theta^0 = ``system.params[name]`` must lie outside
      their interval (section 4.1, conditions 1-2). Several names give the tensor product (eq. 21).
    - ``richardson``: ``{"m": m, "r": r}`` with integer m >= 0 and r in (0, 1) (eq. 26).
    - ``grid``: an integer coarsening factor >= 2; the solver then runs on
      ``system.coarsened(grid)`` and is wrapped in :class:`OnCoarseGrid` (eqs. 32-33).
    - ``executor``: runs the auxiliary solvers of each call concurrently (Algorithm 1, steps 4, 15);
      :func:`parastokes.parareal.run` supplies its own when this is None.
    - ``allow_oversubscribe``: with ``executor``, accept more auxiliary solvers N_G than workers
      N_c (batched per worker, ceil(N_G / N_c) rounds per coarse step); by default that is a
      ValueError (Algorithm 1 requires N_G <= N_c; see `check_workers`).
    - ``rtol``, ``atol``: adaptive steps of every auxiliary solver (``dt`` the first step tried;
      a scheme with an error estimate, docs/stiff.md); not with Richardson extrapolation, whose
      weights (eq. 27) need the fixed steps r^q τ.

    Everything is validated before any solver is built; the message names the rule that failed.
    """
    if not (isinstance(dt, int | float) and math.isfinite(dt) and dt > 0.0):
        raise ValueError(f"dt must be positive and finite, got {dt!r}")
    integrate.scheme_order(scheme)
    thetas, weights = _lagrange_nodes(system, lagrange)
    spec: RichardsonSpec = richardson or {"m": 0}
    extra = sorted(set(spec) - {"m", "r"})
    if extra or "m" not in spec:
        raise ValueError(f"richardson takes the keys 'm' and 'r', got {sorted(spec)}")
    m, r = spec["m"], spec.get("r")
    validate_richardson(m, r)
    tolerances = adaptive_tolerances(scheme, rtol, atol, m)
    check_workers(len(thetas) * (m + 1), executor, allow_oversubscribe)
    if grid is not None:
        if isinstance(grid, bool) or not isinstance(grid, int) or grid < 2:
            raise ValueError(f"grid must be an integer coarsening factor >= 2, got {grid!r}")
        if not hasattr(system, "coarsened"):
            raise ValueError(f"grid: {type(system).__name__} has no coarsened(factor) method")
        coarse_system, transfer = system.coarsened(grid)
        inner = Extrapolated(coarse_system, scheme, dt, thetas, weights, r or 1.0, m, executor,
                             tolerances)
        return OnCoarseGrid(inner, transfer)
    return Extrapolated(system, scheme, dt, thetas, weights, r or 1.0, m, executor, tolerances)
