"""``parastokes.tuning.slice_map`` and the tuner's verdict on it (``stability.spectral_radius``),
on linear maps whose answers are known.

The map is far from normal (‖A‖ ≫ ρ(A)) with its largest eigenvalues near 1, like the coarse maps
over the paper's slices (docs/validation.md section 2): a few power-iteration steps from a random
start, what the tuner used before, return neither ρ nor the norm and depend on the start; the
estimate here must be ρ to its tolerance from any start, and must say when it did not converge.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from parastokes import integrate
from parastokes.tuning import slice_map, stability

N = 20  # points: 3N = 60 unknowns


def _non_normal(top: float = 1.05, seed: int = 3) -> np.ndarray:
    """Q T Q^T: T upper triangular with eigenvalues ``top``, 1, 0.999, 0.998 (a cluster below the
    top, like the rigid and slow modes of the rods), 0, 0.01 and the rest in (-0.5, 0.9); the
    coupling 50 between the two damped modes makes ‖A‖ = 50 (a one-step transient)."""
    rng = np.random.default_rng(seed)
    size = 3 * N
    eigenvalues = np.concatenate([[top, 1.0, 0.999, 0.998, 0.0, 0.01],
                                  rng.uniform(-0.5, 0.9, size - 6)])
    t = np.diag(eigenvalues) + np.triu(rng.standard_normal((size, size)), 1) / np.sqrt(size)
    t[4, 5] = 50.0
    q, _ = np.linalg.qr(rng.standard_normal((size, size)))
    return q @ t @ q.T


def _propagate(a: np.ndarray):
    """x -> x with its positions (columns 0-2) replaced by A applied to them."""

    def propagate(x: np.ndarray) -> np.ndarray:
        out = x.copy()
        out[:, :3] = (a @ x[:, :3].ravel()).reshape(-1, 3)
        return out

    return propagate


def _x0() -> np.ndarray:
    return np.random.default_rng(0).standard_normal((N, 4))  # a fourth column the map keeps


def _positions(x: np.ndarray) -> np.ndarray:
    return np.array(x[:, :3])


def _probe(a: np.ndarray) -> slice_map.Probe:
    return slice_map.Probe(_propagate(a), _positions, _x0())


def _power_iteration(a: np.ndarray, seed: int, steps: int = 4) -> float:
    d = np.random.default_rng(seed).standard_normal(len(a))
    gain = 0.0
    for _ in range(steps):
        d = a @ (d / np.linalg.norm(d))
        gain = float(np.linalg.norm(d))
    return gain


def test_the_map_is_far_from_normal_and_defeats_a_short_power_iteration():
    """The premise: ‖A‖ ≫ ρ(A), and four steps (the tuner's former estimate) give neither, and
    differ between starts."""
    a = _non_normal()
    assert np.abs(np.linalg.eigvals(a)).max() == pytest.approx(1.05, rel=1e-9)
    assert np.linalg.norm(a, 2) > 40 * 1.05
    gains = [_power_iteration(a, seed) for seed in range(5)]
    assert max(gains) - min(gains) > 0.5
    assert max(abs(g - 1.05) for g in gains) > 0.3


def test_dense_gives_the_spectral_radius_and_the_norm():
    a = _non_normal()
    probe = _probe(a)
    rho, norm = slice_map.dense(probe)
    assert rho == pytest.approx(1.05, rel=1e-6)
    assert norm == pytest.approx(np.linalg.norm(a, 2), rel=1e-6)
    assert probe.calls == 3 * N + 1
    central = slice_map.Probe(_propagate(a), _positions, _x0(), central=True)
    assert slice_map.dense(central)[0] == pytest.approx(rho, rel=1e-6)
    assert central.calls == 6 * N


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
def test_radius_is_the_spectral_radius_from_any_start(seed):
    """A tight tolerance: ρ to 1e-6 from any start (about 50 calls). The tuner's settings
    (tolerance 1e-2, Krylov space 20, at most 80 calls): ρ to a few times the tolerance
    (ARPACK's test bounds the residual; the cluster 5e-2 below the top blurs it: 1.022-1.046),
    in 22 calls; a four-step power iteration read 0.45-1.40 here."""
    tight = slice_map.radius(_probe(_non_normal()), seed, tol=1e-8, max_calls=None)
    assert tight.converged and tight.rho == pytest.approx(1.05, rel=1e-6)
    found = slice_map.radius(_probe(_non_normal()), seed)
    assert found.converged
    assert found.rho == pytest.approx(1.05, rel=5 * slice_map.TOLERANCE)
    assert found.calls <= slice_map.MAX_CALLS


def test_radius_says_when_it_did_not_converge():
    """A bound on the calls below one Krylov space: no number, and the calls it took."""
    found = slice_map.radius(_probe(_non_normal()), 0, krylov=12, max_calls=8)
    assert not found.converged and math.isnan(found.rho)
    assert found.calls == 8


class _Linear:
    """A system of N points whose slice map is x -> A x on the positions (a propagator
    ``(t0, t1, x)``); ``blow_up`` raises integrate.BlowUpError for perturbed states."""

    def __init__(self, a: np.ndarray, blow_up: bool = False) -> None:
        self.step = _propagate(a)
        self.blow_up = blow_up

    def positions(self, state: np.ndarray) -> np.ndarray:
        return _positions(state)

    def __call__(self, t0: float, t1: float, x: np.ndarray) -> np.ndarray:
        if self.blow_up and not np.array_equal(x, _x0()):
            raise integrate.BlowUpError(t1, 0, math.nan, x, "perturbed state blew up")
        return self.step(x)


@pytest.mark.parametrize("top", [1.05, 1.3])
def test_verdict_rests_on_the_spectral_radius_not_the_norm(top):
    """Both maps have a norm (50) above what even 4 slices allow (GROWTH^(1/4) = 3.16); over 40
    slices (1.122 allowed) the one with ρ = 1.05 passes, the one with ρ = 1.3 is rejected."""
    a = _non_normal(top)
    system = _Linear(a)
    found = stability.spectral_radius(system, system, _x0(), 0.0, 1.0,  # type: ignore[arg-type]
                                      tol=stability.radius_tolerance(40))
    assert found.converged and found.rho == pytest.approx(top, rel=5e-2)
    assert np.linalg.norm(a, 2) > stability.allowed_radius(1.0, 4)
    assert (found.rho <= stability.allowed_radius(1.0, 40)) == (top < 1.1)


def test_blow_up_of_a_perturbed_state_is_infinite_growth():
    system = _Linear(_non_normal(), blow_up=True)
    found = stability.spectral_radius(system, system, _x0(), 0.0, 1.0)  # type: ignore[arg-type]
    assert found.converged and found.rho == math.inf and found.calls == 2


def test_positions_that_are_not_the_first_columns_are_refused():
    with pytest.raises(ValueError, match="columns 0-2"):
        slice_map.Probe(_propagate(_non_normal()), lambda x: x[:, 1:4], _x0())
