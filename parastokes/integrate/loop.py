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

:class:`CompiledPair` runs the adaptive steps of an embedded explicit pair on the same parts
(:func:`_adaptive`), as :func:`parastokes.integrate.controller.adaptive_steps` takes them in
Python: the same steps, bit for bit, since both call the controller's compiled error norm and
step factor (docs/stiff.md, "Adaptive explicit pairs").

numba caches each compiled function keyed on its own source file only: after editing a system's
parts (or anything they call, the arithmetic of :mod:`.controller` included; its constants are
read at each call) in another file, delete the ``__pycache__`` folders before timing or
testing, or the cached loop still runs the old parts. A fresh checkout or install has no cache.
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
from . import controller
from .base import ABOVE, BEYOND, DONE, NON_FINITE
from .controller import AdaptiveResult, StepSizeError
from .schemes import Scheme

__all__ = [
    "CompiledPair",
    "advance",
    "body_rates_into",
    "bracket_into",
    "compiled_pair",
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


#: Slots of the ``carry`` array of :func:`_adaptive` (what a call hands to the next).
T, H, PREVIOUS, KNOWN, ACCEPTED, REJECTED, WORST, LAST, EVALUATIONS = range(9)
#: ``carry[KNOWN]``: nothing known at (t, x); ``k[0]`` (the first stage of a rejected step);
#: ``k[-1]`` (the last stage of an accepted step of a first-same-as-last pair).
UNKNOWN, FIRST, FSAL = 0.0, 1.0, 2.0
#: Outcomes of :func:`_adaptive`: ``t1`` reached, paused after ``pause`` accepted steps, the
#: step shrank below the smallest one.
REACHED, PAUSED, TOO_SMALL = 0, 1, 2


@njit(**_OPTS)
def _adaptive(x, k, carry, t1, pause, tableau, low, data, control, constants, limit):
    """Adaptive steps of an embedded pair from ``(carry[T], x)`` toward ``t1``, as
    :func:`parastokes.integrate.controller.adaptive_steps` takes them through
    :class:`parastokes.integrate.explicit.PairStepper` and :class:`.adaptive.Watch`: the same
    stages, solutions, error norm, controller (``control`` = ``(q, rtol, atol, pi, smallest
    step, fsal)``, ``constants`` those of :func:`.controller.constants`), first-same-as-last
    and retried first stages, the last step cut to land on ``t1``, a state non-finite or whose
    monitor exceeds ``limit`` rejected.

    ``k`` (s, n, columns) holds the stages of the last step tried; ``carry`` (in and out) the
    time, next step, last accepted error (PI), which stage is known at ``(t, x)``, the counts,
    the worst monitor, the last accepted step and the rate evaluations. Returns
    :data:`REACHED`, :data:`PAUSED` (after ``pause`` accepted steps before ``t1``) or
    :data:`TOO_SMALL`; the state reached is written into ``x``.
    """
    c, a, b, stage_brackets, final_brackets = tableau
    b_low, low_brackets = low
    q, rtol, atol, pi, smallest, fsal = (int(control[0]), control[1], control[2],
                                         control[3] != 0.0, control[4], control[5] != 0.0)
    s = b.size
    comb = np.empty((x.shape[0], data.rate_columns))
    work = workspace(data, x)
    state = x
    t, h, previous, known = carry[T], carry[H], carry[PREVIOUS], carry[KNOWN]
    taken, outcome = 0, REACHED
    while t < t1:
        last = controller.lands(t, h, t1)
        step = t1 - t if last else h
        if known == FSAL:
            k[0, :, :] = k[s - 1]
        elif known == UNKNOWN:
            rates_into(data, t, state, work, k[0])
            carry[EVALUATIONS] += 1
        carry[EVALUATIONS] += s - 1
        for st in range(1, s):
            _combine(data, a[st, :st], k, stage_brackets, st, step, comb)
            rates_into(data, t + c[st] * step, advance(data, state, comb, step), work, k[st])
        _combine(data, b, k, final_brackets, -1, step, comb)
        x_new = advance(data, state, comb, step)
        _combine(data, b_low, k, low_brackets, -1, step, comb)
        err = controller.error_norm(state, x_new, advance(data, state, comb, step), rtol, atol)
        if not np.isfinite(err):
            err = np.inf
        ok = err <= 1.0 and _finite(x_new)
        m = monitor(data, x_new) if ok else math.nan
        ok = ok and m <= limit
        h = step * controller.step_factor(err, q, ok, previous, constants)
        if ok:
            t = t1 if last else t + step
            state = x_new
            carry[ACCEPTED] += 1
            carry[WORST] = max(carry[WORST], m)
            carry[LAST] = step
            previous = max(err, constants[6]) if pi else 0.0
            known = FSAL if fsal else UNKNOWN
            taken += 1
        else:
            carry[REJECTED] += 1
            known = FIRST
        if h < smallest:
            outcome = TOO_SMALL
            break
        if ok and t < t1 and taken >= pause:
            outcome = PAUSED
            break
    carry[T], carry[H], carry[PREVIOUS], carry[KNOWN] = t, h, previous, known
    x[:] = state
    return outcome


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


def _loop_for(data: tuple, loop: Any = None) -> Any:
    """The compiled ``loop`` (default :func:`_run`; :func:`_adaptive`) for ``data``: itself for
    the package's types, and for data with types from other modules (a user's body,
    docs/extending.md) a copy of it per set of such modules, cached in its own index file named
    after them.

    numba keeps one cache index per function, keyed by the argument types, and unpickles every
    key when it reads the index: a user's type in ``_run``'s index would make every later process
    that cannot import the user's module fail to load any compiled loop. In an index of their own
    the user's types are read only where the user's data is stepped, so their module is loaded.
    """
    loop = _run if loop is None else loop
    modules = tuple(sorted(_foreign_modules(data)))
    if not modules:
        return loop
    key = (loop.py_func.__name__, *modules)
    if key not in _FOREIGN_LOOPS:
        code = loop.py_func
        copy = types.FunctionType(code.__code__, code.__globals__, code.__name__,
                                  code.__defaults__, code.__closure__)
        copy.__qualname__ = f"{code.__name__}_for_" + "__".join(m.replace(".", "_")
                                                                for m in modules)
        copy.__doc__ = code.__doc__
        _FOREIGN_LOOPS[key] = njit(**_OPTS)(copy)
    return _FOREIGN_LOOPS[key]


#: Wall time aimed at per compiled call: the loop returns to Python this often, so that Ctrl-C
#: (and any other signal) is handled within about a second during a long propagation.
CALL_SECONDS = 0.25


def _next_chunk(chunk: int, start: float, taken: int) -> int:
    """The steps of the next compiled call: about :data:`CALL_SECONDS` at the time per step of
    the call begun at ``start`` (``taken`` steps), at most 4 times the last call's ``chunk``."""
    per_step = (time.perf_counter() - start) / max(taken, 1)
    return max(1, min(4 * chunk, int(CALL_SECONDS / max(per_step, 1e-9))))


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
            chunk = _next_chunk(chunk, start, taken)


class CompiledPair:
    """Adaptive steps of an explicit embedded pair on a system's compiled parts
    (:func:`_adaptive`): what :func:`parastokes.integrate.controller.adaptive_steps` does with a
    :class:`parastokes.integrate.explicit.PairStepper`, the same steps (tested: counts equal,
    states equal to round-off), in compiled calls of about :data:`CALL_SECONDS`, or of
    ``every`` accepted steps each where ``until`` watches the steps.

    ``steps`` counts the steps tried and ``evaluations`` the rate evaluations; ``k`` (s, n,
    columns) holds the stages of the last step (as ``PairStepper.k``)."""

    def __init__(self, system: ThreadedSystem, make_data: Callable[[Any, int], tuple],
                 scheme: Scheme) -> None:
        assert scheme.b_low is not None
        self.system, self.make_data, self.scheme = system, make_data, scheme
        self.steps = self.evaluations = 0
        self.k = np.empty((scheme.stages, 0, 0))
        #: Where the last call ended, ``(t, the state returned)``, and what was known there.
        self._end: tuple[float, np.ndarray | None] = (math.nan, None)
        self._known = UNKNOWN

    def steps_from(self, x: np.ndarray, t0: float, t1: float, h0: float, q: int,
                   tol: tuple[float, float], limit: float, worst: float,
                   until: Callable[[float, np.ndarray, float, float], bool] | None = None,
                   pi: bool = True, every: int = 1, previous: float | None = None
                   ) -> tuple[np.ndarray, AdaptiveResult, float]:
        """The steps of :func:`.controller.adaptive_steps` (the same arguments; ``limit`` the
        monitor's, ``worst`` the worst monitor so far): the state reached, the counts, and the
        worst monitor seen. Raises :class:`.controller.StepSizeError` as it does. From the
        state the last call returned (the same array, at its end), the stage known there is
        used, as a :class:`parastokes.integrate.explicit.PairStepper` does."""
        s = self.scheme
        known = self._known if x is self._end[1] and t0 == self._end[0] else UNKNOWN
        x = np.array(x, dtype=float, order="C")  # the compiled calls write the state into it
        tableau = tableau_arrays(s)
        low = (np.array(s.b_low, dtype=float),
               np.array(s.low_brackets, dtype=float).reshape(-1, 3))
        control = np.array([q, tol[0], tol[1], pi, controller.smallest_step(t0, t1), s.fsal],
                           dtype=float)
        carry = np.array([t0, min(h0, t1 - t0), previous if pi and previous else 0.0, known,
                          0, 0, worst, math.nan, 0])
        chunk = every if until is not None else 8
        steps, evaluations = self.steps, self.evaluations
        with kernel_threads(self.system.n_threads) as threads:
            data: Any = self.make_data(self.system, threads)
            loop = _loop_for(data, _adaptive)
            if known == UNKNOWN:
                self.k = np.empty((s.stages, x.shape[0], data.rate_columns))
            while True:
                start, before = time.perf_counter(), carry[ACCEPTED]
                outcome = loop(x, self.k, carry, float(t1), chunk, tableau, low, data, control,
                               controller.constants(), float(limit))
                self.steps = steps + int(carry[ACCEPTED] + carry[REJECTED])
                self.evaluations = evaluations + int(carry[EVALUATIONS])
                if outcome == TOO_SMALL:
                    raise StepSizeError(carry[T], carry[H])
                if outcome == REACHED:
                    break
                if until is None:
                    chunk = _next_chunk(chunk, start, int(carry[ACCEPTED] - before))
                elif until(carry[T], x, carry[LAST], carry[H]):
                    break
        self._end, self._known = (carry[T], x), carry[KNOWN]
        result = AdaptiveResult(int(carry[ACCEPTED]), int(carry[REJECTED]), carry[H], carry[T],
                                carry[PREVIOUS] if pi and carry[PREVIOUS] > 0 else None)
        return x, result, carry[WORST]


def compiled_pair(system: System, scheme: Scheme) -> CompiledPair | None:
    """The compiled adaptive steps of the pair ``scheme`` for ``system``, where its exact type
    has a compiled loop of this module (:func:`register_parts`, a scene's), else None."""
    loop = registry.compiled_loop(system)
    if not (isinstance(loop, functools.partial) and loop.func is run_steps):
        return None
    owner, make_data = loop.args
    return CompiledPair(owner, make_data, scheme)


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
