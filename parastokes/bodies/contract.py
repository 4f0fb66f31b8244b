"""The System contract checked at run time, where a body's values enter the package.

A body written outside the package hands arrays to it (forces, rates, advanced and projected
states, its initial state, positions, its monitor value); each is checked once, where it enters,
and a value the package cannot use is a :class:`BodyError`: one line naming the method
(``MyBody.forces(state)``), what it returned and what is expected (docs/contracts.md):

- :func:`array`: a real array (float64-convertible) of the expected shape or rows, finite where
  asked; used by the Python paths (``PointsInShear.rates``, ``integrate.step``, scenes of bodies
  of any kind). The compiled loops of the package's own bodies never pass through it.
- :func:`number`: a real number (a monitor value, a limit, a parameter).
- :func:`signatures`: every method of the contract can be called as the package calls it.
- :func:`probe`: all of the above once, at the initial state (``parastokes check``, every run before
  its workers start, and :func:`parastokes.testing.check_system`), finiteness included.
- :func:`culprit`: after a non-finite state in a run, the method that returned non-finite values
  at the last good state (called on a blow-up only).

Non-finite values during a run are a blow-up (:class:`parastokes.integrate.BlowUpError`: a stiff
body may overflow at too large a step), not a broken contract: they are checked at the probe and
named, after the fact, by :func:`culprit`.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Iterator, Mapping
from typing import Any

import numpy as np

__all__ = [
    "BodyError",
    "array",
    "culprit",
    "is_builtin",
    "number",
    "probe",
    "signatures",
    "user_bodies",
]


class BodyError(ValueError):
    """A body broke the System contract (docs/contracts.md): ``method`` is ``"Type.call"``; the
    message says what it returned or how it is declared, and what is expected, in one line."""

    def __init__(self, message: str, method: str = "") -> None:
        super().__init__(message)
        self.method = method

    def __reduce__(self) -> tuple:  # rebuilt whole in the manager from a worker
        return (type(self), (str(self), self.method))


def _fail(system: Any, call: str, found: str, expected: str) -> BodyError:
    method = f"{type(system).__name__}.{call}"
    return BodyError(f"{method} {found}" + (f"; expected {expected}" if expected else ""), method)


#: What :class:`~parastokes.bodies.base.PointsInShear` reads of the class it is mixed into
#: (docs/extending.md): name -> how to declare it.
POINTS_IN_SHEAR = {
    "epsilon": "epsilon: float",
    "viscosity": "viscosity: float",
    "shear_rate": "shear_rate: float",
    "n_threads": "n_threads: int | None = None",
    "target_blocks": ("target_blocks: Blocks | None = field(default=None, init=False)"
                      "  (parastokes.fluid.Blocks)"),
}


def _shape_text(shape: tuple[int, ...]) -> str:
    return f"({shape[0]},)" if len(shape) == 1 else f"({', '.join(map(str, shape))})"


def array(
    system: Any,
    call: str,
    value: Any,
    *,
    shape: tuple[int, ...] | None = None,
    rows: int | None = None,
    ndim: int | None = None,
    what: str = "",
    finite: bool = False,
) -> np.ndarray:
    """``value`` (what ``system.call`` returned) as a float64 array, unchanged when it is one;
    :class:`BodyError` unless it is real numbers of ``shape`` (or ``ndim`` dimensions and
    ``rows`` rows), and, with ``finite``, finite. ``what`` says what the shape means."""
    if isinstance(value, np.ndarray) and value.dtype == np.float64:
        arr = value
    else:
        try:
            arr = np.asarray(value)
        except Exception as error:  # ragged lists and the like
            raise _fail(system, call, f"returned {type(value).__name__} that is no array "
                        f"({error})", "an array of real numbers") from None
        if arr.dtype.kind not in "biuf":
            raise _fail(system, call, f"returned {type(value).__name__} of dtype {arr.dtype}",
                        "real numbers (float64)")
        arr = arr.astype(np.float64)
    note = f": {what}" if what else ""
    if shape is not None and arr.shape != shape:
        raise _fail(system, call, f"returned shape {_shape_text(arr.shape)}",
                    f"{_shape_text(shape)}{note}")
    if (rows is not None and (arr.ndim == 0 or arr.shape[0] != rows)) or (
        ndim is not None and arr.ndim != ndim
    ):
        want = f"{ndim or 'any'}-dimensional with {rows} rows" if rows is not None else (
            f"{ndim}-dimensional")
        raise _fail(system, call, f"returned shape {_shape_text(arr.shape)}", f"{want}{note}")
    if finite and not np.isfinite(arr).all():
        bad = ~np.isfinite(arr)
        kind = "NaN" if np.isnan(arr).any() else "infinite values"
        raise _fail(system, call, f"returned {kind} ({int(bad.sum())} of {arr.size} values, "
                    f"first at index {tuple(int(i) for i in np.argwhere(bad)[0])})",
                    "finite values")
    return arr


def number(system: Any, call: str, value: Any, *, finite: bool = False,
           positive: bool = False) -> float:
    """``value`` (what ``system.call`` returned or holds) as a float; :class:`BodyError` unless it
    is a real number (not a bool), finite with ``finite``, > 0 with ``positive``."""
    if type(value) in (float, np.float64) and not (finite or positive):  # the loop's case
        return float(value)
    real = isinstance(value, int | float | np.integer | np.floating) and not isinstance(
        value, bool | np.bool_)
    if (not real and isinstance(value, np.ndarray) and value.shape == ()
            and value.dtype.kind in "iuf"):
        real, value = True, value.item()
    if not real:
        raise _fail(system, call, f"is {value!r} ({type(value).__name__})", "a real number")
    x = float(value)
    if finite and not math.isfinite(x):
        raise _fail(system, call, f"is {x!r}", "a finite number")
    if positive and not x > 0:
        raise _fail(system, call, f"is {x!r}", "a number > 0")
    return x


# ---- signatures --------------------------------------------------------------------------------
#: How the package calls each method of a body: name -> its arguments (docs/contracts.md).
CALLS: dict[str, tuple[str, ...]] = {
    "initial_state": (),
    "rates": ("t", "state"),
    "advance": ("state", "rates", "dt"),
    "project": ("state",),
    "positions": ("state",),
    "monitor": ("state",),
}
#: Methods called only where a body has them: scenes' members, a Lie bracket, a point body's
#: forces, the Jacobian hooks of the linearly implicit schemes (:mod:`parastokes.stiff.jacobian`).
OPTIONAL_CALLS: dict[str, tuple[str, ...]] = {
    "loads": ("t", "state"),
    "body_rates": ("u", "w"),
    "bracket": ("r1", "r2"),
    "forces": ("state",),
    "load_jacobian": ("t", "state"),
    "stiff_jacobian": ("t", "state"),
}


def _method_calls(system: Any) -> Iterator[tuple[str, tuple[str, ...]]]:
    yield from CALLS.items()
    from .base import PointsInShear  # (base imports this module)

    for name, args in OPTIONAL_CALLS.items():
        if hasattr(system, name) and (name != "forces" or isinstance(system, PointsInShear)):
            yield name, args


def signatures(system: Any) -> None:
    """:class:`BodyError` naming the first method of the contract that cannot be called as the
    package calls it (e.g. ``forces(self)`` without ``state``), a property written as a method,
    or a field that :class:`~parastokes.bodies.base.PointsInShear` reads and the body lacks."""
    from .base import PointsInShear  # (base imports this module)

    if isinstance(system, PointsInShear):
        for name, declaration in POINTS_IN_SHEAR.items():
            if not hasattr(system, name):
                raise _fail(system, name, "is missing (PointsInShear reads it)",
                            f"a field `{declaration}` (docs/extending.md)")
    for name, args in _method_calls(system):
        method = getattr(system, name, None)
        if not callable(method):
            raise _fail(system, name, f"is {method!r}", f"a method {name}({', '.join(args)})")
        try:
            signature = inspect.signature(method)
        except (TypeError, ValueError):  # a builtin or compiled callable: nothing to read
            continue
        try:
            signature.bind(*args)
        except TypeError as error:
            raise _fail(system, f"{name}{signature}", f"cannot be called as {name}"
                        f"({', '.join(args)}) ({error})",
                        f"def {name}(self{''.join(', ' + a for a in args)})") from None
    for name in ("params", "monitor_limit"):
        if inspect.ismethod(getattr(system, name, None)):
            raise _fail(system, name, "is a method", "a value: decorate it with @property")
    params = getattr(system, "params", None)
    if params:
        try:
            inspect.signature(system.with_params).bind(**dict.fromkeys(params, 1.0))
        except TypeError as error:
            raise _fail(system, "with_params", f"cannot take the parameters {sorted(params)} as "
                        f"keywords ({error})", "def with_params(self, **theta)") from None
        except ValueError:
            pass


# ---- the probe at the initial state ------------------------------------------------------------
def _call(system: Any, call: str, method: Any, *args: Any) -> Any:
    """``method(*args)``; an error it raises (but a :class:`BodyError`) as a :class:`BodyError`
    naming ``Type.call``, the original chained."""
    try:
        return method(*args)
    except BodyError:
        raise
    except Exception as error:
        raise _fail(system, call, f"raised {type(error).__name__} at the initial state: {error}",
                    "") from error


def _probe_loads(system: Any, t: float, x: np.ndarray) -> None:
    rows = (len(x), 3)
    loads = _call(system, "loads(t, state)", system.loads, t, x)
    if not (isinstance(loads, tuple) and len(loads) == 2):
        raise _fail(system, "loads(t, state)", f"returned {type(loads).__name__}",
                    "a pair (forces, torques or None)")
    array(system, "loads(t, state)[0]", loads[0], shape=rows, what="forces, one row per point",
          finite=True)
    if loads[1] is not None:
        array(system, "loads(t, state)[1]", loads[1], shape=rows,
              what="torques, one row per point", finite=True)


def probe(system: Any, t: float = 0.0, dt: float = 0.0) -> np.ndarray:
    """Call every method of ``system``'s contract once at its initial state (time ``t``,
    ``advance`` with the step ``dt``) and check what each returns (shapes, real numbers,
    finite values; :class:`BodyError` naming the first that fails); returns the initial state.
    Cheap: one evaluation of the forces and the rates, one advance, one projection."""
    from .base import PointsInShear  # (base imports this module)

    signatures(system)
    x = array(system, "initial_state()", _call(system, "initial_state()", system.initial_state),
              ndim=2, finite=True, what="one row per point")
    points = array(system, "positions(state)",
                   _call(system, "positions(state)", system.positions, x), ndim=2, finite=True,
                   what="(N, 3), the points' x, y, z")
    if points.shape[1] != 3:
        raise _fail(system, "positions(state)", f"returned shape {_shape_text(points.shape)}",
                    "(N, 3): the points' x, y, z")
    if isinstance(system, PointsInShear):
        array(system, "forces(state)", _call(system, "forces(state)", system.forces, x),
              shape=(len(x), 3), finite=True, what="one row per point")
    if hasattr(system, "loads"):
        _probe_loads(system, t, x)
    r = array(system, "rates(t, state)", _call(system, "rates(t, state)", system.rates, t, x),
              rows=len(x), ndim=x.ndim, finite=True, what="one row per state row")
    call = "advance(state, rates, dt)"
    y = array(system, call, _call(system, call, system.advance, x, r, dt), shape=x.shape,
              finite=True, what="the state's shape")
    array(system, "project(state)", _call(system, "project(state)", system.project, y),
          shape=x.shape, finite=True, what="the state's shape")
    m = number(system, "monitor(state)", _call(system, "monitor(state)", system.monitor, x),
               finite=True)
    if m < 0:
        raise _fail(system, "monitor(state)", f"is {m!r} at the initial state", "a number >= 0")
    number(system, "monitor_limit", system.monitor_limit, finite=True, positive=True)
    params = system.params
    if not isinstance(params, Mapping):
        raise _fail(system, "params", f"is {type(params).__name__}", "a dict name -> number")
    for name, value in params.items():
        number(system, f"params[{name!r}]", value, finite=True)
    return x


def culprit(system: Any, t: float, x: np.ndarray) -> str:
    """The first of ``system``'s forces and rates that is not finite at the (finite) state ``x``,
    as ``"; Type.method returned NaN ..."``, or ``""`` (called after a non-finite step only)."""
    from .base import PointsInShear  # (base imports this module)

    calls: list[tuple[str, Any]] = []
    if isinstance(system, PointsInShear):
        calls.append(("forces(state)", lambda: system.forces(x)))
    calls.append(("rates(t, state)", lambda: system.rates(t, x)))
    for call, evaluate in calls:
        try:
            value = np.asarray(evaluate(), dtype=float)
        except Exception:  # nothing more to say than the blow-up itself
            return ""
        if not np.isfinite(value).all():
            kind = "NaN" if np.isnan(value).any() else "infinite values"
            return (f"; {type(system).__name__}.{call} returned {kind} at the last good state "
                    f"(t = {t:.10g})")
    return ""


# ---- which bodies are the user's ---------------------------------------------------------------
def is_builtin(system: Any) -> bool:
    """Whether ``system``'s type is one of the package's own (its module is in parastokes)."""
    module = type(system).__module__
    return module == "parastokes" or module.startswith("parastokes.")


def user_bodies(system: Any) -> list[Any]:
    """The bodies of ``system`` whose types are not the package's own: ``system`` itself, or the
    bodies of a scene (``bodies``) that are not."""
    if is_builtin(system):
        return [body for body in getattr(system, "bodies", ()) if not is_builtin(body)]
    return [system]
