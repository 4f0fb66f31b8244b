"""``validation.map_norm``: the study's choice between the whole Jacobian and ARPACK at its tight
tolerance (docs/validation.md section 2), on a linear map whose answers are known. The method
itself (``parastokes.tuning.slice_map``: probe, Jacobian, ARPACK) is tested in
tests/test_slice_map.py.
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
