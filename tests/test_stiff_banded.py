"""The linear algebra of the linearly implicit steps (parastokes.stiff.banded, .solve, .stepper):
the compiled block product against scipy's, the band and LAPACK's banded layout, factorizations
against dense solves, and when the stepper rebuilds ``A`` and refactorizes (exact counts), its
reuse of a factorization across a change of step (the W-method's view), determinism."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.sparse as sp
from test_stiff import Forced

from parastokes import integrate, models
from parastokes.kinds.chain import ChainSystem
from parastokes.scene import Scene
from parastokes.stiff import ROSENBROCK, StiffSolveError, banded, jacobian, local, solve, stepper
from parastokes.stiff.solve import Factorization


def _random_bsr(rng, n_rows, n_cols, block, density):
    pattern = sp.random_array((n_rows, n_cols), density=density, rng=rng, format="csr")
    pattern.data[:] = 1.0
    coo = sp.coo_array(pattern)
    blocks = rng.standard_normal((coo.nnz, *block))
    dense = np.zeros((n_rows * block[0], n_cols * block[1]))
    for (i, j), b in zip(zip(coo.row, coo.col, strict=True), blocks, strict=True):
        dense[i * block[0]:(i + 1) * block[0], j * block[1]:(j + 1) * block[1]] = b
    return sp.bsr_array(dense, blocksize=block), dense


@pytest.mark.parametrize(("left", "right"), [((6, 6), (6, 6)), ((3, 3), (3, 3)), ((2, 3), (3, 4))])
def test_block_product_is_the_matrix_product(left, right):
    rng = np.random.default_rng(1)
    m, dm = _random_bsr(rng, 30, 25, left, 0.2)
    k, dk = _random_bsr(rng, 25, 20, right, 0.15)
    product = banded.block_product(m, k)
    assert product.blocksize == (left[0], right[1])
    assert np.allclose(product.toarray(), dm @ dk, rtol=1e-13, atol=1e-13)


def test_block_product_refuses_blocks_that_do_not_chain():
    rng = np.random.default_rng(2)
    m, _ = _random_bsr(rng, 4, 4, (3, 3), 0.5)
    k, _ = _random_bsr(rng, 4, 4, (2, 2), 0.5)
    with pytest.raises(ValueError, match="do not chain"):
        banded.block_product(m, k)


def test_the_rods_a_is_the_near_mobility_times_the_load_jacobian():
    """local_jacobian's compiled product equals scipy's M @ K on a rod above the wall."""
    rod = models.rod_swimmer(n_points=31, length=6.0, n_threads=1)
    x = rod.initial_state()
    k = jacobian.load_jacobian(rod, 0.0, x)
    m = local.near_mobility(rod.positions(x), rod.epsilon, rod.viscosity, True,
                            jacobian.CUTOFF * rod.epsilon)
    a = jacobian.local_jacobian(rod, 0.0, x, 6 * len(x)).toarray()
    expected = (m @ sp.csr_array(k)).toarray()
    assert np.allclose(a, expected, rtol=0, atol=1e-13 * np.abs(expected).max())


def _reference_product(body, x):
    """M_near @ K of ``body`` at ``x`` through the stored near mobility and scipy's product."""
    size = 6 if getattr(body, "angular", False) else 3
    k = sp.bsr_array(jacobian.load_jacobian(body, 0.0, x), blocksize=(size, size))
    m = local.near_mobility(body.positions(x), body.epsilon, body.viscosity, size == 6,
                            jacobian.CUTOFF * body.epsilon)
    return (m @ sp.csr_array(k)).toarray(), k


def _bent_rod():
    rod = models.rod_swimmer(n_points=101, length=20.0, epsilon=0.4, n_threads=1)
    x = rod.initial_state()
    s = np.linspace(0.0, 1.0, len(x))
    x[:, 1] += 0.5 * np.sin(3.0 * s)  # bent out of line: every pair's separation has y
    x[:, 2] += 0.3 * s ** 2           # and z, so no block entry is zero by symmetry
    return rod, rod.project(x)


@pytest.mark.parametrize("kind", ["rod", "chain"])
def test_fused_near_product_is_the_reference_product_in_lapacks_layout(kind):
    """The one-pass product (M's blocks never stored) on a bent rod (6 x 6 blocks, loads on
    the two neighbours) and a chain (3 x 3, two neighbours each side): the matrix M @ K to
    round-off, a dia_array whose row ku + i - j of column j is entry (i, j), Fortran order,
    with the reference's band."""
    if kind == "rod":
        body, x = _bent_rod()
    else:
        body = ChainSystem(n_beads=40, tilt=0.3, stretch=1.1, epsilon=0.8)  # pairs: 2 beads
        x = body.initial_state()
        x[:, 1] += 0.3 * np.cos(np.linspace(0.0, 2.0, len(x)))
        x[:, 2] += 0.2 * np.sin(np.linspace(0.0, 3.0, len(x)))
    expected, k = _reference_product(body, x)
    a = jacobian.local_jacobian(body, 0.0, x, expected.shape[0])
    assert isinstance(a, sp.dia_array) and a.data.flags.f_contiguous
    kl, ku = banded.bandwidth(sp.bsr_array(expected, blocksize=k.blocksize))
    assert banded.bandwidth(a) == (kl, ku) and a.data.shape == (kl + ku + 1, len(expected))
    assert list(a.offsets) == list(range(ku, -kl - 1, -1))
    scale = np.abs(expected).max()
    assert np.abs(a.toarray() - expected).max() < 1e-13 * scale
    rows, cols = np.nonzero(np.abs(expected) > 1e-6 * scale)
    np.testing.assert_allclose(a.data[ku + rows - cols, cols], expected[rows, cols], rtol=0,
                               atol=1e-13 * scale)


def test_near_product_beyond_an_eighth_of_its_size_is_the_general_product():
    """Points in no order along a line (a vesicle's, a curled rod's): the band is wide, and
    near_product gives the block product of the stored mobility, the same matrix."""
    rng = np.random.default_rng(6)
    points = rng.uniform(0.0, 3.0, size=(40, 3))
    k, dk = _random_bsr(rng, 40, 40, (6, 6), 0.1)
    a = banded.near_product(points, 0.5, 2.0, True, 1.5, k)
    assert isinstance(a, sp.bsr_array)
    m = local.near_mobility(points, 0.5, 2.0, True, 1.5).toarray()
    assert np.allclose(a.toarray(), m @ dk, rtol=0, atol=1e-13 * np.abs(m @ dk).max())


def test_near_product_refuses_a_load_jacobian_of_other_blocks():
    rng = np.random.default_rng(7)
    k, _ = _random_bsr(rng, 10, 10, (3, 3), 0.3)
    with pytest.raises(ValueError, match="expected"):
        banded.near_product(rng.uniform(size=(10, 3)), 0.5, 1.0, True, 1.5, k)


def test_a_scene_of_a_rod_and_a_chain_composes_their_fused_products():
    """A scene's A (its stiff_jacobian) holds each body's fused band product on its diagonal
    blocks, padded to the widest rates: the reference products there, zero elsewhere."""
    rod, x_rod = _bent_rod()
    chain = ChainSystem(n_beads=12, tilt=0.3, stretch=1.1, viscosity=rod.viscosity,
                        epsilon=0.3, height=30.0, wall=True)
    scene = Scene((rod, chain), viscosity=rod.viscosity, wall=True)
    x = scene.stack([x_rod, chain.initial_state()])
    a = sp.csr_array(scene.stiff_jacobian(0.0, x)).toarray()
    expected = np.zeros_like(a)
    n_rod = 6 * len(x_rod)
    expected[:n_rod, :n_rod] = _reference_product(rod, x_rod)[0]
    chain_a = _reference_product(chain, chain.initial_state())[0]
    for i in range(3):  # the chain's 3 rates per bead in rows and columns of 6
        for j in range(3):
            expected[n_rod + i::6, n_rod + j::6] = chain_a[i::3, j::3]
    assert np.abs(a - expected).max() < 1e-13 * np.abs(expected).max()
    assert np.abs(a[n_rod:, n_rod:]).max() > 0


def test_band_storage_of_the_fused_band_is_that_of_the_block_product():
    """I - hγA from the fused dia band and from the BSR product: the same LAPACK rows (the
    first kl, dgbtrf's room for fill, are not set from the dia band), in single precision too,
    and into a given array."""
    rod, x = _bent_rod()
    expected = _reference_product(rod, x)[0]
    bsr = sp.bsr_array(expected, blocksize=(6, 6))
    kl, ku = banded.bandwidth(bsr)
    a = jacobian.local_jacobian(rod, 0.0, x, len(expected))
    fused = banded.band_storage(a, 0.7, kl, ku)
    assert fused.flags.f_contiguous and fused.shape == (2 * kl + ku + 1, len(expected))
    scale = 0.7 * np.abs(expected).max()
    reference = banded.band_storage(bsr, 0.7, kl, ku)
    assert not reference[:kl].any()
    assert np.abs(fused[kl:] - reference[kl:]).max() < 1e-13 * scale
    assert fused[kl + ku, 5] == pytest.approx(1.0 - 0.7 * expected[5, 5], rel=1e-12)
    out = np.full_like(fused, np.nan, dtype=np.float32)
    single = banded.band_storage(a, 0.7, kl, ku, np.float32, out=out)
    assert single is out and np.allclose(single[kl:], fused[kl:], rtol=1e-6, atol=1e-6 * scale)


def test_bandwidth_of_blocks_counts_every_entry_of_a_block():
    """A block tridiagonal matrix of 6 x 6 blocks has bandwidth 11 either side; a lower
    bidiagonal one of 1 x 1 entries (1, 0); the COO and BSR paths agree."""
    tri = sp.bsr_array(np.kron(sp.diags_array([1, 1, 1], offsets=[-1, 0, 1], shape=(5, 5))
                               .toarray(), np.ones((6, 6))), blocksize=(6, 6))
    assert banded.bandwidth(tri) == (11, 11)
    assert banded.bandwidth(sp.csr_array(tri)) == (11, 11)
    lower = sp.diags_array([1.0, 2.0], offsets=[-1, 0], shape=(4, 4))
    assert banded.bandwidth(lower) == (1, 0)


def _banded_matrix(n=240, kl=5, ku=3, seed=3):
    rng = np.random.default_rng(seed)
    dense = np.zeros((n, n))
    for off in range(-kl, ku + 1):
        dense += np.diag(rng.standard_normal(n - abs(off)), off)
    return dense


def test_band_storage_is_lapacks_layout():
    """Entry (i, j) of I - hγA at row kl + ku + i - j of column j, the first kl rows zero."""
    dense = _banded_matrix()
    kl, ku = 5, 3
    ab = banded.band_storage(sp.csr_array(dense), 0.3, kl, ku)
    expected = np.eye(len(dense)) - 0.3 * dense
    for i, j in [(0, 0), (7, 4), (4, 7), (100, 95), (95, 98)]:
        assert ab[kl + ku + i - j, j] == expected[i, j]
    assert not ab[:kl].any()
    bsr = sp.bsr_array(dense, blocksize=(4, 4))  # the compiled path: the same entries
    kb, ub = banded.bandwidth(bsr)
    ab4 = banded.band_storage(bsr, 0.3, kb, ub)
    for i, j in [(0, 0), (7, 4), (4, 7), (100, 95), (95, 98)]:
        assert ab4[kb + ub + i - j, j] == expected[i, j]


@pytest.mark.parametrize("kl", [5, 200])
def test_factorization_solves_as_a_dense_solve(kl, monkeypatch):
    """Banded (LAPACK, a band below n/8; its elimination in double here) and general
    (SuperLU) factorizations of I - hγA solve like numpy's dense solve."""
    monkeypatch.setattr(solve, "BAND_PRECISION", np.float64)
    dense = _banded_matrix(kl=kl, ku=3)
    lu = Factorization(sp.csr_array(dense), 0.05, 0.0)
    assert lu.banded == (kl < 240 // 8)
    rhs = np.random.default_rng(4).standard_normal(240)
    expected = np.linalg.solve(np.eye(240) - 0.05 * dense, rhs)
    assert np.allclose(lu.solve(rhs), expected, rtol=1e-10, atol=1e-12)


def test_single_precision_factors_solve_one_fixed_matrix_in_double():
    """The default banded LU eliminates in single precision and solves in double on those
    factors: the solves are those of one matrix I - hγA' (linear to double's round-off, as a
    W-method needs), A' within single precision of A (the solve off the exact one by about
    1e-7, far more than double's round-off: the elimination really is single)."""
    assert solve.BAND_PRECISION == np.float32
    dense = _banded_matrix(kl=5, ku=3)
    lu = Factorization(sp.csr_array(dense), 0.05, 0.0)
    rng = np.random.default_rng(8)
    v, w = rng.standard_normal((2, 240))
    x, y = lu.solve(v), lu.solve(w)
    combined = lu.solve(0.3 * v - 2.0 * w)
    assert np.abs(combined - (0.3 * x - 2.0 * y)).max() < 1e-13 * np.abs(combined).max()
    exact = np.linalg.solve(np.eye(240) - 0.05 * dense, v)
    off = np.abs(x - exact).max() / np.abs(exact).max()
    assert 1e-10 < off < 1e-5


@pytest.mark.parametrize("kl", [2, 200])
def test_a_singular_matrix_is_a_named_stiff_solve_error(kl):
    dense = _banded_matrix(kl=kl, ku=1)
    dense[10] = 0.0
    dense[10, 10] = 1.0 / 0.5  # row 10 of I - 0.5 A is zero
    with pytest.raises(StiffSolveError, match="singular"):
        Factorization(sp.csr_array(dense), 0.5, 1.5)


@dataclasses.dataclass(frozen=True)
class Counted(Forced):
    """Forced with a counter of its Jacobian builds (a list shared by copies)."""

    calls: list = dataclasses.field(default_factory=list)

    def stiff_jacobian(self, t, x):
        self.calls.append(t)
        return super().stiff_jacobian(t, x)


def _stepper(system, scheme="ros2", refresh=None):
    return stepper.Stepper(system, ROSENBROCK[scheme], system.rates, system.advance,
                           refresh=refresh)


@pytest.mark.parametrize(("steps", "refresh", "builds"), [(12, 5, 3), (10, 5, 2), (7, 1, 7),
                                                          (9, 10, 1)])
@pytest.mark.parametrize("scheme", ["ros2", "ros34pw2", "ros2-krylov"])
def test_a_is_rebuilt_every_refresh_steps_and_factorized_once_per_build(scheme, steps, refresh,
                                                                        builds):
    """At a fixed step: ``A`` built at steps 0, refresh, 2 refresh, ... and factorized once
    each (ros2-krylov too: its preconditioner is kept across the steps)."""
    system = Counted(lam=(-1.0, -1e3))
    run = _stepper(system, scheme, refresh)
    x = system.initial_state()
    for i in range(steps):
        x = run.step(0.01 * i, x, 0.01)
    assert (run.jacobians, run.factorizations, len(system.calls)) == (builds, builds, builds)
    assert system.calls == pytest.approx([0.01 * refresh * j for j in range(builds)])


@pytest.mark.parametrize(("scheme", "ratio", "refactorized"), [
    ("ros2", 1.0, False), ("ros2", 2.0, False), ("ros2", 0.5, False), ("ros2", 2.01, True),
    ("ros2", 0.49, True), ("ros34pw2", 1.25, False), ("ros34pw2", 0.5, False),
    ("ros34pw2", 1.26, True), ("ros34pw2", 0.49, True)])
def test_a_factorization_serves_the_steps_of_its_reuse_range(scheme, ratio, refactorized):
    """A step of ``ratio`` times the factorized one keeps the factorization inside the scheme's
    ``reuse`` range (ROS2 [1/2, 2], ROS34PW2 [1/2, 1.25]) and refactorizes outside it."""
    system = Forced(lam=(-1.0, -1e3))
    run = _stepper(system, scheme, refresh=100)
    x = run.step(0.0, system.initial_state(), 0.01)
    run.step(0.01, x, 0.01 * ratio)
    assert run.factorizations == 1 + refactorized


def _amplification(scheme, factor):
    """The largest |R| of one step on y' = zy, z from -1e-2 to -1e8, with A = factor z."""
    return max(abs(integrate.step(Forced(lam=(z,), forced=False, jacobian_factor=factor),
                                  scheme, 0.0, np.array([[1.0]]), 1.0)[0, 0])
               for z in -np.logspace(-2, 8, 60))


@pytest.mark.parametrize("scheme", ["lieuler", "ros2", "ros34pw2"])
def test_the_reuse_range_keeps_the_step_from_amplifying(scheme):
    """A step h = r h_f on a factorization at h_f is a step with A = z / r: within the reuse
    range (r at both ends) |R| <= 1 for every z < 0; ROS34PW2 at r = 2 amplifies (|R| = 6.5)."""
    low, high = ROSENBROCK[scheme].reuse
    assert _amplification(scheme, 1.0 / low) <= 1.0
    assert _amplification(scheme, 1.0 / high) <= 1.0
    if scheme == "ros34pw2":
        assert _amplification(scheme, 0.5) > 5.0


def test_a_reused_factorization_is_the_w_method_with_a_scaled_jacobian():
    """A step h after a factorization at h_f equals, to round-off, a fresh step h whose A is
    (h_f / h) times the Jacobian: the reuse is exactly a W-method with that A."""
    h_f, h = 0.01, 0.012
    system = Forced(lam=(-1.0, -1e3))
    run = _stepper(system, "ros34pw2", refresh=100)
    x1 = run.step(0.0, system.initial_state(), h_f)
    reused = run.step(h_f, x1, h)
    assert run.factorizations == 1
    scaled = Forced(lam=(-1.0, -1e3), jacobian_factor=h_f / h)
    fresh = _stepper(scaled, "ros34pw2").step(h_f, x1, h)
    assert np.allclose(reused, fresh, rtol=1e-13, atol=1e-15)
    plain = _stepper(system, "ros34pw2").step(h_f, x1, h)
    assert not np.allclose(reused, plain, rtol=1e-10, atol=0)  # the scaling is real


def _count_factorizations(monkeypatch) -> list[float]:
    """The step sizes hγ of every factorization the stepper makes from now on."""
    made: list[float] = []
    original = stepper.Factorization

    def counted(matrix, hgamma, t):
        made.append(hgamma)
        return original(matrix, hgamma, t)

    monkeypatch.setattr(stepper, "Factorization", counted)
    return made


def test_adaptive_steps_factorize_less_often_than_they_change_the_step(monkeypatch):
    """Adaptive ROS2 on Prothero-Robinson (λ = -1e3, A every 1000 steps): the step changes at
    nearly every step, yet the factorizations are fewer than half the steps; the run is the
    same bits twice."""
    made = _count_factorizations(monkeypatch)
    monkeypatch.setattr(stepper, "REFRESH", 1000)
    system = Forced(lam=(-1.0, -1e3))
    runs = [integrate.run(system, system.initial_state(), 0.0, 1.0, "ros2", 1e-3,
                          rtol=1e-4, atol=1e-6) for _ in range(2)]
    assert np.array_equal(runs[0].state, runs[1].state)
    assert (runs[0].n_steps, runs[0].n_rejected) == (runs[1].n_steps, runs[1].n_rejected)
    per_run = len(made) // 2
    assert runs[0].n_steps > 100 and per_run < (runs[0].n_steps + runs[0].n_rejected) / 4
    assert np.abs(runs[0].state - system.exact(1.0)).max() < 2e-4


def test_banded_and_general_factorizations_give_the_same_run(monkeypatch):
    """The rod's run with A's band factorized by LAPACK in double equals (to 1e-10) the run
    with SuperLU (the band reported as the whole matrix), and in single (the default) to
    1e-7: a W-method on A within single precision of A."""
    rod = models.rod_swimmer(n_points=61, length=12.0, epsilon=0.3, n_threads=1)
    x0 = rod.initial_state()
    single = integrate.run(rod, x0, 0.0, 5e-4, "ros34pw2", 1e-4).state
    monkeypatch.setattr(solve, "BAND_PRECISION", np.float64)
    assert Factorization(jacobian.local_jacobian(rod, 0.0, x0, 6 * len(x0)), 1e-4, 0.0).banded
    a = integrate.run(rod, x0, 0.0, 5e-4, "ros34pw2", 1e-4).state
    monkeypatch.setattr(solve, "bandwidth", lambda matrix: (matrix.shape[0], matrix.shape[0]))
    assert not Factorization(jacobian.local_jacobian(rod, 0.0, x0, 6 * len(x0)), 1e-4, 0.0).banded
    b = integrate.run(rod, x0, 0.0, 5e-4, "ros34pw2", 1e-4).state
    assert np.allclose(a, b, rtol=0, atol=1e-10 * np.abs(a).max())
    moved = np.abs(single - a)[:, :3].max() / np.abs(a[:, :3] - x0[:, :3]).max()
    assert 1e-13 < moved < 1e-6


@pytest.mark.parametrize("width", [3, 2])
def test_coloured_differences_are_the_analytic_jacobian(width):
    """fd_jacobian on f_i = (x_i0 x_{i+1,1}, sin x_i2 + 2 x_{i-1,0}, x_i1²)[:width] (chain
    coupling, rates by shifts): the analytic Jacobian, entry (width i + l, 3 j + q)."""
    from parastokes.stiff import coloring

    n = 7
    x = np.random.default_rng(5).standard_normal((n, 3))

    def function(y):
        nxt, prev = np.roll(y, -1, axis=0), np.roll(y, 1, axis=0)
        nxt[-1], prev[0] = 0.0, 0.0
        return np.stack([y[:, 0] * nxt[:, 1], np.sin(y[:, 2]) + 2 * prev[:, 0], y[:, 1] ** 2],
                        axis=1)[:, :width]

    expected = np.zeros((n * width, n * 3))
    for i in range(n):
        if i + 1 < n:
            expected[width * i, 3 * i] = x[i + 1, 1]
            expected[width * i, 3 * (i + 1) + 1] = x[i, 0]
        expected[width * i + 1, 3 * i + 2] = np.cos(x[i, 2])
        if i > 0:
            expected[width * i + 1, 3 * (i - 1)] = 2.0
        if width == 3:
            expected[width * i + 2, 3 * i + 1] = 2 * x[i, 1]
    got = coloring.fd_jacobian(function, lambda y, d, h: y + h * d, x, 3,
                               coloring.banded(1, n, 1), 1e-6).toarray()
    assert np.allclose(got, expected, rtol=0, atol=1e-8)


def test_the_rods_load_jacobian_hook_is_the_coloured_differences():
    """RodSystem.load_jacobian (compiled, segment by segment) on two bent and twisted rods
    beating at t = 0.013 (a preferred strain that depends on t and on the half point): the
    coloured central differences of its loads, to their round-off (relative 1e-9)."""
    from parastokes.stiff import coloring

    rod = models.rod_swimmer(n_points=21, length=4.0, epsilon=0.4, n_threads=1)
    rod = dataclasses.replace(rod, n_rods=2, spacing=3.0)
    x = rod.initial_state()
    s = np.tile(np.linspace(0.0, 1.0, 21), 2)
    x[:, 1] += 0.4 * np.sin(3.0 * s) + 0.1 * np.arange(42) // 21
    x[:, 2] += 0.2 * s ** 2
    twist = np.zeros((42, 6))
    twist[:, 3:] = 0.3 * np.stack([np.cos(5 * s), s, np.sin(4 * s)], axis=1)
    x = rod.advance(x, twist, 1.0)  # frames no longer along the centre line
    hook = rod.load_jacobian(0.013, x)
    assert isinstance(hook, sp.bsr_array) and hook.blocksize == (6, 6)
    loads = jacobian._loads_function(rod, 0.013)
    fd = coloring.fd_jacobian(loads, rod.advance, x, 6, rod.load_coupling(),
                              jacobian.fd_step(x)).toarray()
    assert np.abs(hook.toarray() - fd).max() < 1e-9 * np.abs(fd).max()
    np.testing.assert_array_equal(jacobian.load_jacobian(rod, 0.013, x).toarray(),
                                  hook.toarray())  # the schemes' K is the hook's


@pytest.mark.parametrize("shape", ["cloud", "rod along z", "coincident"])
def test_sorted_pairs_are_every_pair_within_the_cutoff(shape):
    """The compiled sort and sweep against all n² distances: the same pairs (at most the
    cutoff apart, self pairs included), sources ascending per target; a rod along z (the sweep
    along its longest extent) and repeated points too."""
    rng = np.random.default_rng(9)
    points = {"cloud": rng.uniform(0.0, 3.0, size=(80, 3)),
              "rod along z": np.stack([0.01 * rng.standard_normal(60), np.zeros(60),
                                       np.linspace(0.0, 12.0, 60)], axis=1),
              "coincident": np.repeat(rng.uniform(0.0, 2.0, size=(20, 3)), 2, axis=0)}[shape]
    cutoff = 0.8
    indptr, source = local.sorted_pairs(points, cutoff)
    distance = np.linalg.norm(points[:, None] - points[None], axis=2)
    for i in range(len(points)):
        row = source[indptr[i]:indptr[i + 1]]
        assert list(row) == list(np.flatnonzero(distance[i] <= cutoff)), i


@pytest.mark.parametrize("precision", [np.float32, np.float64])
def test_band_solve_is_lapacks_dgbtrs_on_the_same_factors(precision):
    """The compiled solve of the banded factors (single or double precision, read as they are)
    against LAPACK's dgbtrs on the same factors in double: the same solution to round-off, on
    a matrix whose elimination pivots (row interchanges happen) with kl != ku."""
    from scipy.linalg import lapack

    kl, ku = 7, 4
    dense = np.eye(200) - 0.8 * _banded_matrix(n=200, kl=kl, ku=ku, seed=10)
    ab = banded.band_storage(sp.csr_array(np.eye(200) - dense), 1.0, kl, ku, precision)
    lu, piv, info = (lapack.sgbtrf if precision == np.float32 else lapack.dgbtrf)(ab, kl, ku)
    assert info == 0 and np.any(piv != np.arange(200))
    rhs = np.random.default_rng(11).standard_normal(200)
    expected = lapack.dgbtrs(lu.astype(float, order="F"), kl, ku, rhs, piv)[0]
    got = solve.band_solve(lu, kl, ku, piv, rhs)
    assert np.abs(got - expected).max() < 1e-12 * np.abs(expected).max()
    if precision == np.float64:
        assert np.allclose(got, np.linalg.solve(dense, rhs), rtol=1e-10, atol=1e-12)


def _column_sweeps(lu, kl, ku, piv, b):
    """LAPACK dgbtrs's sweeps, column by column over the whole stored band, in numpy (each
    update ``x_i -= u x_c`` rounded as the compiled solve rounds it): the reference bits."""
    n, kv = lu.shape[1], kl + ku
    x = b.copy()
    for j in range(n - 1):
        x[[j, piv[j]]] = x[[piv[j], j]]
        if x[j] != 0.0:
            lm = min(kl, n - j - 1)
            x[j + 1:j + 1 + lm] -= lu[kv + 1:kv + 1 + lm, j].astype(float) * x[j]
    for j in range(n - 1, -1, -1):
        if x[j] != 0.0:
            x[j] /= float(lu[kv, j])
            first = max(0, j - kv)
            x[first:j] -= lu[kv + first - j:kv, j].astype(float) * x[j]
    return x


def _ragged_band(n, kl, ku, seed):
    """A banded matrix whose columns reach 0 to kl below and 0 to ku above the diagonal (a
    ragged band, as a rod's near mobility gives), its diagonal small enough that the
    elimination pivots."""
    rng = np.random.default_rng(seed)
    dense = np.zeros((n, n))
    for j in range(n):
        below, above = rng.integers(0, kl + 1), rng.integers(0, ku + 1)
        rows = np.arange(max(0, j - above), min(n, j + below + 1))
        dense[rows, j] = rng.standard_normal(rows.size)
        dense[j, j] = 0.3 * rng.standard_normal()
    return dense


@pytest.mark.parametrize(("n", "kl", "ku", "precision"), [
    (37, 5, 3, np.float64), (53, 2, 9, np.float32), (200, 7, 4, np.float32),
    (201, 12, 12, np.float64), (6, 4, 1, np.float64), (1, 0, 0, np.float64)])
def test_band_solve_is_the_column_sweeps_bit_for_bit_and_solves(n, kl, ku, precision):
    """The compiled solve (its loops over unsigned indices) gives the very bits of dgbtrs's
    column-by-column sweeps, on ragged banded matrices whose elimination pivots, odd sizes,
    kl != ku, right-hand sides with zeros (the skipped columns), in single and double
    precision; and it solves: against scipy's solve_banded, and with a residual of round-off
    against the matrix the factors are of (P L U; for double factors the matrix itself)."""
    from scipy.linalg import lapack, solve_banded

    dense = _ragged_band(n, kl, ku, seed=n + kl)
    ab = banded.band_storage(sp.csr_array(-dense), 1.0, kl, ku, precision) - (
        banded.band_storage(sp.csr_array(np.eye(n)), 0.0, kl, ku, precision))
    lu, piv, info = (lapack.sgbtrf if precision == np.float32 else lapack.dgbtrf)(ab, kl, ku)
    assert info == 0
    if n > 30:
        assert np.any(piv != np.arange(n))
    rng = np.random.default_rng(n)
    for zeros in (0, n // 3):
        rhs = rng.standard_normal(n)
        rhs[rng.choice(n, zeros, replace=False)] = 0.0
        got = solve.band_solve(lu, kl, ku, piv, rhs)
        assert np.array_equal(got, _column_sweeps(lu, kl, ku, piv, rhs))
        band = np.zeros((kl + ku + 1, n))
        for off in range(-kl, ku + 1):
            band[ku - off, max(off, 0):n + min(off, 0)] = np.diag(dense, off)
        exact = solve_banded((kl, ku), band, rhs)
        residual = np.abs(dense @ got - rhs).max() / np.abs(rhs).max()
        if precision == np.float64:
            assert np.allclose(got, exact, rtol=1e-9, atol=1e-11 * np.abs(exact).max())
            assert residual < 1e-12
        else:  # exact for the factors' own matrix P L U (rounded to single by sgbtrf)
            p_l_u = _factors_product(lu, kl, ku, piv)
            assert np.abs(p_l_u @ got - rhs).max() < 1e-12 * np.abs(rhs).max() * max(
                1.0, np.abs(got).max())
            assert 1e-9 < np.abs(got - exact).max() / np.abs(exact).max() < 1e-3


def _factors_product(lu, kl, ku, piv):
    """P L U in double from gbtrf's factors (each multiplier and row interchange in turn)."""
    n, kv = lu.shape[1], kl + ku
    u = np.zeros((n, n))
    for j in range(n):
        first = max(0, j - kv)
        u[first:j + 1, j] = lu[kv + first - j:kv + 1, j]
    product = u
    for j in range(n - 2, -1, -1):  # undo the eliminations in reverse: L_j then P_j
        lm = min(kl, n - j - 1)
        product[j + 1:j + 1 + lm] += np.outer(lu[kv + 1:kv + 1 + lm, j].astype(float),
                                              product[j])
        product[[j, piv[j]]] = product[[piv[j], j]]
    return product


def test_spares_keep_freed_arrays_by_shape_and_dtype():
    """take() hands back a given array only for its shape and dtype, each once; give() keeps the
    latest ``keep``."""
    spares = solve.Spares(keep=2)
    a = np.empty((5, 7), dtype=np.float32, order="F")
    spares.give(a)
    assert spares.take((5, 7), np.float64) is not a
    assert spares.take((7, 5), np.float32) is not a
    assert spares.take((5, 7), np.float32) is a
    assert spares.take((5, 7), np.float32) is not a  # once
    given = [np.empty((2, 2), order="F") for _ in range(3)]
    for array in given:
        spares.give(array)
    assert [id(k) for k in spares._free] == [id(k) for k in given[1:]]
    kept = [spares.take((2, 2), np.float64) for _ in range(3)]
    assert kept[0] is given[1] and kept[1] is given[2] and kept[2] is not given[0]


def test_a_freed_factorizations_memory_serves_the_next_with_the_same_solves():
    """The banded factors go back to SPARES when their Factorization is freed, and the next
    factorization of that shape reuses them: its solves are the same bits as on new memory
    (dgbtrf reads none of what is left there: here NaN), and two live factorizations never
    share their factors."""
    import gc

    rod, x = _bent_rod()
    a = jacobian.local_jacobian(rod, 0.0, x, 6 * len(x))
    v = np.random.default_rng(12).standard_normal(6 * len(x))
    first = Factorization(a, 1e-4, 0.0)
    expected = first.solve(v)
    memory = first._band[0]
    memory_id = id(memory)
    del first, memory
    gc.collect()
    assert any(id(m) == memory_id for m in solve.SPARES._free)
    for m in solve.SPARES._free:
        m[...] = np.nan  # whatever was left there
    second = Factorization(a, 1e-4, 0.0)
    assert id(second._band[0]) == memory_id
    assert np.array_equal(second.solve(v), expected)
    third = Factorization(a, 2e-4, 0.0)  # while the second lives: its own memory
    assert third._band[0] is not second._band[0]
    assert np.array_equal(second.solve(v), expected)
    assert not np.array_equal(third.solve(v), expected)
