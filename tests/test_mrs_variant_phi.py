"""Variant Φ of the torque parts (``torque_blob="phi"``, physics.md section 1): the force blob φ_ε
regularizes the torques too. Free space only.

- compiled == oracle; batched == one by one; bit-identical for any thread count;
- w = ½ curl u by finite differences: in test_mrs_properties (oracle pair and compiled kernel);
- self terms: u = 0 and w = 5 n / (16π μ ε³) at r = 0 (D1(0) = 10/(8π ε³));
- far field: variant Φ and variant L both tend to the singular rotlet, their difference decaying
  like (ε/r)² (fitted slope);
- refused with the wall, and an unknown blob name raises.
"""

import numba
import numpy as np
import pytest

from parastokes import mrs
from parastokes.mrs import reference as ref

PHI = dict(torque_blob="phi")


def _cloud(rng, n):
    return rng.uniform(-1.0, 1.0, (n, 3))


@pytest.mark.parametrize("n", [1, 9, 70])
@pytest.mark.parametrize("with_forces", [False, True], ids=["n", "f+n"])
def test_compiled_matches_oracle(n, with_forces):
    rng = np.random.default_rng(40 + n + with_forces)
    y = _cloud(rng, n)
    f = rng.normal(size=(n, 3)) if with_forces else np.zeros((n, 3))
    t = rng.normal(size=(n, 3))
    kw = dict(epsilon=0.15, mu=0.8, torques=t, angular=True, **PHI)
    for x in (y, _cloud(rng, n + 11)):
        for got, want in zip(mrs.velocity(x, y, f, **kw), ref.velocity(x, y, f, **kw), strict=True):
            assert np.max(np.abs(got - want)) <= 1e-12 * np.max(np.abs(want))


def test_self_terms():
    eps, mu = 0.2, 1.7
    n = np.array([[0.3, -1.1, 0.7]])
    u, w = mrs.velocity(np.zeros((1, 3)), np.zeros((1, 3)), np.zeros((1, 3)), torques=n,
                        epsilon=eps, mu=mu, angular=True, **PHI)
    assert np.all(u == 0.0)
    np.testing.assert_allclose(w, 5.0 * n / (16.0 * np.pi * mu * eps**3), rtol=1e-14)


def test_variants_agree_far_away_like_eps_over_r_squared():
    rng = np.random.default_rng(42)
    eps = 0.01
    t = rng.normal(size=(1, 3))
    direction = rng.normal(size=(20, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    ratios = np.array([10.0, 20.0, 40.0, 80.0, 160.0])
    diffs = []
    for q in ratios:
        x = q * eps * direction
        kw = dict(torques=t, epsilon=eps, mu=1.0)
        u_l = mrs.velocity(x, np.zeros((1, 3)), np.zeros((1, 3)), **kw)
        u_p = mrs.velocity(x, np.zeros((1, 3)), np.zeros((1, 3)), **kw, **PHI)
        diffs.append(np.max(np.abs(u_p - u_l)) / np.max(np.abs(u_l)))
    slope = np.polyfit(np.log(ratios), np.log(diffs), 1)[0]
    assert -2.2 < slope < -1.8


def test_batched_equals_one_by_one():
    rng = np.random.default_rng(43)
    y = np.stack([_cloud(rng, 12) for _ in range(3)])
    f, t = rng.normal(size=y.shape), rng.normal(size=y.shape)
    eps, mu = np.array([0.1, 0.2, 0.3]), np.array([1.0, 2.0, 0.5])
    u, w = mrs.velocity(y, y, f, torques=t, epsilon=eps, mu=mu, angular=True, **PHI)
    for b in range(3):
        ub, wb = mrs.velocity(y[b], y[b], f[b], torques=t[b], epsilon=eps[b], mu=mu[b],
                              angular=True, **PHI)
        assert np.array_equal(u[b], ub) and np.array_equal(w[b], wb)


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="numba has a single thread")
def test_bit_identical_for_any_thread_count():
    rng = np.random.default_rng(44)
    y = _cloud(rng, 150)
    f, t = rng.normal(size=y.shape), rng.normal(size=y.shape)
    kw = dict(torques=t, epsilon=0.1, mu=1.0, angular=True, **PHI)
    one = mrs.velocity(y, y, f, n_threads=1, **kw)
    two = mrs.velocity(y, y, f, n_threads=2, **kw)
    assert all(np.array_equal(a, b) for a, b in zip(one, two, strict=True))


def test_phi_is_refused_with_the_wall_and_unknown_blobs_raise():
    x = np.array([[0.0, 0.0, 1.0]])
    with pytest.raises(ValueError, match=r"^torque_blob\b.*free space"):
        mrs.velocity(x, x, x, torques=x, epsilon=0.1, mu=1.0, wall=True, **PHI)
    with pytest.raises(ValueError, match=r"^torque_blob\b"):
        mrs.velocity(x, x, x, torques=x, epsilon=0.1, mu=1.0, torque_blob="Phi")
