"""Extrapolation weights: Lagrange in the physical parameters, Richardson in the time step.

- :func:`lagrange_weights` gives the weights ``w_i^j`` of eq. 17 (one parameter) and, for several
  parameters, their tensor product ``w_j = w_1^{j_1} w_2^{j_2} w_3^{j_3}`` of eqs. 22 and 25.
- :func:`richardson_weights` gives the weights ``v_q`` of eq. 27 derived from the recursion eq. 26
  (Table 1 of the paper prints them for m <= 2; its m = 2 row is wrong, see ``docs/parareal.md``).
- :func:`step_weights` gives the weights for arbitrary, actually taken steps ``h_q``: the unique
  ``v`` with ``sum_q v_q = 1`` and ``sum_q v_q h_q^(alpha + j) = 0`` for ``j = 0 .. m - 1``, i.e.
  the combination that cancels the error terms ``tau^alpha .. tau^(alpha + m - 1)``. For
  ``h_q = r^q tau`` it coincides with :func:`richardson_weights`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:  # typing.TypeIs is Python 3.13's
    from typing_extensions import TypeIs

__all__ = [
    "check_nodes",
    "lagrange_weights",
    "richardson_weights",
    "step_weights",
    "validate_richardson",
]


def check_nodes(theta0: float, nodes: npt.ArrayLike, name: str) -> np.ndarray:
    """Check the conditions 1-2 of section 4.1 on one parameter's nodes; return them as an array."""
    values = np.asarray(nodes, dtype=float)
    if values.ndim != 1 or values.size == 0:
        raise ValueError(f"{name}: the nodes must be a non-empty 1-D sequence, got {nodes!r}")
    if not (np.all(np.isfinite(values)) and math.isfinite(theta0)):
        raise ValueError(f"{name}: theta0 and the nodes must be finite")
    if np.any(np.diff(values) <= 0.0):
        raise ValueError(
            f"{name}: condition 1 of section 4.1 fails: the nodes must be strictly increasing, "
            f"got {values.tolist()}"
        )
    if values[0] <= theta0 <= values[-1]:
        raise ValueError(
            f"{name}: condition 2 of section 4.1 fails: theta0 = {theta0} must lie outside the "
            f"node interval [{values[0]}, {values[-1]}]"
        )
    return values


def _lagrange_1d(theta0: float, nodes: np.ndarray) -> np.ndarray:
    """Eq. 17: w^j = prod_{l != j} (theta0 - theta^l) / (theta^j - theta^l)."""
    weights = np.ones(nodes.size)
    for j in range(nodes.size):
        for node_l in np.delete(nodes, j):
            weights[j] *= (theta0 - node_l) / (nodes[j] - node_l)
    return weights


def _is_scalar(theta0: float | Sequence[float]) -> TypeIs[float]:
    """One parameter's θ⁰ (a number), not several (a sequence)."""
    return np.ndim(theta0) == 0


def lagrange_weights(
    theta0: float | Sequence[float], nodes: Sequence[float] | Sequence[Sequence[float]]
) -> np.ndarray:
    """Lagrange extrapolation weights in the physical parameters (eqs. 17, 22 and 25).

    ``lagrange_weights(theta0, [theta^1, ..., theta^N])`` returns the N weights of eq. 17 for one
    parameter. With several parameters, ``theta0 = (theta_1^0, ..., theta_P^0)`` and
    ``nodes = (nodes_1, ..., nodes_P)``, it returns the tensor-product weights of eq. 25 as an
    array of shape ``(N_1, ..., N_P)``: ``w[j_1, ..., j_P] = prod_i w_i^{j_i}`` (eq. 22), whose flat
    C-order enumeration matches ``itertools.product(*nodes)``.

    Raises ValueError when the nodes of a parameter are not strictly increasing (condition 1 of
    section 4.1) or when theta^0 lies inside their interval (condition 2).
    """
    if _is_scalar(theta0):
        return _lagrange_1d(float(theta0), check_nodes(float(theta0), nodes, "lagrange"))
    theta0 = [float(value) for value in theta0]
    if len(theta0) != len(nodes):
        raise ValueError(f"got {len(theta0)} values of theta0 but {len(nodes)} node sets")
    weights = np.ones(())
    node_sets: Sequence[npt.ArrayLike] = nodes
    for i, (value, node_set) in enumerate(zip(theta0, node_sets, strict=True)):
        weights = np.multiply.outer(
            weights, _lagrange_1d(value, check_nodes(value, node_set, f"parameter {i}"))
        )
    return weights


def validate_richardson(m: int, r: float | None = None) -> None:
    """Check the Richardson parameters of eq. 26: m a non-negative integer, r in (0, 1)."""
    if isinstance(m, bool) or not isinstance(m, int | np.integer) or m < 0:
        raise ValueError(f"richardson: m must be a non-negative integer, got {m!r}")
    if r is not None and not (isinstance(r, int | float) and 0.0 < r < 1.0):
        raise ValueError(f"richardson: r must lie in the open interval (0, 1), got {r!r}")
    if m > 0 and r is None:
        raise ValueError("richardson: r is required when m >= 1")


def richardson_weights(m: int, r: float, order: int) -> np.ndarray:
    """Weights v_0..v_m of eq. 27 (steps r^q tau) from the recursion eq. 26.

    R_0 = G_tau and R_m(tau) = (r^(alpha+m-1) R_{m-1}(tau) - R_{m-1}(r tau)) / (r^(alpha+m-1) - 1),
    where R_{m-1}(r tau) has the weights of R_{m-1}(tau) shifted by one step. ``order`` is alpha,
    the order of accuracy of the auxiliary solver. The weights sum to 1 (Lemma 1) and cancel the
    error terms tau^alpha .. tau^(alpha+m-1).
    """
    validate_richardson(m, r if m > 0 else None)
    if isinstance(order, bool) or not isinstance(order, int | np.integer) or order < 1:
        raise ValueError(f"richardson: the order must be a positive integer, got {order!r}")
    weights = np.ones(1)
    for level in range(1, m + 1):
        factor = r ** (order + level - 1)
        weights = (factor * np.append(weights, 0.0) - np.insert(weights, 0, 0.0)) / (factor - 1.0)
    return weights


def step_weights(steps: Sequence[float] | np.ndarray, order: int) -> np.ndarray:
    """Richardson weights for the steps h_0..h_m actually taken (the general form of eq. 27).

    Solves sum_q v_q = 1 and sum_q v_q h_q^(alpha + j) = 0 for j = 0 .. m - 1 (alpha = ``order``),
    so that the combination cancels the error terms tau^alpha .. tau^(alpha + m - 1) exactly as
    eq. 26 does for geometric steps. The steps are scaled by the largest one (the equations are
    invariant under that scaling) to keep the Vandermonde-like system well conditioned.
    """
    h = np.asarray(steps, dtype=float)
    if h.ndim != 1 or h.size == 0 or np.any(~np.isfinite(h)) or np.any(h <= 0.0):
        raise ValueError(f"richardson: the steps must be positive and finite, got {steps!r}")
    if np.unique(h).size != h.size:
        raise ValueError(
            f"richardson: the steps actually taken must be distinct, got {h.tolist()} "
            "(after rounding to whole step counts two auxiliary solvers coincide; "
            "use a smaller dt, a smaller r or longer time slices)"
        )
    scaled = h / h.max()
    matrix = np.vstack([np.ones_like(scaled)] + [scaled ** (order + j) for j in range(h.size - 1)])
    rhs = np.zeros(h.size)
    rhs[0] = 1.0
    return np.linalg.solve(matrix, rhs)
