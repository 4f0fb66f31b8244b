"""Explicit Runge-Kutta time stepping over the System interface (docs/contracts.md).

A scheme is a Butcher tableau applied through ``system.rates`` and ``system.advance`` only, so one
implementation serves every body type (docs/physics.md section 3, "Time stepping"):

- stage states are built from the *old* state with ``advance(x, sum_j a_ij k_j, dt)``;
- the step ends with ``advance(x, sum_j b_j k_j, dt)``.

For positions ``advance`` is ``x + dt * rate``, which makes this the classical Runge-Kutta
method. For rod frames ``advance`` is the exact rotation by ``dt * |w|`` about ``w`` (eq. 13),
which makes it a Runge-Kutta-Munthe-Kaas (RKMK) method on SO(3). RKMK needs no correction up to
order 2, so forward Euler and RK2 (Heun, exactly as docs/physics.md describes: predict with Euler,
evaluate at ``t + dt``, advance the old state by the averaged rates) are plain tableaux. Order 4
on SO(3) needs two commutator terms (Munthe-Kaas 1999; Hairer, Lubich & Wanner, *Geometric
Numerical Integration*, section IV.8):

    k3 = rates(t + dt/2, advance(x, k2/2 - dt/8 [k1, k2], dt))
    x1 = advance(x, (k1 + 2 k2 + 2 k3 + k4)/6 - dt/12 [k1, k4], dt)

A system whose rates live in a non-abelian Lie algebra provides ``bracket(r1, r2)`` (rods: the
cross product of the angular parts, zero for the linear parts); systems without it (vesicles) are
abelian and the terms vanish. Without them, RK4 on rotating frames is only second-order accurate.

``system.project`` (re-orthonormalize frames) is applied to the initial state and to the result of
every propagation, not per step: the rotation update keeps frames orthonormal to round-off (the
drift is a random walk of about 1e-16 per step), and leaving the steps alone keeps each one an exact
RKMK step. Projecting the input makes a propagator safe on states that come straight from a linear
combination (Parareal's correction, extrapolation); for orthonormal input it changes nothing beyond
round-off.

A system type may also have the whole loop of steps in compiled code, registered for its exact
type in :mod:`parastokes.registry.loops` (rods and vesicles): the same tableau, the same parts,
the same checks, without a Python call per stage. :func:`run` uses it when present;
``run(..., compiled=False)`` does not.

The linearly implicit schemes of :mod:`parastokes.stiff` (``lieuler``, ``ros2``,
``ros2-krylov``: Rosenbrock-W methods, one linear solve per stage) are entries of
:data:`SCHEMES` too, usable wherever the explicit ones are; they always take their steps in
Python (:class:`parastokes.stiff.Stepper`), since the stage solves are scipy's. With ``rtol``
(and ``atol``) in place of a fixed step, :func:`run` takes adaptive steps from the embedded
error estimate of a scheme that has one (``ros2``); the step sequence is a deterministic
function of the input.

Blow-up is an error: after every step the state must be finite and ``system.monitor`` must stay
below ``blowup_factor * system.monitor_limit``; otherwise :class:`BlowUpError` names the time, the
step index and the monitor value and keeps the last good state.
"""

from __future__ import annotations

import functools
import logging
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .. import stiff
from ..bodies import contract
from ..core.contracts import StepFailure, System
from ..registry.loops import compiled_loop
from ..stiff import Rosenbrock

__all__ = [
    "SCHEMES",
    "AnyScheme",
    "BlowUpError",
    "Propagator",
    "RunResult",
    "Scheme",
    "explicit_scheme",
    "is_stable",
    "largest_stable_step",
    "n_steps",
    "propagate",
    "run",
    "run_result",
    "scheme_order",
    "step",
    "tolerances",
]

log = logging.getLogger(__name__)

#: Default ratio of monitor value to ``system.monitor_limit`` at which a run is declared blown up.
BLOWUP_FACTOR = 100.0

# A bracket term (coefficient, p, q) contributes coefficient * dt * bracket(k_p, k_q).
Bracket = tuple[float, int, int]


@dataclass(frozen=True)
class Scheme:
    """An explicit Runge-Kutta tableau with optional RKMK commutator corrections.

    ``a[i]`` holds the coefficients of stages ``0..i-1`` for stage ``i`` (``a[0] == ()``), ``b`` the
    final weights, ``c`` the stage times; ``stage_brackets[i]`` and ``final_brackets`` are the
    commutator terms ``(coefficient, p, q)`` described in the module docstring.
    """

    name: str
    order: int
    c: tuple[float, ...]
    a: tuple[tuple[float, ...], ...]
    b: tuple[float, ...]
    stage_brackets: tuple[tuple[Bracket, ...], ...]
    final_brackets: tuple[Bracket, ...] = ()

    #: Explicit: no linear solves (the schemes of :mod:`parastokes.stiff` say True).
    implicit = False

    @property
    def stages(self) -> int:
        return len(self.b)


#: A scheme of :data:`SCHEMES`: an explicit tableau or a linearly implicit one.
AnyScheme = Scheme | Rosenbrock

#: Every scheme by name; each says its ``order`` and whether it is ``implicit``.
SCHEMES: dict[str, AnyScheme] = {
    "euler": Scheme("euler", 1, c=(0.0,), a=((),), b=(1.0,), stage_brackets=((),)),
    "rk2": Scheme(
        "rk2", 2, c=(0.0, 1.0), a=((), (1.0,)), b=(0.5, 0.5), stage_brackets=((), ())
    ),
    "rk4": Scheme(
        "rk4",
        4,
        c=(0.0, 0.5, 0.5, 1.0),
        a=((), (0.5,), (0.0, 0.5), (0.0, 0.0, 1.0)),
        b=(1 / 6, 1 / 3, 1 / 3, 1 / 6),
        stage_brackets=((), (), ((-1 / 8, 0, 1),), ()),
        final_brackets=((-1 / 12, 0, 3),),
    ),
    **stiff.ROSENBROCK,
}


def _scheme(scheme: str | AnyScheme) -> AnyScheme:
    if isinstance(scheme, Scheme | Rosenbrock):
        return scheme
    try:
        return SCHEMES[scheme]
    except KeyError:
        raise ValueError(
            f"scheme: unknown scheme {scheme!r}; choose one of {sorted(SCHEMES)}"
        ) from None


def explicit_scheme(name: str) -> Scheme:
    """The explicit tableau ``name`` (for the compiled and GPU loops, which run tableaux only);
    ValueError naming the scheme for an implicit one."""
    s = _scheme(name)
    if not isinstance(s, Scheme):
        explicit = ", ".join(k for k, v in SCHEMES.items() if not v.implicit)
        raise ValueError(f"scheme: {name!r} is linearly implicit; the GPU and compiled loops run "
                         f"the explicit schemes only ({explicit})")
    return s


def scheme_order(name: str) -> int:
    """Order of accuracy of the named scheme (used by Richardson extrapolation, eq. 26/27)."""
    return _scheme(name).order


class BlowUpError(RuntimeError):
    """A run produced a non-finite state or a monitor far beyond its limit.

    Attributes: ``t`` (time reached by the failing step), ``step`` (its index, counted from 0 within
    the run), ``monitor`` (the monitor value there, ``nan`` for a non-finite state) and
    ``last_state`` (the last good state, at time ``t - dt``).
    """

    def __init__(self, t: float, step: int, monitor: float, last_state: np.ndarray, reason: str):
        super().__init__(
            f"blow-up at t={t:.10g} (step {step}): {reason}; monitor={monitor:.6g}"
        )
        self.t = t
        self.step = step
        self.monitor = monitor
        self.last_state = last_state
        self.reason = reason

    def __reduce__(self):
        # rebuild from the attributes, so the error crosses process boundaries intact
        return type(self), (self.t, self.step, self.monitor, self.last_state, self.reason)


def projected(system: System, x: np.ndarray, t: float, step: int = 0) -> np.ndarray:
    """``system.project(x)``, a state the projection rejects (a ValueError, e.g. a rod frame
    made singular by a step far too large) being a :class:`BlowUpError` at ``t``."""
    try:
        return system.project(x)
    except ValueError as error:
        raise BlowUpError(t, step, math.nan, np.array(x), f"not a valid state ({error})") from None


def _combine(
    system: System,
    coefs: tuple[float, ...],
    k: list[np.ndarray],
    brackets: tuple[Bracket, ...],
    dt: float,
) -> np.ndarray:
    """sum_j coefs[j] k_j + dt * sum coefficient * bracket(k_p, k_q)."""
    terms = [(c, kj) for c, kj in zip(coefs, k, strict=False) if c != 0.0]
    if len(terms) == 1 and terms[0][0] == 1.0 and not brackets:
        return terms[0][1]
    if not terms:  # a stage row of zeros: the stage is evaluated at the step's start state
        r = np.zeros_like(k[0])
    else:
        r = terms[0][0] * terms[0][1]
    for c, kj in terms[1:]:
        r += c * kj
    bracket = getattr(system, "bracket", None)
    if bracket is not None:
        for c, p, q in brackets:
            r += (c * dt) * bracket(k[p], k[q])
    return r


def _rates(system: System, t: float, x: np.ndarray) -> np.ndarray:
    """``system.rates(t, x)``, checked where it enters (real numbers, a row per state row)."""
    return contract.array(system, "rates(t, state)", system.rates(t, x), rows=len(x),
                          ndim=x.ndim, what="one row per state row")


def _advance(system: System, x: np.ndarray, r: np.ndarray, dt: float) -> np.ndarray:
    """``system.advance(x, r, dt)``, checked where it enters (real numbers, the state's shape)."""
    return contract.array(system, "advance(state, rates, dt)", system.advance(x, r, dt),
                          shape=x.shape, what="the state's shape")


def step(system: System, scheme: str | AnyScheme, t: float, x: np.ndarray, dt: float
         ) -> np.ndarray:
    """One step of ``scheme`` from ``(t, x)`` to ``t + dt`` (no projection; what ``rates`` and
    ``advance`` return is checked, :mod:`parastokes.bodies.contract`, not its finiteness)."""
    s = _scheme(scheme)
    if isinstance(s, Rosenbrock):
        return _implicit_stepper(system, s)(t, x, dt)
    k: list[np.ndarray] = [_rates(system, t, x)]
    for i in range(1, s.stages):
        xi = _advance(system, x, _combine(system, s.a[i], k, s.stage_brackets[i], dt), dt)
        k.append(_rates(system, t + s.c[i] * dt, xi))
    return _advance(system, x, _combine(system, s.b, k, s.final_brackets, dt), dt)


def _stiff_blowup(error: stiff.StiffSolveError | stiff.StepSizeError, step: int,
                  x: np.ndarray) -> BlowUpError:
    """A failed stage solve or a step size that shrank to nothing, as the blow-up of a run."""
    if isinstance(error, stiff.StepSizeError):
        reason = f"{error} (adaptive steps); loosen rtol/atol or check the body's forces"
    else:
        reason = str(error)
    return BlowUpError(error.t, step, math.nan, x, reason)


def _checked_stepper(system: System, scheme: Rosenbrock) -> stiff.Stepper:
    """A :class:`parastokes.stiff.Stepper` on the checked ``rates`` and ``advance``."""
    return stiff.Stepper(system, scheme, lambda t, y: _rates(system, t, y),
                         lambda y, r, h: _advance(system, y, r, h))


def _implicit_stepper(system: System, scheme: Rosenbrock):
    """``step(t, x, dt)`` of a linearly implicit scheme: a :class:`parastokes.stiff.Stepper`
    (it keeps the Jacobian and its factorization across the steps of one run) on the checked
    ``rates`` and ``advance``; a failed solve is a :class:`BlowUpError`."""
    stepper = _checked_stepper(system, scheme)

    def take(t: float, x: np.ndarray, dt: float) -> np.ndarray:
        try:
            return stepper.step(t, x, dt)
        except stiff.StiffSolveError as error:
            raise _stiff_blowup(error, stepper.steps, x) from error

    return take


def n_steps(t_start: float, t_end: float, dt: float) -> int:
    """Equal steps used on ``[t_start, t_end]``: ``max(1, round(span/dt))``, and 0 if span = 0."""
    if not dt > 0:
        raise ValueError(f"dt: must be positive, got {dt}")
    span = t_end - t_start
    if span < 0:
        raise ValueError(f"t_end: must not precede t_start, got [{t_start}, {t_end}]")
    if span == 0:
        return 0
    return max(1, round(span / dt))


@dataclass(frozen=True)
class RunResult:
    """Outcome of :func:`run`: final state, largest monitor seen, steps taken and step used."""

    state: np.ndarray
    max_monitor: float
    n_steps: int
    dt: float
    completed: bool = True
    #: Steps rejected by the error control of adaptive steps (``n_steps`` counts the accepted).
    n_rejected: int = 0


#: Outcomes of a loop of steps (:func:`_python_steps`, ``system.run_steps``): all steps taken;
#: stopped after a step whose monitor exceeded ``stop_above`` (kept); a non-finite state; a
#: monitor beyond the blow-up limit (neither kept).
DONE, ABOVE, NON_FINITE, BEYOND = 0, 1, 2, 3


def _monitor(system: System, x: np.ndarray) -> float:
    """``system.monitor(x)``, checked where it enters (a real number; infinite is the sign of a
    point on the wall, NaN of a non-finite state)."""
    return contract.number(system, "monitor(state)", system.monitor(x))


def _python_steps(
    system: System,
    scheme: AnyScheme,
    x: np.ndarray,
    t0: float,
    dt: float,
    n: int,
    limit: float,
    stop_above: float,
) -> tuple[np.ndarray, float, int, int, float]:
    """``n`` steps through ``system.rates``/``system.advance``, checked after each step.

    Returns ``(last state kept, worst monitor, steps kept, outcome, monitor that ended the run)``;
    ``system.run_steps`` (optional, compiled) has the same signature and result.
    """
    worst = _monitor(system, x)
    take = (_implicit_stepper(system, scheme) if isinstance(scheme, Rosenbrock)
            else functools.partial(step, system, scheme))
    for i in range(n):
        try:
            x_new = take(t0 + i * dt, x, dt)
        except StepFailure as error:  # (a failed mobility solve): no result, a blow-up
            raise BlowUpError(t0 + (i + 1) * dt, i, math.nan, x, str(error)) from None
        if not np.isfinite(x_new).all():
            return x, worst, i, NON_FINITE, math.nan
        m = _monitor(system, x_new)
        if not m <= limit:
            return x, worst, i, BEYOND, m
        worst = max(worst, m)
        x = x_new
        if m > stop_above:
            return x, worst, i + 1, ABOVE, m
    return x, worst, n, DONE, worst


def _stepping(
    system: System,
    scheme: AnyScheme,
    x: np.ndarray,
    t0: float,
    dt: float,
    n: int,
    blowup_factor: float,
    stop_above: float | None = None,
    compiled: bool = True,
) -> RunResult:
    """Take ``n`` steps of size ``dt``; stop early (``completed=False``) if monitor > stop_above.

    The steps run in the compiled loop registered for the exact type of ``system`` when there is
    one and ``compiled`` (:mod:`parastokes.registry.loops`: rods, vesicles), else in
    :func:`_python_steps`; both return the same.
    """
    limit = blowup_factor * system.monitor_limit
    shape = x.shape
    x = projected(system, x, t0)
    loop = compiled_loop(system) if compiled and not scheme.implicit else None
    if loop is None:
        x = contract.array(system, "project(state)", x, shape=shape, what="the state's shape")
        loop = functools.partial(_python_steps, system)
    steps = loop(scheme, x, t0, dt, n, limit, math.inf if stop_above is None else stop_above)
    return run_result(system, t0, dt, steps, blowup_factor)


def run_result(
    system: System,
    t0: float,
    dt: float,
    steps: tuple[np.ndarray, float, int, int, float],
    blowup_factor: float = BLOWUP_FACTOR,
) -> RunResult:
    """The :class:`RunResult` of a loop of steps from ``t0`` (``steps``: what ``run_steps``
    returns), or the :class:`BlowUpError` it ended with. Also used by the GPU backend
    (:mod:`parastokes.gpu`), whose batched loops return the same tuples."""
    x, worst, taken, outcome, m = steps
    t = t0 + (taken + 1) * dt
    if outcome == NON_FINITE:
        reason = "non-finite state" + contract.culprit(system, t - dt, x)
        raise BlowUpError(t, taken, math.nan, x, reason)
    if outcome == BEYOND:
        reason = f"monitor beyond {blowup_factor:g} x its limit {system.monitor_limit:g}"
        if m == math.inf:  # the monitors' sign of a point on or below the wall z = 0
            reason += " (infinite: a point reached the wall z = 0)"
        raise BlowUpError(t, taken, m, x, reason)
    end = projected(system, x, t0 + taken * dt, max(taken - 1, 0))
    return RunResult(end, worst, taken, dt, completed=outcome == DONE)


def run(
    system: System,
    x: np.ndarray,
    t0: float,
    t1: float,
    scheme: str | AnyScheme,
    dt: float,
    *,
    blowup_factor: float = BLOWUP_FACTOR,
    compiled: bool = True,
    rtol: float | None = None,
    atol: float | None = None,
) -> RunResult:
    """Integrate from ``t0`` to ``t1`` with equal steps closest to ``dt``; report the worst monitor.

    With ``rtol`` (``atol`` defaults to ``rtol``): adaptive steps of a scheme with an error
    estimate instead (:func:`parastokes.stiff.adaptive_steps`, ``dt`` the first step tried);
    ``n_steps`` of the result counts the accepted steps, ``n_rejected`` the rejected ones.

    The step actually used is ``(t1 - t0) / n_steps(t0, t1, dt)``; a change is logged (DEBUG).
    The initial and the final state are projected (``system.project``). Raises
    :class:`BlowUpError` on blow-up. ``compiled=False`` takes the steps through the system's
    ``rates`` and ``advance`` in Python even when it has a compiled loop (``run_steps``), e.g. to
    check one against the other: both give the same result.
    """
    s = _scheme(scheme)
    n = n_steps(t0, t1, dt)
    if rtol is not None and n:
        return _adaptive(system, s, np.asarray(x, dtype=float), t0, t1, dt,
                         tolerances(s, rtol, atol), blowup_factor)
    if n == 0:
        return RunResult(system.project(np.array(x, dtype=float)), system.monitor(x), 0, dt)
    h = (t1 - t0) / n
    if abs(h - dt) > 1e-12 * dt:
        log.debug("step adjusted from %.6g to %.6g: %d steps divide [%g, %g]", dt, h, n, t0, t1)
    return _stepping(
        system, s, np.asarray(x, dtype=float), t0, h, n, blowup_factor, compiled=compiled
    )


def tolerances(scheme: str | AnyScheme, rtol: float, atol: float | None
               ) -> tuple[float, float]:
    """``(rtol, atol)`` checked for the adaptive steps of ``scheme``: finite and positive
    (``atol`` None: ``rtol``), and a scheme with an error estimate (ValueError naming the key)."""
    s = _scheme(scheme)
    atol = rtol if atol is None else atol
    for name, value in (("rtol", rtol), ("atol", atol)):
        if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
            raise ValueError(f"{name}: must be a finite number > 0, got {value!r}")
    if getattr(s, "b_low", None) is None:
        adaptive = sorted(k for k, v in SCHEMES.items() if getattr(v, "b_low", None) is not None)
        raise ValueError(f"rtol: the scheme {s.name!r} has no error estimate for adaptive "
                         f"steps; use one of {adaptive}, or a fixed step without rtol/atol")
    return float(rtol), float(atol)


def _adaptive(system: System, scheme: AnyScheme, x: np.ndarray, t0: float, t1: float,
              dt: float, tol: tuple[float, float], blowup_factor: float) -> RunResult:
    """:func:`run` with adaptive steps (see there): every accepted state is checked as the
    fixed steps' are (finite, monitor within ``blowup_factor`` times the limit; a state beyond
    it is a rejected step, halved)."""
    assert isinstance(scheme, Rosenbrock)
    limit = blowup_factor * system.monitor_limit
    x = projected(system, x, t0)
    worst = [_monitor(system, x)]
    stepper = _checked_stepper(system, scheme)

    def accept(t: float, x_new: np.ndarray, index: int) -> bool:
        if not np.isfinite(x_new).all():
            return False
        m = _monitor(system, x_new)
        if not m <= limit:
            return False
        worst[0] = max(worst[0], m)
        return True

    try:
        end, counts = stiff.adaptive_steps(stepper, x, t0, t1, dt, *tol, accept)
    except (stiff.StiffSolveError, stiff.StepSizeError) as error:
        raise _stiff_blowup(error, stepper.steps, x) from error
    except StepFailure as error:  # (a failed mobility solve): no result, a blow-up
        raise BlowUpError(t0, stepper.steps, math.nan, x, str(error)) from None
    log.debug("adaptive %s on [%g, %g]: %d steps accepted, %d rejected", scheme.name, t0, t1,
              counts.accepted, counts.rejected)
    return RunResult(projected(system, end, t1), worst[0], counts.accepted, counts.last_step,
                     n_rejected=counts.rejected)


def propagate(
    system: System,
    x: np.ndarray,
    t0: float,
    t1: float,
    scheme: str | AnyScheme,
    dt: float,
    *,
    blowup_factor: float = BLOWUP_FACTOR,
    rtol: float | None = None,
    atol: float | None = None,
) -> np.ndarray:
    """The state at ``t1`` of the run of :func:`run` (fixed public name, design.md)."""
    return run(system, x, t0, t1, scheme, dt, blowup_factor=blowup_factor, rtol=rtol,
               atol=atol).state


@dataclass(frozen=True)
class Propagator:
    """A picklable solver ``P(t_start, t_end, x) -> x`` (fine F or auxiliary G): fixed steps
    closest to ``dt``, or with ``rtol`` (and ``atol``) adaptive steps from a first step ``dt``."""

    system: System
    scheme: str
    dt: float
    blowup_factor: float = BLOWUP_FACTOR
    rtol: float | None = None
    atol: float | None = None

    def __post_init__(self) -> None:
        _scheme(self.scheme)
        if not self.dt > 0:
            raise ValueError(f"dt: must be positive, got {self.dt}")
        if self.rtol is not None or self.atol is not None:
            tolerances(self.scheme, self.rtol if self.rtol is not None else math.nan, self.atol)

    @property
    def order(self) -> int:
        return scheme_order(self.scheme)

    def n_steps(self, t_start: float, t_end: float) -> int:
        """Number of equal steps actually taken on ``[t_start, t_end]``."""
        return n_steps(t_start, t_end, self.dt)

    def __call__(self, t_start: float, t_end: float, x: np.ndarray) -> np.ndarray:
        return propagate(self.system, x, t_start, t_end, self.scheme, self.dt,
                         blowup_factor=self.blowup_factor, rtol=self.rtol, atol=self.atol)

    def run(self, t_start: float, t_end: float, x: np.ndarray) -> RunResult:
        """The :class:`RunResult` of the propagation (steps taken, and rejected with ``rtol``)."""
        return run(self.system, x, t_start, t_end, self.scheme, self.dt,
                   blowup_factor=self.blowup_factor, rtol=self.rtol, atol=self.atol)


def is_stable(
    system: System,
    scheme: str | AnyScheme,
    dt: float,
    t_span: float,
    *,
    x0: np.ndarray | None = None,
    t0: float = 0.0,
    limit: float | None = None,
) -> bool:
    """Whether ``ceil(t_span/dt)`` steps of exactly ``dt`` keep the monitor within ``limit``
    (default: the system's ``monitor_limit``)."""
    limit = system.monitor_limit if limit is None else limit
    worst = _worst_monitor(system, scheme, dt, t_span, x0, t0, limit)
    return worst is not None and worst <= limit


def _worst_monitor(system: System, scheme: str | AnyScheme, dt: float, t_span: float,
                   x0: np.ndarray | None, t0: float, stop_above: float) -> float | None:
    """The largest monitor over ``ceil(t_span/dt)`` steps of ``dt``; None if it blew up or went
    above ``stop_above`` (the run stops there)."""
    x = system.initial_state() if x0 is None else np.asarray(x0, dtype=float)
    n = max(1, math.ceil(t_span / dt - 1e-9))
    try:
        res = _stepping(system, _scheme(scheme), x, t0, dt, n, BLOWUP_FACTOR,
                        stop_above=stop_above)
    except BlowUpError:
        return None
    return res.max_monitor if res.completed else None


def largest_stable_step(
    system: System,
    scheme: str | AnyScheme,
    t_span: float,
    dt_lo: float,
    dt_hi: float,
    *,
    x0: np.ndarray | None = None,
    t0: float = 0.0,
    rtol: float = 0.05,
    relative: bool = False,
    stop: Callable[[], None] | None = None,
) -> float:
    """Largest step in ``[dt_lo, dt_hi]`` keeping the monitor within ``system.monitor_limit``
    (``relative``: within the limit of its value at ``dt_lo``, i.e. of the body's own change,
    for bodies whose monitor changes physically: a vesicle of perturbed viscosity deforms more).

    Bisects geometrically on runs of length ``t_span`` (steps of exactly dt, see
    :func:`is_stable`) until the bracket is narrower than ``rtol``: the result passes and a step at
    most ``result * (1 + rtol)`` failed. The paper picks its coarse steps "close to the largest time
    step permitted" (section 5.1.1, Fig. 3) with the limits of docs/physics.md (rod length 1%,
    vesicle area 0.01%). ``dt_lo`` must pass (ValueError otherwise); if ``dt_hi`` passes it is
    returned with a warning. ``stop`` is called before every trial run (a caller's budget: it
    raises to abandon the search).
    """
    if not 0 < dt_lo < dt_hi:
        raise ValueError(f"dt_lo, dt_hi: need 0 < dt_lo < dt_hi, got {dt_lo}, {dt_hi}")
    if not t_span > 0:
        raise ValueError(f"t_span: must be positive, got {t_span}")
    if not rtol > 0:
        raise ValueError(f"rtol: must be positive, got {rtol}")

    check = stop or (lambda: None)
    threshold = None
    if relative:  # the run at dt_lo sets the threshold, so it passes by construction
        check()
        physical = _worst_monitor(system, scheme, dt_lo, t_span, x0, t0, math.inf)
        if physical is None:
            raise ValueError(f"dt_lo: {dt_lo:g} is not stable over t_span={t_span:g}")
        threshold = system.monitor_limit + physical

    def ok(dt: float) -> bool:
        check()
        return is_stable(system, scheme, dt, t_span, x0=x0, t0=t0, limit=threshold)

    if not relative and not ok(dt_lo):
        raise ValueError(f"dt_lo: {dt_lo:g} is not stable over t_span={t_span:g}")
    if ok(dt_hi):
        log.warning("largest_stable_step: dt_hi=%g is stable; the limit lies above it", dt_hi)
        return dt_hi
    lo, hi = dt_lo, dt_hi
    while hi > lo * (1 + rtol):
        mid = math.sqrt(lo * hi)
        if ok(mid):
            lo = mid
        else:
            hi = mid
    return lo
