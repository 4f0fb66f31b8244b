"""The solves run BLAS on at most the fluid's threads (parastokes.mobility.threads), whatever
the process's BLAS default, and leave that default as it was."""

from __future__ import annotations

import numpy as np
import pytest
import threadpoolctl

from parastokes.mobility import RigidSurface, choice, resistance_matrix, solve_mobility
from parastokes.mobility.sphere import fibonacci_sphere


def _blas_threads() -> set[int]:
    return {lib["num_threads"] for lib in threadpoolctl.threadpool_info()
            if lib["user_api"] == "blas"}


@pytest.mark.parametrize("method", ["dense", "gmres"])
def test_a_solve_limits_blas_to_the_fluids_threads_and_restores_the_default(monkeypatch, method):
    seen: list[set[int]] = []
    for name in ("direct_solve", "gmres_solve"):
        original = getattr(choice, name)

        def spy(*args, _original=original, **kwargs):
            seen.append(_blas_threads())
            return _original(*args, **kwargs)

        monkeypatch.setattr(choice, name, spy)
    surface = RigidSurface(fibonacci_sphere(60), 0.2)
    with threadpoolctl.threadpool_limits(limits=2, user_api="blas"):
        assert _blas_threads() == {2}
        result = solve_mobility(surface.place((0.0, 0.0, 2.0)), mu=1.0, wall=True,
                                external_force=(0.0, 0.0, -1.0), method=method, n_threads=1)
        assert _blas_threads() == {2}
        assert np.isfinite(result.U).all()
    assert seen == [{1}]


def test_the_resistance_matrix_is_factorized_on_one_blas_thread(monkeypatch):
    from parastokes.mobility import direct

    seen: list[set[int]] = []
    original = direct.factor_for
    monkeypatch.setattr(direct, "factor_for",
                        lambda *a, **k: (seen.append(_blas_threads()), original(*a, **k))[1])
    with threadpoolctl.threadpool_limits(limits=2, user_api="blas"):
        resistance_matrix(RigidSurface(fibonacci_sphere(40), 0.3), (0.0, 0.0, 2.0), mu=1.0,
                          wall=True)
    assert seen == [{1}]
