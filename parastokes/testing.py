"""Contract checks for any system (docs/contracts.md), for users' bodies as for the package's own.

>>> from parastokes.testing import check_system
>>> check_system(my_system)                      # doctest: +SKIP

:func:`check_system` raises ``AssertionError`` naming the part of the contract that is broken:

- ``members``: every member of :class:`parastokes.core.contracts.System` is there;
- ``calls`` (and the part of each method below): every method can be called as the package calls
  it, and returns, at the initial state, real finite values of the shapes the package expects
  (:func:`parastokes.bodies.contract.probe`, as ``parastokes check`` and every run do);
- ``state``: ``initial_state()`` is a finite float64 array, ``positions`` gives (N, 3);
- ``rates``: ``rates(t, x)`` is finite with a row per state row; ``advance(x, r, dt)`` returns a
  new array of the state's shape, leaves its inputs alone, and ``advance(x, r, 0)`` is ``x``;
- ``monitor``: ``monitor(x)`` is a finite number >= 0 below the blow-up bound of
  ``integrate.run`` (``BLOWUP_FACTOR * monitor_limit``);
- ``with_params``: each parameter of ``params`` changes alone (to the value asked; for a dataclass
  whose parameters are its fields, no other field changes) and changes the rates, the original
  is unchanged, an unknown name is a ``ValueError``;
- ``pickle``: the system pickles small and its copy gives the same rates, bit for bit;
- ``project``: ``project`` is idempotent and leaves a valid state (nearly) unchanged;
- ``compiled loop``: where ``integrate.run`` has a compiled loop for the system, it gives the
  same states as the Python loop, bit for bit, for every scheme of ``integrate.SCHEMES`` but
  the embedded pairs;
- ``order``: the error of every scheme of ``integrate.SCHEMES`` but the embedded pairs falls
  with its declared order (eq. 26's p), fitted over halved steps against a fine RK4 reference.

The order check needs a state whose dynamics are active and a horizon on which the steps are in
the asymptotic regime: pass ``state`` and ``horizon`` where the defaults (the initial state, a
fifth of the time the fastest point takes to cross the body, shortened until every scheme's
coarsest step is stable, as stiff bodies need) do not fit.
"""

from __future__ import annotations

import dataclasses
import math
import pickle
from collections.abc import Sequence
from typing import Any

import numpy as np

from . import integrate
from .bodies import contract
from .core.contracts import System
from .registry.loops import compiled_loop

__all__ = ["check_system", "fitted_order"]


class _Part:
    """Assertions of one part of the contract, each naming the part and the system."""

    def __init__(self, system: System, part: str) -> None:
        self.where = f"check_system({type(system).__name__}): {part}"

    def __call__(self, condition: bool, message: str) -> None:
        if not condition:
            raise AssertionError(f"{self.where}: {message}")


#: The part of the contract a method's :class:`~parastokes.bodies.contract.BodyError` is named
#: under (others: ``calls``, the signatures).
_PARTS = {"initial_state": "state", "positions": "state", "forces": "rates", "loads": "rates",
          "rates": "rates", "advance": "rates", "project": "project", "monitor": "monitor",
          "monitor_limit": "monitor", "params": "with_params", "with_params": "with_params"}

#: Errors below this fraction of the state's size are round-off, not truncation: left out of fits.
ROUND_OFF = 1e-11


def fitted_order(
    system: System, x0: np.ndarray, t0: float, horizon: float, scheme: str,
    counts: Sequence[int], reference: np.ndarray, compiled: bool = True,
) -> float:
    """The slope of log(error) against log(1/steps) over ``[t0, t0 + horizon]``: the observed
    order of ``scheme``; steps whose error is at round-off level (:data:`ROUND_OFF`) are left out,
    NaN when fewer than two remain."""
    floor = ROUND_OFF * max(1.0, float(np.abs(reference).max()))
    points = []
    for n in counts:
        x = integrate.run(system, x0, t0, t0 + horizon, scheme, horizon / n, compiled=compiled)
        error = float(np.abs(x.state - reference).max())
        if error > floor:
            points.append((n, error))
    if len(points) < 2:
        return math.nan
    n, e = np.array(points).T
    return float(-np.polyfit(np.log(n), np.log(e), 1)[0])


def _check_state(system: System, x: np.ndarray) -> None:
    ok = _Part(system, "state")
    ok(isinstance(x, np.ndarray) and x.dtype == np.float64, "the state must be a float64 array")
    ok(bool(np.isfinite(x).all()), "the state is not finite")
    pos = system.positions(x)
    ok(isinstance(pos, np.ndarray) and pos.ndim == 2 and pos.shape[1] == 3,
       f"positions(state) must be (N, 3), got {getattr(pos, 'shape', type(pos))}")


def _check_rates(system: System, x: np.ndarray, t: float, dt: float) -> np.ndarray:
    ok = _Part(system, "rates")
    copy = x.copy()
    r = system.rates(t, x)
    ok(isinstance(r, np.ndarray) and r.ndim >= 1 and r.shape[0] == x.shape[0],
       f"rates(t, x) must have one row per state row {x.shape}, got {getattr(r, 'shape', r)}")
    ok(bool(np.isfinite(r).all()), "rates(t, x) is not finite")
    ok(np.array_equal(x, copy), "rates(t, x) modified the state")
    r_copy = r.copy()
    y = system.advance(x, r, dt)
    ok(isinstance(y, np.ndarray) and y.shape == x.shape,
       f"advance(x, rates, dt) must have the state's shape {x.shape}, got {getattr(y, 'shape', y)}")
    ok(y is not x and not np.shares_memory(y, x), "advance must return a new array")
    ok(np.array_equal(x, copy) and np.array_equal(r, r_copy), "advance modified its inputs")
    ok(not np.array_equal(y, x) or not r.any(), "advance(x, rates, dt) did not move the state")
    zero = system.advance(x, r, 0.0)
    ok(np.allclose(zero, x, rtol=0, atol=1e-14 * max(1.0, np.abs(x).max())),
       "advance(x, rates, 0) must be x")
    return r


def _check_monitor(system: System, x: np.ndarray) -> None:
    ok = _Part(system, "monitor")
    m = system.monitor(x)
    limit = system.monitor_limit
    ok(isinstance(m, float | np.floating) and math.isfinite(m) and bool(m >= 0),
       f"monitor(state) must be a finite float >= 0, got {m!r}")
    ok(isinstance(limit, float | int | np.number) and bool(limit > 0),
       f"monitor_limit must be a number > 0, got {limit!r}")
    bound = integrate.BLOWUP_FACTOR * limit
    ok(m <= bound, f"monitor(state) = {m:g} is already beyond the blow-up bound {bound:g}")


def _check_params(system: System, x: np.ndarray, t: float) -> None:
    ok = _Part(system, "with_params")
    params = dict(system.params)
    ok(all(isinstance(v, float | int) and not isinstance(v, bool) for v in params.values()),
       f"params must map names to numbers, got {params!r}")
    before = pickle.dumps(system)
    fields: tuple[dataclasses.Field[Any], ...] = (
        dataclasses.fields(system) if dataclasses.is_dataclass(system) else ()
    )
    if not set(params) <= {f.name for f in fields}:
        fields = ()  # a composite (a scene): its parameters are not its own fields
    for name, value in params.items():
        new_value = float(value) * 1.125
        other = system.with_params(**{name: new_value})
        ok(type(other) is type(system), f"with_params({name}=...) returned a {type(other)}")
        ok(other.params == params | {name: new_value},
           f"with_params({name}={new_value:g}) gave params {other.params}")
        moved = {f.name for f in fields if getattr(other, f.name) != getattr(system, f.name)}
        ok(not fields or moved == {name}, f"with_params({name}=...) changed the fields {moved}")
        changed = not np.array_equal(other.rates(t, x), system.rates(t, x))
        ok(changed, f"changing {name} does not change the rates at the given state")
    ok(pickle.dumps(system) == before, "with_params changed the original system")
    try:
        system.with_params(**{"no_such_parameter": 1.0})
    except ValueError:
        pass
    else:
        ok(False, "with_params(no_such_parameter=...) must raise ValueError")


def _check_pickle(system: System, x: np.ndarray, t: float, limit: int) -> None:
    ok = _Part(system, "pickle")
    try:
        blob = pickle.dumps(system)
    except Exception as error:
        ok(False, f"the system does not pickle ({type(error).__name__}: {error})")
    ok(len(blob) <= limit,
       f"the system pickles to {len(blob)} bytes (> {limit}); it travels to every worker task")
    again = pickle.loads(blob)
    ok(np.array_equal(again.rates(t, x), system.rates(t, x)),
       "the unpickled system gives other rates")


def _check_project(system: System, x: np.ndarray, r: np.ndarray, dt: float) -> None:
    ok = _Part(system, "project")
    scale = max(1.0, float(np.abs(x).max()))
    px = system.project(x)
    ok(px.shape == x.shape, f"project changed the shape {x.shape} -> {px.shape}")
    ok(np.allclose(px, x, rtol=0, atol=1e-12 * scale), "project moved a valid state")
    # a linear combination of states, as Parareal's correction and extrapolation form them
    y = 1.5 * system.advance(x, r, dt) - 0.5 * x
    once = system.project(y)
    twice = system.project(once)
    ok(np.allclose(twice, once, rtol=0, atol=1e-13 * scale), "project is not idempotent")


def _checked_schemes() -> dict[str, integrate.AnyScheme]:
    """The schemes the checks run: all but the embedded explicit pairs (rk23, rk45), which are
    for adaptive steps; on fixed steps they are tableaux like rk4's, through the same code
    (their orders: tests/test_integrate_pairs.py)."""
    return {name: s for name, s in integrate.SCHEMES.items() if s.implicit or not s.adaptive}


def _check_compiled(system: System, x: np.ndarray, t: float, dt: float, n: int) -> None:
    ok = _Part(system, "compiled loop")
    for name in _checked_schemes():
        a = integrate.run(system, x, t, t + n * dt, name, dt, compiled=True)
        b = integrate.run(system, x, t, t + n * dt, name, dt, compiled=False)
        ok(np.array_equal(a.state, b.state) and a.max_monitor == b.max_monitor,
           f"{name}: the compiled loop differs from the Python loop by "
           f"{np.abs(a.state - b.state).max():.3g}")


#: The order of a linearly implicit scheme is fitted on steps this many times smaller than an
#: explicit one's: at the steps where an explicit scheme is barely stable, the W-methods' error
#: constants still involve the stiff Jacobian (hJ of order one) and the order shows only below.
IMPLICIT_REFINEMENT = 4


def _check_orders(system: System, x: np.ndarray, t: float, horizon: float,
                  counts: Sequence[int], tolerance: float) -> dict[str, float]:
    ok = _Part(system, "order")
    finest = 16 * max(counts)
    reference = integrate.run(system, x, t, t + horizon, "rk4", horizon / finest).state
    orders = {}
    for name, scheme in _checked_schemes().items():
        steps = [2 * n for n in counts] if scheme.order == 1 else list(counts)
        if scheme.implicit:  # their error constants carry the stiff Jacobian: smaller steps
            steps = [IMPLICIT_REFINEMENT * n for n in steps]
        p = fitted_order(system, x, t, horizon, name, steps, reference)
        ok(not math.isnan(p),
           f"{name}: the errors are at round-off level (steps {steps} on a horizon of "
           f"{horizon:g}); pass a longer horizon or a more active state")
        ok(abs(p - scheme.order) <= tolerance,
           f"{name}: fitted order {p:.2f}, declared {scheme.order} (steps {steps} on a horizon "
           f"of {horizon:g}; pass state/horizon where the dynamics are too weak or too stiff)")
        orders[name] = p
    return orders


def _default_horizon(system: System, x: np.ndarray, t: float) -> float:
    pos = system.positions(x)
    extent = float(np.ptp(pos, axis=0).max()) or 1.0
    speed = float(np.abs(system.rates(t, x)[:, :3]).max())
    _Part(system, "rates")(speed > 0, "all rates vanish at the state: pass an active state")
    return 0.2 * extent / speed


def _stable_horizon(system: System, x: np.ndarray, t: float, horizon: float,
                    counts: Sequence[int], given: bool) -> float:
    """``horizon``, shrunk (by 4, at most 10 times) until the coarsest step of every scheme in the
    order check stays stable; a horizon the user ``given`` is not shrunk: its blow-up is named."""
    ok = _Part(system, "order")
    for _ in range(10):
        try:
            for name, scheme in _checked_schemes().items():
                if scheme.implicit:  # at least as stable as the explicit ones, fitted finer
                    continue
                steps = 2 * min(counts) if scheme.order == 1 else min(counts)
                integrate.run(system, x, t, t + horizon, name, horizon / steps)
            return horizon
        except integrate.BlowUpError as error:
            ok(not given, f"{name} blows up with {steps} steps on the horizon {horizon:g} "
               f"({error}); pass a shorter horizon")
            horizon /= 4.0
    ok(False, f"every scheme tried blows up, down to the horizon {horizon:g}: the system is "
       "unstable at any step tried; pass state/horizon where it is stable")
    return horizon


def check_system(
    system: System,
    state: np.ndarray | None = None,
    *,
    t: float = 0.0,
    horizon: float | None = None,
    counts: Sequence[int] = (8, 16, 32, 64),
    order_tolerance: float = 0.3,
    pickle_limit: int = 4096,
) -> dict[str, float]:
    """Check ``system`` against the System contract (docs/contracts.md); see the module docstring.

    ``state`` (default ``initial_state()``) and time ``t`` are where the rates are evaluated and
    the orders fitted, over ``[t, t + horizon]`` with ``counts`` steps (twice as many for
    first-order schemes). Raises ``AssertionError`` naming the broken part; returns the fitted
    order of every scheme of ``integrate.SCHEMES`` (``{"euler": 1.01, ...}``, the slope of
    :func:`fitted_order`), which docs/validation.md section 3 prints for a rod and a vesicle.
    """
    missing = sorted(n for n in vars(System) if not n.startswith("_") and not hasattr(system, n))
    _Part(system, "members")(not missing, f"missing {', '.join(missing)} (contracts.System)")
    try:
        contract.probe(system, t)
    except contract.BodyError as error:
        _Part(system, _PARTS.get(error.method.split(".", 1)[1].split("(")[0], "calls"))(
            False, str(error))
    x0 = system.initial_state()
    _check_state(system, x0)
    x = x0 if state is None else np.ascontiguousarray(state, dtype=float)
    _check_state(system, x)
    given = horizon is not None
    horizon = float(horizon) if horizon is not None else _default_horizon(system, x, t)
    horizon = _stable_horizon(system, x, t, horizon, counts, given)
    dt = horizon / max(counts)
    r = _check_rates(system, x, t, dt)
    _check_monitor(system, x)
    _check_params(system, x, t)
    _check_pickle(system, x, t, pickle_limit)
    _check_project(system, x, r, dt)
    if compiled_loop(system) is not None:
        _check_compiled(system, x, t, dt, 6)
    return _check_orders(system, x, t, horizon, counts, order_tolerance)
