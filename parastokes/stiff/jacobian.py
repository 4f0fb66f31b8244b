"""The approximate Jacobian ``A`` of a system's rates that the linearly implicit schemes use.

In order of preference (docs/stiff.md, "Which Jacobian"):

1. the system's own ``stiff_jacobian(t, state)``: a sparse (or dense) square matrix over the
   rates, point-major (a :class:`parastokes.scene.Scene` composes its bodies' this way);
2. for a body on the MRS fluid (``loads``, ``epsilon``, ``viscosity``): the near-pair mobility
   (:func:`.local.near_mobility`, pairs within :data:`CUTOFF` ε) times the Jacobian of its loads,
   ``A = M_near K`` (:func:`.banded.near_product`: in LAPACK's band layout for a rod or
   chain). ``K`` is the body's ``load_jacobian(t, state)`` if it has one (checked
   against finite differences by ``parastokes.testing.check_system``), else coloured finite
   differences (:mod:`.coloring`) over its declared ``load_coupling()`` pattern (the package's
   rod, vesicle and chain declare theirs), else dense finite differences (a user body without
   either: two loads evaluations per point and rate column);
3. otherwise (a rigid or prescribed-motion body, whose velocity is already a solve; a system
   with rates only): no ``A``, and the schemes step it as their explicit counterparts
   (:func:`has_stiff_part` says which, without calling anything).

A user's hooks (``stiff_jacobian``, ``load_jacobian``) are checked where they enter: a value
that is no matrix, of the wrong shape, or an error they raise is a
:class:`~parastokes.bodies.contract.BodyError` naming the hook (exit 2 of a run, in a worker
too); non-finite entries during a run are a blow-up there (:class:`NonFiniteJacobian`, a
:class:`~.solve.StiffSolveError`), and at the initial state a BodyError (:func:`probe_hooks`,
called by ``parastokes check`` and before every run).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import scipy.sparse as sp

from ..bodies import contract
from .banded import near_product
from .coloring import fd_jacobian
from .solve import StiffSolveError

__all__ = ["CUTOFF", "NonFiniteJacobian", "block_jacobian", "fd_step", "has_stiff_part",
           "jacobian_check", "load_jacobian", "local_jacobian", "probe_hooks"]

#: Pairs of points closer than CUTOFF ε enter the near mobility (docs/benchmarks.md, "Stiff
#: bodies": 3 ε keeps ROS2 stable at 20x the explicit limit on the paper's rod).
CUTOFF = 3.0


def _rate_columns(body: Any) -> int:
    return int(getattr(body, "rate_columns", 6 if getattr(body, "angular", False) else 3))


class NonFiniteJacobian(StiffSolveError):
    """A Jacobian hook (``method``: ``"Type.hook(t, state)"``) returned non-finite entries at
    time ``t`` of a run: a blow-up there, like a failed stage solve."""

    def __init__(self, t: float, method: str, kind: str) -> None:
        super().__init__(t, math.nan, 0, f"{method} returned {kind}")
        self.args = (f"{method} returned {kind} at t = {t:.10g}",)
        self.method, self.kind = method, kind

    def __reduce__(self) -> tuple:
        return type(self), (self.t, self.method, self.kind)


def _hook(system: Any, call: str, t: float, x: np.ndarray) -> Any:
    """``system.call(t, x)`` (a Jacobian hook); an error it raises as a BodyError naming
    ``Type.call(t, state)`` and the time (exit 2 wherever it runs, never a failed task)."""
    name = f"{type(system).__name__}.{call}(t, state)"
    try:
        return getattr(system, call)(t, x)
    except (contract.BodyError, NonFiniteJacobian):  # a scene's: its bodies' hooks, named
        raise
    except Exception as error:
        raise contract.BodyError(f"{name} raised {type(error).__name__} at t = {t:.10g}: "
                                 f"{error}", name) from error


def _sparse(system: Any, call: str, matrix: Any, shape: tuple[int, int], what: str, t: float
            ) -> sp.csr_array | sp.bsr_array:
    """``matrix`` (what ``system.call`` returned at time ``t``) as a CSR (or BSR) array of
    ``shape`` (BodyError naming ``Type.call`` otherwise; ``what`` says what the shape means),
    finite (:class:`NonFiniteJacobian` otherwise)."""
    name = f"{type(system).__name__}.{call}"
    try:  # block-sparse stays so (near_product's K, the rod's hook): no conversion
        out = (matrix.astype(float, copy=False) if isinstance(matrix, sp.bsr_array)
               else sp.csr_array(matrix, dtype=float))
    except (TypeError, ValueError) as error:
        raise contract.BodyError(f"{name} returned {type(matrix).__name__} that is no matrix "
                                 f"({error}); expected a sparse or dense matrix", name) from None
    if out.shape != shape:
        raise contract.BodyError(f"{name} returned shape {out.shape}; expected {shape}: {what}",
                                 name)
    if not np.isfinite(out.data).all():
        kind = "NaN" if np.isnan(out.data).any() else "infinite entries"
        raise NonFiniteJacobian(t, name, kind)
    return out


def _loads_function(body: Any, t: float) -> Any:
    """state -> the body's loads per point as one (n, 3) or (n, 6) array ``[f, n]``."""
    angular = bool(getattr(body, "angular", False))

    def loads(state: np.ndarray) -> np.ndarray:
        forces, torques = body.loads(t, state)
        if not angular:
            return np.asarray(forces, dtype=float)
        torques = np.zeros_like(forces) if torques is None else torques
        return np.concatenate([forces, torques], axis=1)

    return loads


def fd_step(x: np.ndarray) -> float:
    """The size of the loads' finite differences at state ``x`` (points' rows, positions
    first): 1e-6 times the largest coordinate, at least 1e-6 (a rotation: 1e-6 radians)."""
    return 1e-6 * max(1.0, float(np.abs(x[:, :3]).max(initial=0.0)))


def load_jacobian(body: Any, t: float, x: np.ndarray, *, dense: bool = False
                  ) -> sp.csr_array | sp.bsr_array:
    """``K``: the Jacobian of the body's loads (rows ``[f, n]`` per point) with respect to its
    rates' coordinates (columns per point): its ``load_jacobian`` if it has one, else coloured
    finite differences over ``load_coupling()`` (``dense``, or without one: every point)."""
    n, rc = len(x), _rate_columns(body)
    width = 6 if getattr(body, "angular", False) else 3
    if getattr(body, "load_jacobian", None) is not None and not dense:
        return _sparse(body, "load_jacobian(t, state)", _hook(body, "load_jacobian", t, x),
                       (n * width, n * rc), "a row per load and a column per rate, point-major",
                       t)
    declared = getattr(body, "load_coupling", None)
    if declared is None or dense:
        coupling = sp.csr_array(np.ones((n, n), dtype=bool))
    else:
        coupling = declared()
        if sp.csr_array(coupling).shape != (n, n):
            name = f"{type(body).__name__}.load_coupling()"
            raise contract.BodyError(f"{name} returned shape {sp.csr_array(coupling).shape}; "
                                     f"expected ({n}, {n}): one row and column per point", name)
    return fd_jacobian(_loads_function(body, t), body.advance, x, rc, coupling, fd_step(x))


def _is_fluid_body(system: Any) -> bool:
    return all(hasattr(system, name) for name in ("loads", "epsilon", "viscosity")) and not (
        hasattr(system, "surface") and hasattr(system, "motion_rates"))


def _local_model(system: Any) -> bool:
    """Whether ``system`` is a body on the MRS fluid whose rates are its points' velocities
    (``A = M_near K`` models it); rates of other columns have no local model."""
    angular = bool(getattr(system, "angular", False))
    return _is_fluid_body(system) and _rate_columns(system) == (6 if angular else 3)


def has_stiff_part(system: Any) -> bool:
    """Whether :func:`local_jacobian` gives ``system`` an ``A`` (its own ``stiff_jacobian``, which
    may still return None, or a body on the fluid); False: a linearly implicit scheme steps it
    with ``A = 0``, as an explicit scheme. (A scene has ``stiff_jacobian``: ask of its bodies.)"""
    return getattr(system, "stiff_jacobian", None) is not None or _local_model(system)


def local_jacobian(system: Any, t: float, x: np.ndarray, n_rates: int
                   ) -> sp.csr_array | sp.bsr_array | sp.dia_array | None:
    """``A`` of ``system`` at ``(t, x)`` over its ``n_rates`` rates flattened point-major, or
    None (no stiff part known: the schemes step it explicitly); see the module docstring."""
    x = np.asarray(x, dtype=float)
    if getattr(system, "stiff_jacobian", None) is not None:
        matrix = _hook(system, "stiff_jacobian", t, x)
        if matrix is None:
            return None
        return _sparse(system, "stiff_jacobian(t, state)", matrix, (n_rates, n_rates),
                       "one row and column per rate, point-major", t)
    if not _local_model(system):
        return None
    angular = bool(getattr(system, "angular", False))
    size = _rate_columns(system)  # = the loads per point (_local_model)
    k = sp.bsr_array(load_jacobian(system, t, x), blocksize=(size, size))
    return near_product(system.positions(x), float(system.epsilon), float(system.viscosity),
                        angular, CUTOFF * float(system.epsilon), k)


def probe_hooks(system: Any, t: float, x: np.ndarray) -> None:
    """Call ``system``'s own Jacobian hooks (``stiff_jacobian``, ``load_jacobian``) once at its
    initial state ``(t, x)``, as a linearly implicit scheme does (:func:`local_jacobian`): a
    :class:`~parastokes.bodies.contract.BodyError` naming the hook for a value that is no
    matrix, of the wrong shape or not finite, or an error it raises. Nothing without hooks."""
    if all(getattr(system, hook, None) is None for hook in ("stiff_jacobian", "load_jacobian")):
        return
    n_rates = np.asarray(system.rates(t, x)).size
    try:
        local_jacobian(system, t, x, n_rates)
    except NonFiniteJacobian as error:
        raise contract.BodyError(f"{error.method} returned {error.kind} at the initial state; "
                                 "expected finite values", error.method) from None


def block_jacobian(parts: list[tuple[int, int, Any]], rows: int, width: int) -> sp.csr_array:
    """A block-diagonal ``A`` over ``rows`` rows of rates padded to ``width`` columns (a
    scene's): ``parts`` are ``(first row, rate columns, A of the body or None)``."""
    data: list[np.ndarray] = []
    r_all: list[np.ndarray] = []
    c_all: list[np.ndarray] = []
    for first, rc, matrix in parts:
        if matrix is None:
            continue
        coo = sp.coo_array(matrix)
        for index, out in ((coo.row, r_all), (coo.col, c_all)):
            out.append((first + index // rc) * width + index % rc)
        data.append(coo.data)
    if not data:
        return sp.csr_array((rows * width, rows * width))
    return sp.csr_array((np.concatenate(data), (np.concatenate(r_all), np.concatenate(c_all))),
                        shape=(rows * width, rows * width))


def jacobian_check(body: Any, t: float, x: np.ndarray) -> float:
    """The largest difference between the load Jacobian the body provides (its
    ``load_jacobian``, or the coloured finite differences over its ``load_coupling``) and dense
    finite differences, relative to the largest entry: a wrong Jacobian or a coupling pattern
    that misses a dependence shows as a difference of order one."""
    given = load_jacobian(body, t, x).toarray()
    dense = load_jacobian(body, t, x, dense=True).toarray()
    scale = max(float(np.abs(dense).max()), 1e-300)
    return float(np.abs(given - dense).max() / scale)
