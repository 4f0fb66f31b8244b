"""Vesicles on a coarser icosphere (``VesicleSystem.coarsened``, ``coarse.grid_factor``): the
levels a factor drops, restriction and prolongation exact where they must be, and the config's
coarse-grid solver built on the coarse mesh."""

from __future__ import annotations

import numpy as np
import pytest

from parastokes import config, models, parareal
from parastokes.kinds.vesicle.transfer import VesicleTransfer, levels_down


def test_levels_down_powers_of_two_only():
    assert [levels_down(f, 3) for f in (1, 2, 4, 8)] == [0, 1, 2, 3]
    for factor in (3, 6, 16, 0, True):
        with pytest.raises(ValueError):
            levels_down(factor, 3)


def _rotation(seed: int) -> np.ndarray:
    q, r = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    return q * np.sign(np.diag(r))


@pytest.mark.parametrize("factor", [2, 4])
def test_a_moved_sphere_prolongs_exactly(factor):
    ves = models.vesicle(subdivisions=3, radius=1.5, n_threads=1)
    coarse, transfer = ves.coarsened(factor)
    assert coarse.subdivisions == 3 - factor.bit_length() + 1
    moved = ves.initial_state() @ _rotation(factor).T + np.array([0.3, -2.0, 1.0])
    np.testing.assert_allclose(transfer.prolong(transfer.restrict(moved)), moved, atol=1e-13)


def test_restriction_undoes_prolongation():
    transfer = VesicleTransfer(3, 1, 1.0)
    xc = np.random.default_rng(1).normal(size=(42, 3))
    fine = transfer.prolong(xc)
    assert fine.shape == (642, 3)
    np.testing.assert_array_equal(transfer.restrict(fine), xc)


def test_a_deformed_sphere_prolongs_within_its_deformation_times_the_sag():
    """An ellipsoid of semi-axes (1 + d, 1, 1): the new vertices miss it by O(d · sag), so the
    error shrinks with d (first order) and is far below d itself."""
    ves = models.vesicle(subdivisions=2, n_threads=1)
    _, transfer = ves.coarsened(2)
    errors = []
    for d in (1e-2, 1e-3):
        shape = ves.initial_state() * np.array([1 + d, 1.0, 1.0])
        errors.append(np.abs(transfer.prolong(transfer.restrict(shape)) - shape).max())
    assert errors[0] < 0.1 * 1e-2
    assert errors[1] == pytest.approx(errors[0] / 10, rel=0.05)


def test_config_grid_factor_puts_the_vesicle_coarse_solver_on_the_coarse_mesh():
    text = """
title = "vesicle on a coarser mesh"
[model]
kind = "vesicle"
subdivisions = 2
[time]
t1 = 0.02
[fine]
scheme = "euler"
dt = 0.001
[coarse]
scheme = "euler"
dt = 0.005
grid_factor = 2
[coarse.lagrange]
epsilon = { nodes = [0.6], unit = "l_max" }
[parareal]
n_slices = 2
[execution]
executor = "serial"
"""
    cfg, resolved = config.loads(text)
    assert resolved.coarse_points == 42
    setup = config.build(cfg, resolved)
    assert isinstance(setup.coarse, parareal.OnCoarseGrid)
    x0 = setup.system.initial_state()
    out = setup.coarse(0.0, 0.01, x0)
    assert out.shape == x0.shape and np.isfinite(out).all()
    with pytest.raises(config.ConfigError, match="grid_factor"):
        config.loads(text.replace("grid_factor = 2", "grid_factor = 3"))
