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
error estimate of a scheme that has one (``SCHEMES[name].adaptive``: the explicit pairs ``rk23``
of Bogacki & Shampine and ``rk45`` of Dormand & Prince, ``ros2``, ``ros2-krylov``), all sized
by the one controller of :mod:`.controller`; the step sequence is a deterministic function of
the input; a pair's adaptive steps run in the system's compiled loop where it has one (the same
steps, :class:`.loop.CompiledPair`). A pair on a fixed step (no ``rtol``) runs its high-order
tableau (the compiled loop too); a config refuses that (``parastokes check``), since ``rk4`` is
cheaper there. The states at given times (a run's frames) come from runs that end there, the
last step cut to land on the time: no interpolation between steps.

Blow-up is an error: after every step the state must be finite and ``system.monitor`` must stay
below ``blowup_factor * system.monitor_limit``; otherwise :class:`BlowUpError` names the time, the
step index and the monitor value and keeps the last good state.

The package reads as scipy's ``integrate/_ivp`` does, one module per part:

- :mod:`.schemes`: the :class:`Scheme` tableaux and the registry :data:`SCHEMES`;
- :mod:`.base`: the checked calls into a system, :class:`RunResult`, :class:`BlowUpError`;
- :mod:`.explicit`: one step of an explicit tableau (RKMK brackets included);
- :mod:`.implicit`: the linearly implicit schemes' steppers on a run's checked calls;
- :mod:`.controller`: THE step-size controller of every adaptive scheme;
- :mod:`.adaptive`: the adaptive driver;
- :mod:`.auto`: ``scheme="auto"``, switching between an explicit pair and an implicit scheme;
- :mod:`.runs`: fixed-step runs, :func:`run`, :func:`propagate`, :class:`Propagator`;
- :mod:`.stability`: :func:`is_stable`, :func:`largest_stable_step`;
- :mod:`.loop`: the compiled loops of steps (fixed steps, and an explicit pair's adaptive ones).
"""

from .base import (
    ABOVE,
    BEYOND,
    BLOWUP_FACTOR,
    DONE,
    NON_FINITE,
    BlowUpError,
    RunResult,
    projected,
)
from .controller import StepSizeError
from .runs import (
    Propagator,
    _python_steps,  # noqa: F401 (tests run it beside a compiled loop)
    n_steps,
    propagate,
    run,
    run_result,
    step,
    tolerances,
)
from .schemes import AUTO, SCHEMES, AnyScheme, Scheme, explicit_scheme, lookup, scheme_order
from .stability import is_stable, largest_stable_step

__all__ = [
    "ABOVE",
    "AUTO",
    "BEYOND",
    "BLOWUP_FACTOR",
    "DONE",
    "NON_FINITE",
    "SCHEMES",
    "AnyScheme",
    "BlowUpError",
    "Propagator",
    "RunResult",
    "Scheme",
    "StepSizeError",
    "explicit_scheme",
    "is_stable",
    "largest_stable_step",
    "lookup",
    "n_steps",
    "projected",
    "propagate",
    "run",
    "run_result",
    "scheme_order",
    "step",
    "tolerances",
]
