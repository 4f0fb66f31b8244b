"""``validation.map_norm``: the spectral radius and norm of a map's linearization from finite
differences, on linear maps whose answers are known (docs/validation.md section 2, section 3).

The map is non-normal with its largest eigenvalues clustered near 1, like the coarse maps over
the paper's slices: a few power-iteration steps from a random start return neither the spectral
radius nor the norm and depend on the start (the defect this module replaced); the estimates here
must not.
"""

from __future__ import annotations

import numpy as np
import pytest

from validation import map_norm

N = 20  # points: 3N = 60 unknowns


def _linear_map(seed: int = 3):
    """(A, propagate): x -> x with its positions replaced by A applied to them."""
    rng = np.random.default_rng(seed)
    eigenvalues = np.concatenate([[1.05, 1.0, 0.999, 0.998], rng.uniform(-0.5, 0.9, 3 * N - 4)])
    basis = np.eye(3 * N) + 0.4 * rng.standard_normal((3 * N, 3 * N)) / np.sqrt(3 * N)
    a = basis @ np.diag(eigenvalues) @ np.linalg.inv(basis)

    def propagate(x: np.ndarray) -> np.ndarray:
        out = x.copy()
        out[:, :3] = (a @ x[:, :3].ravel()).reshape(-1, 3)
        return out

    return a, propagate


def _x0() -> np.ndarray:
    return np.random.default_rng(0).standard_normal((N, 4))  # a fourth column the map keeps


def _positions(x: np.ndarray) -> np.ndarray:
    return x[:, :3]


def _power_iteration(a: np.ndarray, seed: int, steps: int = 5) -> float:
    d = np.random.default_rng(seed).standard_normal(len(a))
    gain = 0.0
    for _ in range(steps):
        d = a @ (d / np.linalg.norm(d))
        gain = float(np.linalg.norm(d))
    return gain


def test_a_short_power_iteration_depends_on_its_start_here():
    """The premise: five steps give neither rho nor the norm, and differ between starts."""
    a, _ = _linear_map()
    rho = np.abs(np.linalg.eigvals(a)).max()
    gains = [_power_iteration(a, seed) for seed in (0, 1)]
    assert abs(gains[0] - gains[1]) > 2e-3 * rho
    assert all(abs(g - rho) > 1e-2 * rho for g in gains)


def test_dense_gives_the_spectral_radius_and_the_norm():
    a, propagate = _linear_map()
    probe = map_norm.Probe(propagate, _positions, _x0())
    rho, norm = map_norm.dense(probe)
    assert rho == pytest.approx(np.abs(np.linalg.eigvals(a)).max(), rel=1e-6)
    assert norm == pytest.approx(np.linalg.norm(a, 2), rel=1e-6)
    assert probe.calls == 3 * N + 1
    central = map_norm.Probe(propagate, _positions, _x0(), central=True)
    assert map_norm.dense(central)[0] == pytest.approx(rho, rel=1e-6)
    assert central.calls == 6 * N


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_arnoldi_radius_is_the_spectral_radius_from_any_start(seed):
    a, propagate = _linear_map()
    probe = map_norm.Probe(propagate, _positions, _x0())
    assert map_norm.arnoldi_radius(probe, seed) == pytest.approx(1.05, rel=1e-6)
    assert np.abs(np.linalg.eigvals(a)).max() == pytest.approx(1.05, rel=1e-12)


def test_linearization_chooses_by_size(monkeypatch):
    _, propagate = _linear_map()
    found = map_norm.linearization(propagate, _positions, _x0())
    assert found["method"] == "dense" and found["rho"] == pytest.approx(1.05, rel=1e-6)
    monkeypatch.setattr(map_norm, "DENSE_LIMIT", 3 * N - 1)
    found = map_norm.linearization(propagate, _positions, _x0())
    assert found["method"] == "arnoldi" and np.isnan(found["norm"])
    assert found["rho"] == pytest.approx(1.05, rel=1e-6)
