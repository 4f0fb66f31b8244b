"""A learned Parareal correction: eq. 11 plus a secant estimate of (F - G)' on each slice.

Eq. 11 forms X_n^k = F(X_{n-1}^{k-1}) + G(X_{n-1}^k) - G(X_{n-1}^{k-1}): it takes the
fine-coarse difference D_n(x) = F(x) - G(x) at the previous iterate as if it did not depend on
the state, so Parareal is Newton's method on the shooting equations with F's Jacobian replaced by
G's (Gander & Vandewalle, SIAM J. Sci. Comput. 29, 2007). The ``secant`` correction adds the part
of D_n' that the previous iterates of slice n have already measured::

    X_n^k = eq. 11 + J_n^k (X_{n-1}^k - X_{n-1}^{k-1}),
    J_n^k s = dD c,   c = argmin_c |dX c - s|  (minimum norm),

with the columns dX_i = X_{n-1}^i - X_{n-1}^{i-1} and dD_i = D_n(X_{n-1}^i) - D_n(X_{n-1}^{i-1})
for i = 1..k-1 (zero columns, converged inputs, left out): J_n^k is the minimum-norm linear map
with J dX_i = dD_i, the secant (multi-secant, Broyden-like) estimate of D_n' on the span of the
previous steps. This is the idea of Krylov-subspace-enhanced Parareal (Gander & Petcu, ESAIM Proc.
25, 2008: on the span of the previous iterates F is applied exactly, for a linear problem) applied
to D_n alone and slice by slice; GParareal (Pentland et al., Statistics and Computing 33:20, 2023)
learns D from the same data by a Gaussian process (docs/parareal.md, "Learned corrections";
docs/benchmarks.md measures both on the rods).

Properties (tests/test_parareal_learned.py): the correction reduces to eq. 11 exactly (bit for bit)
when X_{n-1}^k = X_{n-1}^{k-1}, so the first k slices are exact after k iterations as in
Parareal; when D_n is affine the secant is exact on the span of the steps, and with as many steps
as the state has dimensions X_n^k = F(X_{n-1}^k). Everything X_n^k uses is slice n's own data of
iterations 0..k-1, which both schedules have when they form X_n^k, so their iterates agree bit for
bit.
"""

from __future__ import annotations

import numpy as np

__all__ = ["CORRECTIONS", "SecantHistory", "secant_step"]

#: The corrections of :func:`parastokes.parareal.run` (``correction=``): eq. 11, or eq. 11 plus
#: the secant term of :class:`SecantHistory`.
CORRECTIONS = ("classical", "secant")


def secant_step(dx: np.ndarray, dd: np.ndarray, step: np.ndarray) -> np.ndarray:
    """J ``step`` for the minimum-norm least-squares J with J dx_i = dd_i (the columns of ``dx``
    and ``dd``, shape (size, m)): ``dd`` c with c the least-squares coefficients of ``step`` in
    the columns of ``dx``. Zero when there are no columns or ``step`` is zero."""
    if dx.shape[1] == 0 or not np.any(step):
        return np.zeros_like(step)
    coefficients, *_ = np.linalg.lstsq(dx, step, rcond=None)
    return dd @ coefficients


class SecantHistory:
    """Each slice's inputs X_{n-1}^i and fine-coarse differences D_n(X_{n-1}^i), i = 0, 1, ...,
    and the secant term of the correction that forms X_n^k from them."""

    def __init__(self) -> None:
        self._points: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}

    def to_arrays(self) -> dict[str, np.ndarray]:
        """The pairs as arrays for a checkpoint (:meth:`from_arrays` reads them back exactly);
        empty when there are none."""
        if not self._points:
            return {}
        keys = sorted(self._points)
        return {"secant_keys": np.array(keys, dtype=np.int64),
                "secant_inputs": np.array([self._points[key][0] for key in keys]),
                "secant_differences": np.array([self._points[key][1] for key in keys])}

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> SecantHistory:
        """The history saved by :meth:`to_arrays` (none saved: an empty one)."""
        history = cls()
        if "secant_keys" in arrays:
            for (n, i), x, d in zip(arrays["secant_keys"], arrays["secant_inputs"],
                                    arrays["secant_differences"], strict=True):
                history._points[int(n), int(i)] = (x, d)
        return history

    def has(self, n: int, i: int) -> bool:
        """Whether slice n's pair of iteration i is known (i < 0: trivially)."""
        return i < 0 or (n, i) in self._points

    def correction(
        self,
        n: int,
        k: int,
        new_input: np.ndarray,
        old_input: np.ndarray,
        fine_value: np.ndarray,
        previous_coarse: np.ndarray,
    ) -> np.ndarray:
        """The secant term J_n^k (X_{n-1}^k - X_{n-1}^{k-1}) added to eq. 11 for X_n^k.

        ``old_input`` = X_{n-1}^{k-1}, ``fine_value`` = F(X_{n-1}^{k-1}) and ``previous_coarse`` =
        G(X_{n-1}^{k-1}) (the three that eq. 11 uses) are kept as slice n's pair of iteration
        k - 1; the pairs of iterations 0..k-2 must be known (:meth:`has`), as they are once
        X_n^{k-1} has been formed.
        """
        if not self.has(n, k - 2):
            raise RuntimeError(f"secant correction of slice {n} in iteration {k} before that of "
                               f"iteration {k - 1} (please report)")
        self._points[n, k - 1] = (np.array(old_input), fine_value - previous_coarse)
        dx, dd = [], []
        for i in range(1, k):
            (x, d), (x_old, d_old) = self._points[n, i], self._points[n, i - 1]
            step = x - x_old
            if np.any(step):
                dx.append(step.ravel())
                dd.append((d - d_old).ravel())
        shape = new_input.shape
        if not dx:
            return np.zeros(shape)
        step = (new_input - old_input).ravel()
        return secant_step(np.array(dx).T, np.array(dd).T, step).reshape(shape)
