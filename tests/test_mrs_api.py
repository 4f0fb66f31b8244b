"""The public entry :func:`parastokes.mrs.velocity`: shapes, batching, threads, bad input.

- outputs are shaped like the targets, u alone or (u, w) with ``angular=True``;
- B systems batched with their own ε and μ give what B separate calls give;
- ``check=False`` changes nothing for valid input; the caller's thread count is restored;
- every bad input raises ValueError naming the argument, and nothing is silently broadcast.
"""

import warnings

import numba
import numpy as np
import pytest
from kernels_signatures import per_system

from parastokes import mrs


def _cloud(rng, n):
    """n random points above the wall."""
    return np.column_stack([rng.uniform(-1, 1, (n, 2)), rng.uniform(0.1, 2, n)])


def _outputs(result):
    """The outputs of :func:`mrs.velocity` as a tuple: (u,) or (u, w)."""
    return result if isinstance(result, tuple) else (result,)


@pytest.mark.parametrize("angular", [False, True])
def test_output_shapes(angular):
    """M targets, N sources: u (M, 3), and w (M, 3) when angular; batched (B, M, 3)."""
    rng = np.random.default_rng(0)
    x, y, f = _cloud(rng, 5), _cloud(rng, 9), rng.normal(size=(9, 3))
    out = _outputs(mrs.velocity(x, y, f, epsilon=0.1, mu=1.0, angular=angular))
    assert len(out) == (2 if angular else 1)
    assert all(o.shape == (5, 3) for o in out)
    xb, yb, fb = (np.stack([a, a]) for a in (x, y, f))
    out = _outputs(mrs.velocity(xb, yb, fb, epsilon=[0.1, 0.2], mu=[1.0, 2.0], angular=angular))
    assert all(o.shape == (2, 5, 3) for o in out)


@pytest.mark.parametrize(
    "flags",
    [
        dict(),
        dict(angular=True),
        dict(torques=True, angular=True),
        dict(torques=True, wall=True, angular=True),
    ],
    ids=["free_u_f", "free_full", "free_full_n", "wall_full"],
)
def test_batched_equals_one_by_one(flags):
    """B = 3 systems with different ε, μ and clouds equal the three unbatched calls."""
    kw = dict(flags)
    rng = np.random.default_rng(1)
    b, m, n = 3, 70, 50
    x = np.stack([_cloud(rng, m) for _ in range(b)])
    y = np.stack([_cloud(rng, n) for _ in range(b)])
    f = rng.normal(size=(b, n, 3))
    t = rng.normal(size=(b, n, 3)) if kw.pop("torques", False) else None
    eps, mu = np.array([0.05, 0.1, 0.3]), np.array([0.5, 1.0, 4.0])
    batched = _outputs(mrs.velocity(x, y, f, torques=t, epsilon=eps, mu=mu, **kw))
    for k in range(b):
        single = _outputs(
            mrs.velocity(
                x[k],
                y[k],
                f[k],
                torques=None if t is None else t[k],
                epsilon=eps[k],
                mu=mu[k],
                **kw,
            )
        )
        for bo, so in zip(batched, single, strict=True):
            np.testing.assert_allclose(bo[k], so, rtol=0, atol=1e-14 * np.max(np.abs(so)))


def test_scalar_parameters_apply_to_every_system():
    """Batched input with scalar ε and μ: the same as passing them once per system."""
    rng = np.random.default_rng(2)
    x = np.stack([_cloud(rng, 20) for _ in range(2)])
    f = rng.normal(size=(2, 20, 3))
    a = mrs.velocity(x, x, f, epsilon=0.2, mu=3.0)
    b = mrs.velocity(x, x, f, epsilon=[0.2, 0.2], mu=[3.0, 3.0])
    assert np.array_equal(a, b)


@pytest.mark.parametrize("wall", [False, True])
def test_check_false_changes_nothing(wall):
    """Valid float64 input: check=False gives the same bits as check=True."""
    rng = np.random.default_rng(3)
    x, f, t = _cloud(rng, 40), rng.normal(size=(40, 3)), rng.normal(size=(40, 3))
    kw = dict(torques=t, epsilon=0.1, mu=2.0, wall=wall, angular=True)
    for a, b in zip(
        mrs.velocity(x, x, f, **kw), mrs.velocity(x, x, f, check=False, **kw), strict=True
    ):
        assert np.array_equal(a, b)


def test_thread_count_restored():
    """n_threads only applies during the call."""
    before = numba.get_num_threads()
    x = _cloud(np.random.default_rng(4), 10)
    mrs.velocity(x, x, x, epsilon=0.1, mu=1.0, n_threads=2)
    assert numba.get_num_threads() == before


def test_list_input_accepted():
    """Nested lists are converted like arrays."""
    u = mrs.velocity(
        [[0.7, -0.3, 1.1]], [[0.2, 0.4, 0.8]], [[1.0, -2.0, 0.5]], epsilon=0.25, mu=1.0
    )
    np.testing.assert_allclose(u[0], [0.0934357322, -0.1578497598, 0.0515548169], atol=1e-9)


# --- bad input --------------------------------------------------------------------------------

_RNG = np.random.default_rng(5)
X = _cloud(_RNG, 6)
F = _RNG.normal(size=(6, 3))
XB = np.stack([X, X])
FB = np.stack([F, F])


def _nan_at(a, index):
    a = a.copy()
    a[index] = np.nan
    return a


def _below(a):
    a = a.copy()
    a[2, 2] = -1e-3
    return a


BAD = {
    # name: (arguments of mrs.velocity, the argument the message must name)
    "targets (N, 2)": (dict(targets=X[:, :2]), "targets"),
    "targets (3,)": (dict(targets=X[0]), "targets"),
    "targets (1, N, 3, 1)": (dict(targets=X[None, :, :, None]), "targets"),
    "sources (N, 2)": (dict(sources=X[:, :2], forces=F[:, :2]), "sources"),
    "forces (N + 1, 3)": (dict(forces=np.vstack([F, F[:1]])), "forces"),
    "forces (1, 3) not broadcast": (dict(forces=F[:1]), "forces"),
    "forces (N, 2)": (dict(forces=F[:, :2]), "forces"),
    "torques (N - 1, 3)": (dict(torques=F[:-1]), "torques"),
    "torques (3,) not broadcast": (dict(torques=F[0]), "torques"),
    "targets nan": (dict(targets=_nan_at(X, (1, 0))), "targets"),
    "sources inf": (dict(sources=np.where(X == X[0, 0], np.inf, X)), "sources"),
    "forces nan": (dict(forces=_nan_at(F, (4, 2))), "forces"),
    "torques nan": (dict(torques=_nan_at(F, (0, 1))), "torques"),
    "epsilon 0": (dict(epsilon=0.0), "epsilon"),
    "epsilon < 0": (dict(epsilon=-0.1), "epsilon"),
    "epsilon nan": (dict(epsilon=np.nan), "epsilon"),
    "epsilon inf": (dict(epsilon=np.inf), "epsilon"),
    "epsilon (1,) unbatched": (dict(epsilon=[0.1]), "epsilon"),
    "epsilon below 1e-18": (dict(epsilon=1e-19), "epsilon"),
    "epsilon above 1e18": (dict(epsilon=1e19), "epsilon"),
    "targets beyond 1e18": (dict(targets=X * 1e19), "targets"),
    "sources beyond 1e18": (dict(sources=X * 1e19), "sources"),
    "mu 0": (dict(mu=0.0), "mu"),
    "mu < 0": (dict(mu=-1.0), "mu"),
    "mu nan": (dict(mu=np.nan), "mu"),
    "n_threads 0": (dict(n_threads=0), "n_threads"),
    "n_threads -1": (dict(n_threads=-1), "n_threads"),
    "n_threads 1.5": (dict(n_threads=1.5), "n_threads"),
    "wall, target below": (dict(targets=_below(X), wall=True), "targets"),
    "wall, source below": (dict(sources=_below(X), wall=True), "sources"),
    "batched epsilon too short": (
        dict(targets=XB, sources=XB, forces=FB, epsilon=[0.1]),
        "epsilon",
    ),
    "batched epsilon too long": (
        dict(targets=XB, sources=XB, forces=FB, epsilon=[0.1, 0.1, 0.1]),
        "epsilon",
    ),
    "batched mu wrong length": (dict(targets=XB, sources=XB, forces=FB, mu=[1.0, 1.0, 1.0]), "mu"),
    "batched epsilon (B, 1)": (
        dict(targets=XB, sources=XB, forces=FB, epsilon=[[0.1], [0.1]]),
        "epsilon",
    ),
    "batched mu <= 0": (dict(targets=XB, sources=XB, forces=FB, mu=[1.0, 0.0]), "mu"),
    "batched sources unbatched": (dict(targets=XB), "sources"),
    "batched forces unbatched": (dict(targets=XB, sources=XB), "forces"),
    "batched torques unbatched": (dict(targets=XB, sources=XB, forces=FB, torques=F), "torques"),
    "batch sizes differ": (
        dict(targets=XB, sources=np.stack([X, X, X]), forces=np.stack([F, F, F])),
        "sources",
    ),
    # regressions: a complex array lost its imaginary part with only a warning, text was
    # parsed, a complex ε raised a TypeError, no targets an IndexError
    "targets complex": (dict(targets=X + 1j), "targets"),
    "forces text": (dict(forces=F.astype(str)), "forces"),
    "epsilon complex": (dict(epsilon=0.1 + 0.1j), "epsilon"),
    "mu text": (dict(mu="1.0"), "mu"),
    "no targets": (dict(targets=np.zeros((0, 3))), "targets"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_input_raises(case):
    """Each bad argument raises ValueError and the message starts with the argument's name."""
    changes, name = BAD[case]
    kw = dict(targets=X, sources=X, forces=F, epsilon=0.1, mu=1.0) | changes
    with pytest.raises(ValueError, match=rf"^{name}\b"):
        mrs.velocity(kw.pop("targets"), kw.pop("sources"), kw.pop("forces"), **kw)


def test_checked_and_unchecked_calls_share_one_compiled_signature():
    """check=False must not hand numba a read-only ε array (a second compilation per kernel)."""
    from parastokes.mrs import compiled

    rng = np.random.default_rng(5)
    x = rng.random((10, 3)) + [0.0, 0.0, 1.0]
    f = rng.normal(size=(10, 3))
    for check in (True, False):
        mrs.velocity(x, x, f, epsilon=0.2, mu=1.0, check=check)
        mrs.velocity(x, x, f, epsilon=0.2, mu=1.0, torques=f, wall=True, angular=True, check=check)
    assert len(per_system(compiled.free_u_f, 3)) == 1
    assert len(per_system(compiled.full, 4)) == 1


def test_fast_path_reads_no_uninitialized_memory():
    """The u-only path must not touch (and divide) rows the kernel never wrote: no warnings."""
    rng = np.random.default_rng(9)
    x = rng.random((70, 3))
    f = rng.normal(size=(70, 3))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for _ in range(50):
            u = mrs.velocity(x, x, f, epsilon=0.1, mu=1e-3)
    assert u.shape == (70, 3) and np.isfinite(u).all()
