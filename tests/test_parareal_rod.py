"""A small rod case: the effect of Fig. 3 (extrapolation in epsilon relaxes the coarse step).

A 6 um swimmer at the paper's resolution (31 nodes, sigma_f = 0.2, epsilon^0 = 5 sigma_f = 1) over
T = 1e-3 in 8 slices. Forward Euler with epsilon^0 needs tau < 1.3e-5 to keep the length within
1%; at tau = 1.5625e-5 it breaks that limit, while the auxiliary solvers with epsilon^j = 1.15,
1.2, 1.25 keep it, and so does their extrapolation to epsilon^0, with which Parareal converges.
"""

import numpy as np
import pytest

from parastokes import integrate, models, parareal

T, N_SLICES, TAU = 1e-3, 8, 1.5625e-5  # 8 coarse steps per slice
NODES = [1.15, 1.2, 1.25]


@pytest.fixture(scope="module")
def rod():
    return models.rod_swimmer(n_points=31, epsilon=1.0, length=6.0)


@pytest.fixture(scope="module")
def fine(rod):
    return integrate.Propagator(rod, "rk2", 4e-6)


def test_plain_coarse_solver_breaks_the_length_limit_but_auxiliary_ones_do_not(rod):
    assert not integrate.is_stable(rod, "euler", TAU, T)
    for epsilon in NODES:
        assert integrate.is_stable(rod.with_params(epsilon=epsilon), "euler", TAU, T)


def test_parareal_with_lagrange_extrapolated_coarse_solver_converges(rod, fine):
    x0 = rod.initial_state()
    reference = parareal.serial_solution(fine, x0, 0.0, T, N_SLICES)
    coarse = parareal.extrapolated(rod, "euler", TAU, lagrange={"epsilon": NODES})
    res = parareal.run(
        fine,
        coarse,
        x0,
        0.0,
        T,
        N_SLICES,
        tol=1e-7,
        max_iterations=N_SLICES,
        reference=reference,
        positions=rod.positions,
        project=rod.project,
    )
    assert res.stop_reason == "tolerance" and res.iterations < N_SLICES
    assert res.errors[0] < 1e-4  # eta^1 of Fig. 3
    assert res.errors[-1] < 1e-7 and res.errors[-1] < res.errors[0] / 100
    assert max(rod.monitor(x) for x in res.states) < rod.monitor_limit
    # the frames stay orthonormal after the corrections (projection hook)
    frames = res.states[-1][:, 3:].reshape(-1, 3, 3)
    np.testing.assert_allclose(
        frames @ frames.transpose(0, 2, 1), np.broadcast_to(np.eye(3), frames.shape), atol=1e-12
    )
