"""The loop of Runge-Kutta steps in compiled code, generic over the system.

:func:`parastokes.integrate.run` takes its steps through ``system.rates`` and
``system.advance``, one Python call each per stage. For the paper's rod fine solve (10^6 RK2
steps of ~0.5 ms) that Python (packing the kernel's input, building the stage states, the
per-step checks) cost 20-35% of the two kernel evaluations of a step. :func:`run_steps` runs the
same tableau (including the RKMK commutator terms of RK4, see :mod:`parastokes.integrate`) in one
compiled call, exactly as :func:`parastokes.integrate.runs._python_steps` does:

- stage ``i``'s state is ``advance(x, Σ_j a_ij k_j + brackets, dt)`` of the old state and its
  rates ``k_i`` are evaluated at ``t + c_i dt``; the step ends with ``advance(x, Σ_j b_j k_j +
  brackets, dt)``; the rates are combined as ``integrate`` combines them (zero coefficients
  skipped, terms added in order, no fused multiply-add), so the results are the same bits;
- after each step: the finiteness check and the monitor, stopping at the first failure with the
  last good state kept (or after the step whose monitor exceeds ``stop_above``).

What is specific to a system are four compiled parts (six to join a scene), chosen by the type
of the system's
``data`` (a ``NamedTuple`` of arrays and numbers built once per call) through
``numba.extending.overload``: :func:`rates_into`, :func:`advance`, :func:`monitor` and
:func:`bracket_into`; and :func:`workspace`, the scratch arrays that ``rates_into`` reuses. A system
registers them for its data type (:mod:`parastokes.kinds.rod.compiled`,
:mod:`parastokes.kinds.vesicle.compiled`, :mod:`parastokes.kinds.chain.stepping`) and must
run the same compiled functions as its Python ``rates``/``advance``/``monitor``, so that both
loops agree bit for bit (tested). A body that
also supplies :func:`loads_into` and :func:`body_rates_into` (its Python ``loads`` and
``body_rates``) can be stepped in a scene's compiled loop (:mod:`parastokes.scene.compiled`);
:func:`register_parts` registers its type for both loops.

numba caches each compiled function keyed on its own source file only: after editing a system's
parts (or anything they call) in another file, delete the ``__pycache__`` folders before timing
or testing, or the cached loop still runs the old parts. A fresh checkout or install has no cache.
"""

from __future__ import annotations

import functools
import math
import time
import types
from collections.abc import Callable
from typing import Any, Protocol

import numpy as np
from numba import njit

from ..core.contracts import System
from ..fluid.compiled import pack_points
from ..mrs import compiled
from ..mrs.velocity import EIGHT_PI, kernel_threads
from ..registry import loops as registry
from .base import ABOVE, BEYOND, DONE, NON_FINITE
from .schemes import Scheme

__all__ = [
    "advance",
    "body_rates_into",
    "bracket_into",
    "kernel_arguments",
    "loads_into",
    "monitor",
    "pack_points",
    "rates_into",
    "register_parts",
    "run_steps",
    "tableau_arrays",
    "workspace",
]

_OPTS = dict(cache=True, error_model="numpy")


class InFluid(Protocol):
    """What the kernels take of a body: its regularization ε and the fluid's viscosity μ."""

    @property
    def epsilon(self) -> float: ...

    @property
    def viscosity(self) -> float: ...


class ThreadedSystem(System, Protocol):
    """A :class:`~parastokes.core.contracts.System` whose kernels run on ``n_threads`` threads."""

    @property
    def n_threads(self) -> int | None: ...


# ---- the parts a system supplies (numba.extending.overload on its data type) ------------------
def workspace(data, x):
    """Scratch arrays for :func:`rates_into` (a tuple), allocated once per :func:`run_steps`."""
    raise NotImplementedError("compiled only: register an overload for the system's data type")


def rates_into(data, t, x, work, out):
    """The system's ``rates(t, x)`` written into ``out`` (n, data.rate_columns)."""
    raise NotImplementedError("compiled only: register an overload for the system's data type")


def advance(data, x, rates, dt):
    """The system's ``advance(x, rates, dt)``: a new state array."""
    raise NotImplementedError("compiled only: register an overload for the system's data type")


def monitor(data, x):
    """The system's stability monitor ``monitor(x)`` (a float)."""
    raise NotImplementedError("compiled only: register an overload for the system's data type")


def bracket_into(data, out, kp, kq, h):
    """Add ``h * bracket(kp, kq)`` to ``out`` (nothing for abelian systems)."""
    raise NotImplementedError("compiled only: register an overload for the system's data type")


def loads_into(data, t, x, forces, torques):
    """The system's point loads on the fluid at time ``t`` (its ``loads``): forces written into
    ``forces`` (n, 3), torques into ``torques`` (n, 3) by bodies that have them (others leave
    it alone). For a scene's loop, which sums all bodies' loads in one kernel call."""
    raise NotImplementedError("compiled only: register an overload for the system's data type")


def body_rates_into(data, u, w, out):
    """The system's rates from the fluid's velocity ``u`` and angular velocity ``w`` (n, 3) at
    its points, background flow included (its ``body_rates``), into ``out``
    (n, data.rate_columns). For a scene's loop."""
    raise NotImplementedError("compiled only: register an overload for the system's data type")


def is_data(numba_type, cls: type) -> bool:
    """Whether ``numba_type`` is the numba type of instances of the ``NamedTuple`` ``cls``: the
    test each system's overloads use to claim their data type."""
    return getattr(numba_type, "instance_class", None) is cls


def kernel_arguments(
    system: InFluid, n_points: int, threads: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(eps, denom, starts)`` as ``mrs.velocity`` passes them to the kernels for ``system``'s
    ε and μ (one system: (1,) arrays, denom = 8πμ) and ``n_points`` targets on ``threads``
    threads; ``starts[-1]`` is the padded target count."""
    return (
        np.full(1, float(system.epsilon)),
        np.full(1, EIGHT_PI * system.viscosity),
        compiled.tile_starts(compiled.padded_size(n_points), threads),
    )


# ---- the generic loop -------------------------------------------------------------------------
def tableau_arrays(scheme: Scheme) -> tuple[np.ndarray, ...]:
    """A :class:`parastokes.integrate.Scheme` as arrays: ``c`` (s,), ``a`` (s, s), ``b`` (s,),
    stage brackets (m, 4) rows ``(stage, coefficient, p, q)``, final brackets (m', 3) rows
    ``(coefficient, p, q)``."""
    s = scheme.stages
    a = np.zeros((s, s))
    for i, row in enumerate(scheme.a):
        a[i, : len(row)] = row
    stage = [(i, c, p, q) for i, terms in enumerate(scheme.stage_brackets) for c, p, q in terms]
    return (
        np.array(scheme.c, dtype=float),
        a,
        np.array(scheme.b, dtype=float),
        np.array(stage, dtype=float).reshape(-1, 4),
        np.array(scheme.final_brackets, dtype=float).reshape(-1, 3),
    )


@njit(error_model="numpy")  # not cached on its own: compiled into each cached loop (see _loop_for)
def _combine(data, coefs, k, brackets, stage, dt, out):
    """``integrate.explicit.combine`` into ``out``: Σ_j coefs[j] k_j (non-zero terms, in order) plus
    ``coefficient * dt * bracket(k_p, k_q)`` for the bracket rows of this ``stage`` (-1: the
    final combination, whose rows have no stage column)."""
    first = True
    for j in range(coefs.size):
        c = coefs[j]
        if c == 0.0:
            continue
        for i in range(out.shape[0]):
            for q in range(out.shape[1]):
                out[i, q] = c * k[j, i, q] if first else out[i, q] + c * k[j, i, q]
        first = False
    if first:  # no non-zero coefficient: zero rates (the Python _combine gives the same)
        out[:] = 0.0
    off = 0 if stage < 0 else 1
    for row in range(brackets.shape[0]):
        if stage < 0 or brackets[row, 0] == stage:
            p = int(brackets[row, off + 1])
            q = int(brackets[row, off + 2])
            bracket_into(data, out, k[p], k[q], brackets[row, off] * dt)


@njit(**_OPTS)
def _finite(x):
    for v in x.flat:
        if not np.isfinite(v):
            return False
    return True


@njit(**_OPTS)
def _run(x, t0, dt, first, n_steps, tableau, data, limit, stop_above):
    """Steps ``first .. first + n_steps - 1`` of a run from ``t0`` (step ``i`` starts at
    ``t0 + i dt``, as in the Python loop), from the state ``x`` at step ``first``.

    The last state kept is written into ``x``; returns ``(worst monitor, steps kept, outcome,
    monitor that ended the call)``. (Returning only numbers keeps Python out of the call: boxing a
    new array calls back into the interpreter, where a pending Ctrl-C would surface as a
    SystemError instead of a KeyboardInterrupt.)
    """
    c, a, b, stage_brackets, final_brackets = tableau
    k = np.empty((b.size, x.shape[0], data.rate_columns))
    comb = np.empty((x.shape[0], data.rate_columns))
    work = workspace(data, x)
    state = x
    worst = monitor(data, state)
    taken, outcome, m = n_steps, DONE, worst
    for i in range(n_steps):
        t = t0 + (first + i) * dt
        rates_into(data, t, state, work, k[0])
        for st in range(1, b.size):
            _combine(data, a[st, :st], k, stage_brackets, st, dt, comb)
            rates_into(data, t + c[st] * dt, advance(data, state, comb, dt), work, k[st])
        _combine(data, b, k, final_brackets, -1, dt, comb)
        x_new = advance(data, state, comb, dt)
        if not _finite(x_new):
            taken, outcome, m = i, NON_FINITE, math.nan
            break
        m = monitor(data, x_new)
        if not m <= limit:
            taken, outcome = i, BEYOND
            break
        worst = max(worst, m)
        state = x_new
        if m > stop_above:
            taken, outcome = i + 1, ABOVE
            break
    if outcome == DONE:
        m = worst
    x[:] = state
    return worst, taken, outcome, m


_FOREIGN_LOOPS: dict[tuple[str, ...], Any] = {}


def _foreign_modules(value: Any) -> set[str]:
    """The modules outside parastokes that define the tuple types in ``value`` (a system's data:
    named tuples of arrays, numbers and tuples, a scene's holding its bodies')."""
    found = set()
    if isinstance(value, tuple):
        module = type(value).__module__
        if type(value) is not tuple and module.partition(".")[0] != "parastokes":
            found.add(module)
        for item in value:
            found |= _foreign_modules(item)
    return found


def _loop_for(data: tuple) -> Any:
    """The compiled :func:`_run` for ``data``: itself for the package's types, and for data with
    types from other modules (a user's body, docs/extending.md) a copy of it per set of such
    modules, cached in its own index file named after them.

    numba keeps one cache index per function, keyed by the argument types, and unpickles every
    key when it reads the index: a user's type in ``_run``'s index would make every later process
    that cannot import the user's module fail to load any compiled loop. In an index of their own
    the user's types are read only where the user's data is stepped, so their module is loaded.
    """
    key = tuple(sorted(_foreign_modules(data)))
    if not key:
        return _run
    if key not in _FOREIGN_LOOPS:
        code = _run.py_func
        copy = types.FunctionType(code.__code__, code.__globals__, code.__name__,
                                  code.__defaults__, code.__closure__)
        copy.__qualname__ = "_run_for_" + "__".join(m.replace(".", "_") for m in key)
        copy.__doc__ = code.__doc__
        _FOREIGN_LOOPS[key] = njit(**_OPTS)(copy)
    return _FOREIGN_LOOPS[key]


#: Wall time aimed at per compiled call: the loop returns to Python this often, so that Ctrl-C
#: (and any other signal) is handled within about a second during a long propagation.
CALL_SECONDS = 0.25


def run_steps(
    system: ThreadedSystem,
    make_data: Callable[[Any, int], tuple],
    scheme: Scheme,
    x: np.ndarray,
    t0: float,
    dt: float,
    n: int,
    limit: float,
    stop_above: float,
) -> tuple[np.ndarray, float, int, int, float]:
    """``n`` steps of ``scheme`` from ``(t0, x)``, the kernels on ``system.n_threads`` threads;
    ``make_data(system, threads)`` builds the system's compiled data.

    Returns what :func:`parastokes.integrate.runs._python_steps` returns: ``(last state kept, worst
    monitor, steps kept, outcome, monitor that ended the run)``, the outcome one of
    ``integrate.DONE``, ``ABOVE``, ``NON_FINITE``, ``BEYOND`` (``nan`` monitor for a non-finite
    state). The steps run in compiled calls of about :data:`CALL_SECONDS` each (the first ones
    shorter, while the time per step is measured), so that a long run still answers Ctrl-C; the
    result does not depend on how the steps are split.
    """
    x = np.array(x, dtype=float, order="C")  # the compiled calls write the state into it
    tableau = tableau_arrays(scheme)
    done, worst, chunk = 0, -math.inf, 8
    with kernel_threads(system.n_threads) as threads:
        data = make_data(system, threads)
        steps = _loop_for(data)
        while True:  # calls of about CALL_SECONDS each, steps numbered from t0 throughout
            start = time.perf_counter()
            chunk_worst, taken, outcome, m = steps(
                x, float(t0), float(dt), done, min(chunk, n - done), tableau, data,
                float(limit), float(stop_above),
            )
            worst = max(worst, chunk_worst)
            done += taken
            if outcome != DONE:
                return x, worst, done, outcome, m
            if done == n:
                return x, worst, done, DONE, worst
            per_step = (time.perf_counter() - start) / max(taken, 1)
            chunk = max(1, min(4 * chunk, int(CALL_SECONDS / max(per_step, 1e-9))))


def register_parts(cls: type, make_data: Callable[[Any, int], tuple], fluid: type | None = None,
                   *, in_scenes: bool = False) -> None:
    """Step systems of exactly the type ``cls`` whose fluid is exactly of the type ``fluid``
    (None: systems without a ``fluid``) with :func:`run_steps` on ``make_data(system, threads)``;
    with ``in_scenes`` (the type also has :func:`loads_into` and :func:`body_rates_into`), let
    scenes compose its parts (:func:`parastokes.registry.loops.register_data`)."""
    registry.register(cls, lambda system: functools.partial(run_steps, system, make_data),
                      fluid=fluid)
    if in_scenes:
        registry.register_data(cls, make_data)
