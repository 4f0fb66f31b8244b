"""Properties of the regularized-Stokeslet kernels (``shared/physics.md`` sections 1, 2 and 5).

- the compiled kernels agree with the numpy oracle on random clouds (1e-12 relative) and give
  bit-identical results on 1 and 2 threads;
- no-slip: above the wall, the velocity on z = 0 vanishes, from forces and from torques;
- w = ½ curl u (central finite differences) for each free part, each image part, and the sums;
- the force -> velocity kernel is symmetric, M(x, y) = M(y, x)ᵀ, free and wall;
- far field: the regularized Stokeslet tends to the singular one like (ε/r)², and the wall kernel
  tends to the free one as the height grows.
"""

import numba
import numpy as np
import pytest
from documented import check

from parastokes import mrs
from parastokes.mrs import reference as ref


def _cloud(rng, n, *, zmin=0.05):
    """n random points in [-1, 1]² × [zmin, 2] (above the wall)."""
    return np.column_stack([rng.uniform(-1, 1, (n, 2)), rng.uniform(zmin, 2, n)])


def _outputs(result):
    """The outputs of :func:`mrs.velocity` as a tuple: (u,) or (u, w)."""
    return result if isinstance(result, tuple) else (result,)


def _relerr(a, b):
    """max |a - b| / max |b| (absolute when b is all zero, e.g. a self-term w)."""
    return np.max(np.abs(a - b)) / (np.max(np.abs(b)) or 1.0)


# --- compiled == oracle ---------------------------------------------------------------------------


@pytest.mark.parametrize("n", [1, 7, 64, 65, 150])
@pytest.mark.parametrize("wall", [False, True], ids=["free", "wall"])
@pytest.mark.parametrize("loads", ["f", "f+n", "n"])
@pytest.mark.parametrize("angular", [False, True], ids=["u", "uw"])
def test_compiled_matches_oracle(n, wall, loads, angular):
    """Random clouds, targets = sources (self terms included) and a separate target set; forces
    only, forces and torques, torques only (the compiled wall kernel regroups all the terms, so
    each kind of load is checked on its own too)."""
    rng = np.random.default_rng(1000 * n + 100 * wall + 10 * len(loads) + angular)
    x = _cloud(rng, n)
    f = rng.normal(size=(n, 3)) if "f" in loads else np.zeros((n, 3))
    t = rng.normal(size=(n, 3)) if "n" in loads else None
    kw = dict(epsilon=0.1, mu=0.7, torques=t, wall=wall, angular=angular)
    for targets in (x, _cloud(rng, n + 37)):
        got = mrs.velocity(targets, x, f, **kw)
        want = ref.velocity(targets, x, f, **kw)
        for g, w in zip(_outputs(got), _outputs(want), strict=True):
            assert g.shape == w.shape == targets.shape
            assert _relerr(g, w) < 1e-12


# --- threads ----------------------------------------------------------------------------------


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="numba has a single thread")
@pytest.mark.parametrize(
    "flags",
    [dict(), dict(angular=True), dict(torques=True, angular=True), dict(torques=True, wall=True)],
    ids=["free_u_f", "free_full", "free_full_n", "wall_full"],
)
def test_bit_identical_for_any_thread_count(flags):
    """Every kernel gives exactly the same bits on 1 and 2 threads (several tiles, batched)."""
    kw = dict(flags)
    rng = np.random.default_rng(7)
    b, n = 2, 333
    x = np.stack([_cloud(rng, n) for _ in range(b)])
    f = rng.normal(size=(b, n, 3))
    if kw.pop("torques", False):
        kw["torques"] = rng.normal(size=(b, n, 3))
    kw.update(epsilon=np.array([0.05, 0.2]), mu=np.array([1.0, 2.0]))
    one = mrs.velocity(x, x, f, n_threads=1, **kw)
    two = mrs.velocity(x, x, f, n_threads=2, **kw)
    for a, c in zip(_outputs(one), _outputs(two), strict=True):
        assert np.array_equal(a, c)


# --- no-slip ----------------------------------------------------------------------------------


@pytest.mark.parametrize("source", ["f", "n"])
def test_no_slip_on_the_wall(source):
    """With the wall, u on z = 0 from forces and from torques vanishes to round-off."""
    rng = np.random.default_rng(3)
    y = _cloud(rng, 40, zmin=0.01)
    targets = np.column_stack([rng.uniform(-2, 2, (60, 2)), np.zeros(60)])
    vec = rng.normal(size=(40, 3))
    zero = np.zeros_like(vec)
    forces, torques = (vec, None) if source == "f" else (zero, vec)
    for eps in (0.02, 0.3):
        kw = dict(epsilon=eps, mu=1.0, torques=torques)
        free = mrs.velocity(targets, y, forces, **kw)
        assert np.max(np.abs(mrs.velocity(targets, y, forces, wall=True, **kw))) < (
            1e-14 * np.max(np.abs(free))
        )
        assert np.max(np.abs(ref.velocity(targets, y, forces, wall=True, **kw))) < (
            1e-14 * np.max(np.abs(free))
        )


# --- w = ½ curl u ---------------------------------------------------------------------------------


def _half_curl(u_of, x, step=1e-5):
    """½ curl of the field u_of((M, 3)) -> (M, 3) at x, by central differences."""
    jac = np.empty((x.shape[0], 3, 3))  # jac[m, i, k] = ∂u_i/∂x_k
    for k in range(3):
        dx = np.zeros(3)
        dx[k] = step
        jac[:, :, k] = (u_of(x + dx) - u_of(x - dx)) / (2 * step)
    curl = np.stack(
        [jac[:, 2, 1] - jac[:, 1, 2], jac[:, 0, 2] - jac[:, 2, 0], jac[:, 1, 0] - jac[:, 0, 1]],
        axis=1,
    )
    return 0.5 * curl


def _free(kernel, y, v, eps):
    """Adapt a free-space oracle kernel (pair differences) to a function of the targets."""
    return lambda x: kernel(
        x[:, None, :] - y[None, :, :], np.broadcast_to(v, (len(x), *v.shape)), eps
    )


def _image(kernel, y, v, eps):
    """Adapt an image oracle kernel to a function of the targets."""
    return lambda x: kernel(x, y, v, eps)


CURL_PAIRS = {
    "stokeslet": (_free, ref.stokeslet, ref.stokeslet_curl),
    "rotlet": (_free, ref.rotlet, ref.rotlet_curl),
    "rotlet_phi": (_free, ref.rotlet_phi, ref.rotlet_phi_curl),
    "blakelet_image": (_image, ref.blakelet_image, ref.blakelet_image_curl),
    "rotlet_image": (_image, ref.rotlet_image, ref.rotlet_image_curl),
}


@pytest.mark.parametrize("eps", [0.1, 0.5])
@pytest.mark.parametrize("part", list(CURL_PAIRS))
def test_angular_velocity_is_half_curl_per_part(part, eps):
    """Each oracle part's w equals ½ curl of its u: the two free parts and the four wall parts.

    The four wall parts are the free Stokeslet and rotlet (evaluated at r) plus the two image parts
    (evaluated at R, the Blakelet's and the rotlet's), checked separately.
    """
    adapt, u_kernel, w_kernel = CURL_PAIRS[part]
    rng = np.random.default_rng(11)
    y = _cloud(rng, 5, zmin=0.2)
    v = rng.normal(size=(5, 3))
    x = _cloud(rng, 8, zmin=0.2)
    w = adapt(w_kernel, y, v, eps)(x)
    fd = _half_curl(adapt(u_kernel, y, v, eps), x)
    assert _relerr(fd, w) < 1e-7


@pytest.mark.parametrize(
    "wall, source",
    [(False, "f"), (False, "n"), (False, "n, variant phi"), (True, "f"), (True, "n")],
)
def test_angular_velocity_is_half_curl_compiled(wall, source):
    """The public kernels' w equals ½ curl of their u (free, and free + image), f and n apart,
    and for the torques of variant Φ (free space)."""
    rng = np.random.default_rng(12)
    y = _cloud(rng, 6, zmin=0.2)
    vec = rng.normal(size=(6, 3))
    forces, torques = (vec, None) if source == "f" else (np.zeros_like(vec), vec)
    kw = dict(epsilon=0.2, mu=1.3, torques=torques, wall=wall)
    if "phi" in source:
        kw["torque_blob"] = "phi"
    x = _cloud(rng, 10, zmin=0.2)
    _, w = mrs.velocity(x, y, forces, angular=True, **kw)
    fd = _half_curl(lambda p: mrs.velocity(p, y, forces, **kw), x)
    assert _relerr(fd, w) < 1e-7


# --- symmetry ---------------------------------------------------------------------------------


def _matrix(x, y, wall, eps=0.15):
    """The 3x3 force -> velocity kernel M(x, y), column j = u(x) from a unit force e_j at y."""
    cols = [
        mrs.velocity(x[None], y[None], e[None], epsilon=eps, mu=1.0, wall=wall)[0]
        for e in np.eye(3)
    ]
    return np.column_stack(cols)


@pytest.mark.parametrize("wall", [False, True], ids=["free", "wall"])
def test_force_kernel_symmetric(wall):
    """M(x, y) = M(y, x)ᵀ for random pairs, including pairs close to the wall."""
    rng = np.random.default_rng(5)
    for _ in range(10):
        x, y = _cloud(rng, 2, zmin=0.01)
        mxy, myx = _matrix(x, y, wall), _matrix(y, x, wall)
        assert _relerr(myx.T, mxy) < 1e-13
        # not trivially symmetric: the wall kernel is not symmetric in its own indices
        if wall:
            assert _relerr(mxy.T, mxy) > 1e-6


# --- far field --------------------------------------------------------------------------------


def _singular_stokeslet(r, f):
    """(f/r + (f·r) r/r³) / 8π for μ = 1 (one source)."""
    d = np.linalg.norm(r, axis=-1, keepdims=True)
    return (f / d + (r @ f)[:, None] * r / d**3) / (8 * np.pi)


def test_regularized_stokeslet_tends_to_singular():
    """Relative error against the singular Stokeslet decays like (ε/r)² (fitted slope -2)."""
    rng = np.random.default_rng(9)
    eps = 0.01
    f = rng.normal(size=3)
    direction = rng.normal(size=(20, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    ratios = np.array([5.0, 10.0, 20.0, 40.0, 80.0, 160.0])
    errs = []
    for q in ratios:
        x = q * eps * direction
        u = mrs.velocity(x, np.zeros((1, 3)), f[None], epsilon=eps, mu=1.0)
        errs.append(_relerr(u, _singular_stokeslet(x, f)))
    errs = np.array(errs)
    assert np.all(np.diff(errs) < 0)
    slope = np.polyfit(np.log(ratios), np.log(errs), 1)[0]
    assert abs(slope + 2.0) < 0.05
    check("kernel_slopes", "far_field", slope)
    assert errs[-1] < 1e-4


def test_wall_kernel_tends_to_free_with_height():
    """Source and targets at height H, a few units apart: |u_wall - u_free| / |u_free| ~ 1/H."""
    rng = np.random.default_rng(10)
    f = rng.normal(size=(3, 3))
    t = rng.normal(size=(3, 3))
    offsets_y = rng.uniform(-1, 1, (3, 3))
    offsets_x = rng.uniform(-1, 1, (7, 3))
    heights = np.array([10.0, 20.0, 40.0, 80.0, 160.0, 320.0])
    errs = []
    for height in heights:
        y = offsets_y + np.array([0.0, 0.0, height])
        x = offsets_x + np.array([0.0, 0.0, height])
        kw = dict(torques=t, epsilon=0.1, mu=1.0, angular=True)
        free = np.concatenate(mrs.velocity(x, y, f, **kw))
        wall = np.concatenate(mrs.velocity(x, y, f, wall=True, **kw))
        errs.append(_relerr(wall, free))
    errs = np.array(errs)
    assert np.all(np.diff(errs) < 0)
    slope = np.polyfit(np.log(heights), np.log(errs), 1)[0]
    assert abs(slope + 1.0) < 0.1
    check("kernel_slopes", "wall_to_free", slope)
    assert errs[-1] < 1e-2


# --- ε per source -------------------------------------------------------------------------------


@pytest.mark.parametrize("wall", [False, True], ids=["free", "wall"])
@pytest.mark.parametrize("loads", ["f", "f+n"])
@pytest.mark.parametrize("angular", [False, True], ids=["u", "uw"])
def test_epsilon_per_source_matches_the_oracle_body_by_body(wall, loads, angular):
    """ε given per source (two bodies of ε 0.1 and 0.3 in one call) is the sum of the oracle over
    each body's sources with its own ε; equal per-source ε give the bits of a scalar ε."""
    rng = np.random.default_rng(11 + 2 * wall + 4 * angular + len(loads))
    n, k = 70, 30
    x = _cloud(rng, n)
    f = rng.normal(size=(n, 3))
    t = rng.normal(size=(n, 3)) if "n" in loads else None
    eps = np.where(np.arange(n) < k, 0.1, 0.3)
    kw = dict(mu=0.7, wall=wall, angular=angular)
    got = _outputs(mrs.velocity(x, x, f, epsilon=eps, torques=t, **kw))
    bodies = [(slice(0, k), 0.1), (slice(k, n), 0.3)]
    parts = [_outputs(ref.velocity(x, x[s], f[s], epsilon=e, **kw,
                                   torques=None if t is None else t[s])) for s, e in bodies]
    for g, a, b in zip(got, *parts, strict=True):
        assert _relerr(g, a + b) < 1e-12
    same = _outputs(mrs.velocity(x, x, f, epsilon=np.full(n, 0.2), torques=t, **kw))
    scalar = _outputs(mrs.velocity(x, x, f, epsilon=0.2, torques=t, **kw))
    for a, b in zip(same, scalar, strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("wall", [False, True], ids=["free", "wall"])
def test_batched_epsilon_per_source_is_each_systems_own(wall):
    """(B, N) ε with a μ per system: system b is the oracle with ε[b] and μ[b] (an index of the
    first system's ε instead of each system's would pass the unbatched test, not this one)."""
    rng = np.random.default_rng(5 + wall)
    n, batch = 40, 3
    x = np.stack([_cloud(rng, n) for _ in range(batch)])
    f = rng.normal(size=(batch, n, 3))
    t = rng.normal(size=(batch, n, 3))
    eps = rng.uniform(0.1, 0.4, size=(batch, n))
    mu = np.array([0.5, 1.0, 2.0])
    got = mrs.velocity(x, x, f, epsilon=eps, mu=mu, torques=t, wall=wall, angular=True)
    for b in range(batch):
        want = [np.zeros((n, 3)), np.zeros((n, 3))]
        for j in range(n):  # one source at a time, each with its own ε
            u, w = ref.velocity(x[b], x[b, j:j + 1], f[b, j:j + 1], epsilon=eps[b, j], mu=mu[b],
                                torques=t[b, j:j + 1], wall=wall, angular=True)
            want[0] += u
            want[1] += w
        assert _relerr(got[0][b], want[0]) < 1e-12 and _relerr(got[1][b], want[1]) < 1e-12


def test_epsilon_per_source_of_the_wrong_length_is_an_error():
    x = np.ones((5, 3))
    with pytest.raises(ValueError, match=r"^epsilon: one per source needs shape \(5,\)"):
        mrs.velocity(x, x, x, epsilon=np.full(4, 0.1), mu=1.0)
    with pytest.raises(ValueError, match=r"^epsilon: must be finite and > 0"):
        mrs.velocity(x, x, x, epsilon=np.array([0.1, 0.1, -1.0, 0.1, 0.1]), mu=1.0)
