"""Launches that mix viscosities and regularizations (parastokes/gpu/hosted.py, gpu/velocity.py,
gpu/batch.py) on numba's CUDA simulator: a launch batches products of one shape from several
solves, each with its own μ and its own ε (one number, or one per source); each product's result
must be its own CPU kernel's, not the first product's μ or ε. Part of the one-line-bug tests
(docs/validation.md, "Planted one-line bugs (round 5)")."""

import numpy as np
import pytest
from gpu_setup import fast_simulator, gpu  # noqa: F401 (an autouse fixture)

from parastokes import integrate, mrs

pytestmark = pytest.mark.gpu


def _close(got, want):
    for g, w in zip(got, want, strict=True):
        assert np.abs(g - w).max() <= 1e-13 * np.abs(w).max()


def test_one_launch_of_many_viscosities_and_regularizations_gives_each_its_own_velocity():
    """Four solves of one shape above the wall, each with its own μ and ε (two with one ε, two
    with one per source), two rounds of products: one launch per round and kind of ε, holding
    two products; each result the CPU's for its own μ and ε."""
    rng = np.random.default_rng(8)
    x = rng.uniform(0.5, 2.0, (3, 3))
    cases = [(0.5, 0.3), (7.0, 0.45)] + [(mu, rng.uniform(0.2, 0.6, 3)) for mu in (0.8, 11.0)]

    def job(mu, eps):
        return [mrs.velocity(x, x, (k + 1) * x[::-1], epsilon=eps, mu=mu, torques=x, wall=True,
                             angular=True) for k in range(2)]

    router = gpu.hosted.Router()
    outcomes = router.run([lambda c=c: job(*c) for c in cases])
    assert router.launches == [2, 2, 2, 2]
    for (ok, values), case in zip(outcomes, cases, strict=True):
        assert ok
        for got, want in zip(values, job(*case), strict=True):
            _close(got, want)


def test_a_batched_evaluation_uses_each_members_viscosity_and_regularization():
    """gpu.velocity on a batch of three members in free space (the force-only kernel) and above
    the wall (the full one): member b's u is the CPU's with μ_b and ε_b."""
    rng = np.random.default_rng(9)
    x = rng.uniform(0.5, 2.0, (3, 4, 3))
    f = rng.normal(size=(3, 4, 3))
    mu, eps = np.array([0.5, 2.0, 9.0]), np.array([0.25, 0.4, 0.6])
    per_source = rng.uniform(0.2, 0.6, (3, 4))
    for wall in (False, True):
        for epsilon in (eps, per_source):
            u = gpu.velocity(x, x, f, epsilon=epsilon, mu=mu, wall=wall)
            for b in range(3):
                want = mrs.velocity(x[b], x[b], f[b], epsilon=epsilon[b], mu=mu[b], wall=wall)
                _close([u[b]], [want])


def test_hosted_rigid_solves_of_other_viscosities_and_regularizations_are_each_their_own(
        monkeypatch):
    """Three rigid spheres by the wall of different μ and ε solved hosted together (sharing their
    launches; GMRES, whose products are routed, as on surfaces above 200 points): each equals its
    own CPU solve, the first as the others."""
    from parastokes.kinds.rigid.shapes import Sphere
    from parastokes.kinds.rigid.system import RigidBody
    from parastokes.mobility import choice

    monkeypatch.setattr(choice, "DENSE_MAX_POINTS", 0)

    body = RigidBody(shape=Sphere(n_points=12), epsilon=0.5, wall=True, position=(0.0, 0.0, 2.0),
                     force=(0.3, 0.0, -1.0))
    x0 = body.initial_state()
    solves = [integrate.Propagator(body.with_params(viscosity=mu, epsilon=eps), "rk2", 0.05)
              for mu, eps in ((1.0, 0.5), (0.25, 0.4), (3.0, 0.6))]
    launches = []
    outcomes = gpu.batch.run_calls([(fn, (0.0, 0.1, x0), {}) for fn in solves],
                                   launches=launches)
    assert max(launches) == 3
    moved = []
    for (ok, value), fn in zip(outcomes, solves, strict=True):
        cpu = fn(0.0, 0.1, x0)
        moved.append(np.abs(cpu - x0).max())
        assert ok and np.abs(value - cpu).max() <= 1e-11 * moved[-1]
    assert moved[1] > 3 * moved[0] > 9 * moved[2]  # μ matters: the solves differ
