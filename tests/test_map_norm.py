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


def test_an_interrupted_jacobian_resumes_from_its_checkpoint(tmp_path):
    """The vesicle's 1927 calls run in the background: a run stopped after some columns and
    restarted gives the same Jacobian, bit for bit, calling G only for the missing columns."""
    _, propagate = _linear_map()
    fresh = map_norm.Probe(propagate, _positions, _x0()).jacobian()
    where = tmp_path / "columns.npy"
    first = map_norm.Probe(propagate, _positions, _x0())
    np.save(where, np.array([first(e) for e in np.eye(first.size)[:25]]))  # 25 columns done
    again = map_norm.Probe(propagate, _positions, _x0())
    np.testing.assert_array_equal(map_norm.jacobian(again, where, every=8), fresh)
    assert again.calls == 1 + 3 * N - 25
    np.testing.assert_array_equal(np.load(where).T, fresh)  # complete now
    with pytest.raises(ValueError, match="columns of size"):
        map_norm.jacobian(map_norm.Probe(lambda x: x, _positions, _x0()[:-1]), where)
