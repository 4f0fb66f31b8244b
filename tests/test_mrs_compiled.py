"""The building blocks of the compiled kernels: the inverse square root and the vector width."""

import numba
import numpy as np
import pytest
from numba import njit

from parastokes import mrs
from parastokes.mrs import compiled
from parastokes.mrs.velocity import SCALE_LIMIT


@njit(cache=False)
def _rsqrt_all(d):
    compiled._kernel_attributes()  # the kernels' settings for the single-precision seed
    out = np.empty_like(d)
    out3 = np.empty_like(d)
    for i in range(d.size):
        out[i] = compiled._rsqrt(d[i])
        out3[i] = compiled._rsqrt3(d[i])
    return out, out3


def test_inverse_square_roots_agree_with_numpy_to_round_off_over_the_supported_range():
    """The single-precision seed plus the Halley step gives 1/sqrt(d) to double round-off for
    every d = r² + ε² the kernels can see (ε and coordinates within SCALE_LIMIT): within 2 ulp of
    numpy's 1.0 / np.sqrt(d), which is itself up to 1 ulp from the true value."""
    rng = np.random.default_rng(7)
    lo, hi = 2 * np.log10(1 / SCALE_LIMIT), 2 * np.log10(SCALE_LIMIT) + 1
    d = 10.0 ** rng.uniform(lo, hi, 200_000)
    d = np.concatenate([d, [10.0**lo, 10.0**hi, 1.0, 2.0, 0.25, np.nextafter(1.0, 2.0)]])
    exact = 1.0 / np.sqrt(d)
    inv, inv3 = _rsqrt_all(d)
    err = np.abs(inv - exact) / np.spacing(exact)
    assert err.max() <= 2.0
    assert np.median(err) == 0.0
    # d^(-3/2) directly, against numpy's (1/sqrt(d))³ computed in extended precision.
    exact3 = (1.0 / np.sqrt(d.astype(np.longdouble))) ** 3
    err3 = np.abs(inv3 - exact3) / np.spacing(exact3.astype(np.float64))
    assert err3.max() <= 3.0


def test_kernels_at_extreme_but_allowed_scales_match_the_oracle():
    """Unit-system independence: the same geometry scaled by 1e-15 and 1e15 gives the same
    dimensionless velocities (u ~ f / (μ length), w ~ f / (μ length²), torques ~ f length)."""
    rng = np.random.default_rng(3)
    x = rng.random((40, 3)) + [0, 0, 0.5]
    f = rng.standard_normal((40, 3))
    base = mrs.velocity(x, x, f, torques=f, epsilon=0.1, mu=1.0, wall=True, angular=True)
    for s in (1e-15, 1e15):
        u, w = mrs.velocity(s * x, s * x, f, torques=f * s, epsilon=0.1 * s, mu=1.0, wall=True,
                            angular=True)
        np.testing.assert_allclose(u * s, base[0], rtol=1e-12, atol=1e-14 * np.abs(base[0]).max())
        np.testing.assert_allclose(w * s**2, base[1], rtol=1e-12,
                                   atol=1e-14 * np.abs(base[1]).max())


def test_kernels_ask_llvm_for_wide_vectors():
    """The kernels' loop bodies carry the per-function attributes, and on a CPU with AVX-512 LLVM
    then uses 512-bit (zmm) registers in a vectorized loop."""

    @njit(cache=False, error_model="numpy", fastmath={"contract"})
    def scale(a, c):
        compiled._kernel_attributes()
        for i in range(a.size):
            a[i] = a[i] * c + 1.0

    scale(np.ones(64), 2.0)
    sig = scale.signatures[0]
    ir = scale.inspect_llvm(sig)
    assert all(attribute in ir for attribute in compiled.KERNEL_ATTRIBUTES)
    features = numba.core.codegen.CPUCodegen._get_host_cpu_features(None)
    if "+avx512f" not in features.split(","):
        pytest.skip("no AVX-512 on this CPU: the attribute has nothing to widen")
    assert "zmm" in scale.inspect_asm(sig)


@pytest.mark.parametrize("padded", [8, 16, 64, 72, 304, 648, 1512, 5000])
@pytest.mark.parametrize("parts", [1, 2, 3, 4])
def test_tile_starts_cover_the_targets_in_vectors_and_balance_the_threads(padded, parts):
    starts = compiled.tile_starts(padded, parts)
    sizes = np.diff(starts)
    assert starts[0] == 0 and starts[-1] == padded
    assert np.all(sizes > 0) and np.all(sizes <= compiled.TILE)
    assert np.all(starts % compiled.LANES == 0)
    assert not starts.flags.writeable  # cached: one shared array
    if padded // compiled.LANES >= parts:
        # numba gives each thread an equal contiguous share of the jobs: equal target counts ±8.
        assert sizes.size % parts == 0
        shares = sizes.reshape(parts, -1).sum(axis=1)
        assert shares.max() - shares.min() <= compiled.LANES


def test_results_do_not_depend_on_the_tiling():
    """Each target sums its sources in the same order in any tile: the same bits for any tiles."""
    rng = np.random.default_rng(5)
    nb, m, mp, ns = 2, 197, 200, 150
    t = np.ascontiguousarray(rng.random((3, nb, mp)) + [[[0]], [[0]], [[0.5]]])
    s = rng.random((nb, ns, 3)) + [0, 0, 0.5]
    f = rng.standard_normal((nb, ns, 3))
    n = rng.standard_normal((nb, ns, 3))
    eps, denom = np.array([0.1, 0.3]), np.array([1.0, 2.0])
    tilings = [
        compiled.tile_starts(mp, 1),
        compiled.tile_starts(mp, 3),
        np.array([0, 8, 72, 80, 136, 200]),
        np.arange(0, mp + 1, 8),
    ]
    results = []
    for starts in tilings:
        starts.flags.writeable = False  # as tile_starts gives them: no second compiled signature
        u = np.empty((nb, m, 3))
        uw = np.empty((2, nb, m, 3))
        compiled.free_u_f(t, s, f, eps, denom, starts, u)
        compiled.full(t, s, f, n, eps, True, False, denom, starts, *uw)
        results.append((u, uw))
    for u, uw in results[1:]:
        assert np.array_equal(u, results[0][0])
        assert np.array_equal(uw, results[0][1])
