"""Higher-order dynamic mode decomposition (HODMD, Le Clainche & Vega 2017), as HODMD-Parareal
uses it (Liu, arXiv 2503.03109, section 3; docs/hodmd.md).

:func:`hodmd` takes K snapshots v_1..v_K (the columns of V, equally spaced by Δt) and returns a
:class:`Decomposition`, from which :meth:`Decomposition.reconstruct` evaluates the expansion

    v(t) ≈ Re Σ_m U u_m exp((δ_m + i ω_m)(t − t_1))

at any time t (inside the window: a fit; beyond it: an extrapolation). The steps:

1. reduced SVD V = U Σ Tᴴ, keeping the N leading singular values with
   ‖σ_{k..n}‖ / ‖σ‖ > ε1 (the relative tolerance), and the reduced snapshots T̂ = Σ Tᴴ (N × K);
2. the modified snapshot matrix of d delayed copies: block row p (p = 0..d−1) is T̂[:, p:p+K−d+1]
   (dN × (K − d + 1));
3. its reduced SVD with the same tolerance, T̃ ≈ U₁ T̂₁;
4. the reduced Koopman matrix R = T̂₁[:, 1:] T̂₁[:, :−1]⁺ and its eigenpairs (λ_m, q_m);
   δ_m + i ω_m = log(λ_m) / Δt: growth rates and angular frequencies;
5. modes: the last N rows of U₁ q_m, normalized; amplitudes a_m by least squares over ALL K
   snapshots, T̂[:, k] ≈ Σ_m a_m λ_m^k mode_m;
6. modes whose amplitude ‖U u_m‖/√J (u_m = a_m mode_m) is below ε times the largest are dropped.

With d = 1 this is exact DMD of the reduced snapshots, which can represent at most N modes: a
standing wave cos(ωt) φ (rank N = 1) needs two (e^{±iωt}), so only d >= 2 recovers it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Decomposition", "expansion", "hodmd", "minimum_snapshots", "retained_rank"]


def retained_rank(singular_values: np.ndarray, tolerance: float) -> int:
    """How many singular values to keep: those σ_k with ‖σ_{k..n}‖ / ‖σ‖ > ``tolerance``
    (all of a zero matrix's: none)."""
    sigma = np.asarray(singular_values, dtype=float)
    total = float(np.linalg.norm(sigma))
    if total == 0.0:
        return 0
    tails = np.sqrt(np.cumsum((sigma**2)[::-1])[::-1]) / total
    return int(np.count_nonzero(tails > tolerance))


def minimum_snapshots(d: int) -> int:
    """The fewest snapshots HODMD with ``d`` delayed copies can use: K − d + 1 >= 2 columns."""
    return d + 1


@dataclass(frozen=True)
class Decomposition:
    """A HODMD expansion (see the module docstring); ``reconstruct`` evaluates it.

    ``basis``: U, J × N (the kept left singular vectors); ``modes``: u_m = a_m mode_m, N × M
    complex; ``growth_rates`` δ_m, ``frequencies`` ω_m, ``amplitudes`` ‖U u_m‖/√J, sorted by
    decreasing amplitude; ``t0``: the time of the first snapshot; ``dt``: the snapshot spacing.
    """

    basis: np.ndarray
    modes: np.ndarray
    growth_rates: np.ndarray
    frequencies: np.ndarray
    amplitudes: np.ndarray
    t0: float
    dt: float

    @property
    def eigenvalues(self) -> np.ndarray:
        """λ_m = exp((δ_m + i ω_m) Δt), the Koopman eigenvalues of the kept modes."""
        return np.exp((self.growth_rates + 1j * self.frequencies) * self.dt)

    def reconstruct(self, times: np.ndarray | float) -> np.ndarray:
        """Re Σ_m U u_m exp((δ_m + i ω_m)(t − t0)) at each time: J × len(times) (J for a scalar
        time). The imaginary part (round-off of conjugate pairs) is discarded explicitly."""
        scalar = np.ndim(times) == 0
        t = np.atleast_1d(np.asarray(times, dtype=float)) - self.t0
        rates = self.growth_rates + 1j * self.frequencies
        reduced = self.modes @ np.exp(np.outer(rates, t))
        values = (self.basis @ reduced).real
        return values[:, 0] if scalar else values


def _truncated_svd(matrix: np.ndarray, tolerance: float) -> tuple[np.ndarray, np.ndarray]:
    """U_r and Σ_r V_rᴴ of the SVD of ``matrix`` truncated by :func:`retained_rank`."""
    u, sigma, vh = np.linalg.svd(matrix, full_matrices=False)
    rank = retained_rank(sigma, tolerance)
    return u[:, :rank], sigma[:rank, None] * vh[:rank]


def hodmd(snapshots: np.ndarray, d: int, dt: float = 1.0, t0: float = 0.0,
          svd_tolerance: float = 1e-8, amplitude_tolerance: float = 1e-8) -> Decomposition:
    """HODMD of ``snapshots`` (J × K, column k at time t0 + k dt) with ``d`` delayed copies, the
    SVD tolerance ε1 = ``svd_tolerance`` and the mode tolerance ε = ``amplitude_tolerance``
    (module docstring, steps 1-6). A zero snapshot matrix gives the empty expansion (zero)."""
    v = np.asarray(snapshots, dtype=float)
    if v.ndim != 2:
        raise ValueError(f"snapshots must be a J x K matrix (one column per time), got {v.shape}")
    j_rows, k_cols = v.shape
    if isinstance(d, bool) or not isinstance(d, int | np.integer) or d < 1:
        raise ValueError(f"d must be an integer >= 1, got {d!r}")
    if k_cols < minimum_snapshots(d):
        raise ValueError(
            f"HODMD with d = {d} needs at least {minimum_snapshots(d)} snapshots, got {k_cols}"
        )
    for name, value in (("svd_tolerance", svd_tolerance),
                        ("amplitude_tolerance", amplitude_tolerance)):
        if not 0.0 <= value < 1.0:
            raise ValueError(f"{name} must lie in [0, 1), got {value!r}")
    if not dt > 0:
        raise ValueError(f"dt must be positive, got {dt!r}")

    basis, reduced = _truncated_svd(v, svd_tolerance)  # step 1: U (J × N), T̂ (N × K)
    n_rank = basis.shape[1]
    empty = Decomposition(basis[:, :0], np.zeros((0, 0), complex), np.zeros(0), np.zeros(0),
                          np.zeros(0), float(t0), float(dt))
    if n_rank == 0:
        return empty
    width = k_cols - d + 1  # step 2: the d delayed copies
    delayed = np.vstack([reduced[:, p:p + width] for p in range(d)])
    u1, reduced1 = _truncated_svd(delayed, svd_tolerance)  # step 3
    if u1.shape[1] == 0:
        return empty
    # step 4: R = T̂₁[:, 1:] T̂₁[:, :-1]⁺ (pseudo-inverse by the SVD of T̂₁[:, :-1])
    koopman = reduced1[:, 1:] @ np.linalg.pinv(reduced1[:, :-1])
    eigenvalues, vectors = np.linalg.eig(koopman)
    keep = np.abs(eigenvalues) > 0  # a zero eigenvalue leaves nothing after the first step
    eigenvalues, vectors = eigenvalues[keep], vectors[:, keep]
    rates = np.log(eigenvalues.astype(complex)) / dt
    # step 5: modes, the last block of U₁ q_m, normalized; amplitudes over all K snapshots
    modes = (u1 @ vectors)[(d - 1) * n_rank:]
    modes = modes / np.linalg.norm(modes, axis=0)
    powers = eigenvalues[None, :] ** np.arange(k_cols)[:, None]  # K × M
    system = (powers[:, None, :] * modes[None, :, :]).reshape(k_cols * n_rank, -1)
    # columns equilibrated first (the same least-squares solution in exact arithmetic): a mode
    # with |λ| > 1 has a column K orders larger than a decaying one, which would otherwise
    # swamp the solve in round-off
    scale = np.linalg.norm(system, axis=0)
    scale[scale == 0] = 1.0
    scaled_amplitudes, *_ = np.linalg.lstsq(system / scale, reduced.T.reshape(-1).astype(complex),
                                            rcond=None)
    amplitudes = scaled_amplitudes / scale
    scaled = modes * amplitudes[None, :]
    size = np.linalg.norm(basis @ scaled, axis=0) / np.sqrt(j_rows)
    # step 6: sort by amplitude, drop the small ones
    order = np.argsort(-size, kind="stable")
    if size.size == 0 or size[order[0]] == 0:
        return empty
    order = order[size[order] / size[order[0]] > amplitude_tolerance]
    return Decomposition(basis, scaled[:, order], rates.real[order], rates.imag[order],
                         size[order], float(t0), float(dt))


def expansion(snapshots: np.ndarray, d: int, tol: float = 1e-8,
              times: np.ndarray | float | None = None) -> np.ndarray:
    """The public ``parastokes.parareal.hodmd(V, d, tol, times)`` (docs/design.md): the HODMD
    expansion of ``snapshots`` V (features × K, at unit spacing from t = 0) with ``d`` delayed
    copies and ``tol`` as both tolerances (ε1 and ε), evaluated, real, at ``times`` (default the
    snapshots' own, 0 .. K - 1; beyond K - 1 an extrapolation): features × len(times)."""
    decomposition = hodmd(snapshots, d, 1.0, 0.0, tol, tol)
    return decomposition.reconstruct(np.arange(np.shape(snapshots)[1]) if times is None
                                     else times)
