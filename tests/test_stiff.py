"""Linearly implicit schemes (parastokes.stiff): closed forms on linear stiff ODEs, fitted orders,
the near mobility against the kernels, Jacobians against finite differences, adaptive steps,
failures named, Parareal with an implicit coarse solver."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import scipy.sparse as sp
from rods import helix_rod

from parastokes import integrate, models, parallel, parareal
from parastokes.bodies.contract import BodyError
from parastokes.integrate import SCHEMES, BlowUpError
from parastokes.kinds.chain import ChainSystem
from parastokes.kinds.rod.system import RodSystem
from parastokes.mrs import reference
from parastokes.scene import Scene
from parastokes.stiff import jacobian, local, solve
from parastokes.testing import fitted_order

GAMMA = 1.0 + 1.0 / math.sqrt(2.0)


@dataclasses.dataclass(frozen=True)
class Forced:
    """Prothero-Robinson: y' = λ (y - g(t)) + g'(t), g = sin, y(t) = g(t) + (y0 - g(0)) e^{λt};
    ``jacobian_factor`` scales the exact Jacobian λ handed to the scheme (None: no Jacobian)."""

    lam: tuple[float, ...] = (-1.0, -1e4)
    jacobian_factor: float | None = 1.0
    forced: bool = True

    def initial_state(self) -> np.ndarray:
        return np.full((len(self.lam), 1), 2.0)

    def g(self, t: float) -> tuple[float, float]:
        return (math.sin(t), math.cos(t)) if self.forced else (0.0, 0.0)

    def rates(self, t: float, x: np.ndarray) -> np.ndarray:
        g, dg = self.g(t)
        return np.asarray(self.lam)[:, None] * (x - g) + dg

    def exact(self, t: float) -> np.ndarray:
        g0, _ = self.g(0.0)
        g, _ = self.g(t)
        return g + (2.0 - g0) * np.exp(np.asarray(self.lam) * t)[:, None]

    def stiff_jacobian(self, t: float, x: np.ndarray):
        if self.jacobian_factor is None:
            return None
        return sp.diags_array(self.jacobian_factor * np.asarray(self.lam))

    def advance(self, x, r, dt):
        return x + dt * r

    def project(self, x):
        return x

    def positions(self, x):
        return np.repeat(x, 3, axis=1)

    @property
    def params(self):
        return {}

    def with_params(self, **theta):
        return self

    def monitor(self, x):
        return float(np.abs(x).max())

    @property
    def monitor_limit(self):
        return 100.0


@pytest.mark.parametrize("z", [-0.5, -30.0, -1e4])
def test_one_step_on_a_linear_stiff_ode_is_the_stability_function(z):
    """One step on y' = λ y with the exact Jacobian: R(z) = 1/(1 - z) (linearly implicit
    Euler); 1 + 2z/D - z/D² + z²/(2D²), D = 1 - γz (ROS2): L-stable, R(-∞) = 0."""
    system = Forced(lam=(z,), forced=False)
    d = 1.0 - GAMMA * z
    closed = {"lieuler": 1.0 / (1.0 - z),
              "ros2": 1.0 + 2 * z / d - z / d**2 + z**2 / (2 * d**2)}
    for name, r in closed.items():
        y = integrate.step(system, name, 0.0, np.array([[1.0]]), 1.0)
        assert y[0, 0] == pytest.approx(r, rel=1e-12, abs=1e-15)
        assert abs(r) < 1.0
    assert abs(closed["ros2"]) < 0.01 if z == -1e4 else True


def _errors(system, name, counts, t1=1.0):
    x0 = system.initial_state()
    return [float(np.abs(integrate.run(system, x0, 0.0, t1, name, t1 / n).state
                         - system.exact(t1)).max()) for n in counts]


def _slope(counts, errors):
    return -np.polyfit(np.log(counts), np.log(errors), 1)[0]


@pytest.mark.parametrize(("name", "factor"), [("lieuler", 1.0), ("ros2", 1.0), ("ros2", 0.5),
                                               ("ros2", 2.0), ("ros2", None)])
def test_fitted_orders_on_a_smooth_ode(name, factor):
    """Non-stiff (λ = -1, -3): the declared order with the exact Jacobian, a wrong one (half,
    twice) or none: the W-property."""
    system = Forced(lam=(-1.0, -3.0), jacobian_factor=factor)
    counts = [32, 64, 128, 256]
    assert abs(_slope(counts, _errors(system, name, counts)) - SCHEMES[name].order) < 0.2


@pytest.mark.parametrize("name", ["lieuler", "ros2"])
def test_stiff_forced_problem_keeps_the_order_at_steps_far_beyond_the_explicit_limit(name):
    """Prothero-Robinson with λ = -1e4 at h|λ| from 80 to 600 (forward Euler's limit: 2): the
    f_t term of the stages keeps ROS2 second order (without it, first)."""
    system = Forced(lam=(-1.0, -1e4))
    counts = [16, 32, 64, 128]
    errors = _errors(system, name, counts)
    assert max(errors) < 0.05
    assert abs(_slope(counts, errors) - SCHEMES[name].order) < 0.2
    with pytest.raises(BlowUpError):  # the explicit scheme at the same steps
        integrate.run(system, system.initial_state(), 0.0, 1.0, "rk2", 1.0 / 16)


def test_fitted_orders_on_the_rod_with_rotating_frames():
    """The helix-relaxing rod (3D frame dynamics, a stiff elastic response): each implicit
    scheme within 0.2 of its order at steps where the stiff Jacobian is resolved."""
    rod = helix_rod()
    x = integrate.propagate(rod, rod.initial_state(), 0.0, 2.0, "rk2", 0.05)
    horizon = 0.1
    ref = integrate.run(rod, x, 0.0, horizon, "rk4", horizon / 1024).state
    for name, steps in (("lieuler", [16, 32, 64, 128]), ("ros2", [8, 16, 32, 64])):
        assert abs(fitted_order(rod, x, 0.0, horizon, name, steps, ref)
                   - SCHEMES[name].order) < 0.2, name


def test_near_mobility_with_every_pair_is_the_kernels():
    rng = np.random.default_rng(0)
    p, f, n = (rng.normal(size=(7, 3)) for _ in range(3))
    matrix = local.near_mobility(p, 0.7, 2.0, True, 1e9).toarray()
    u, w = reference.velocity(p, p, f, epsilon=0.7, mu=2.0, torques=n, angular=True)
    uw = (matrix @ np.concatenate([f, n], axis=1).ravel()).reshape(7, 6)
    np.testing.assert_allclose(uw, np.concatenate([u, w], axis=1), rtol=1e-12, atol=1e-14)


def test_tapered_near_mobility_is_positive_semidefinite_where_truncation_is_not():
    """Cut at 3ε, the Stokeslet matrix has negative eigenvalues (a truncated kernel): a W-method
    on it amplifies. Tapered by Wendland's function it stays positive semi-definite."""
    rng = np.random.default_rng(1)
    points = rng.uniform(0, 4.0, size=(120, 3))
    tapered = local.near_mobility(points, 0.5, 1.0, False, 1.5).toarray()
    assert np.linalg.eigvalsh(0.5 * (tapered + tapered.T)).min() > -1e-10 * np.abs(tapered).max()
    indptr, source = local.sorted_pairs(points, 1.5)
    target = np.repeat(np.arange(len(points)), np.diff(indptr))
    blocks = local.pair_blocks(points[target] - points[source], 0.5, False)
    cut = np.zeros((360, 360))
    for b, i, j in zip(blocks, target, source, strict=True):
        cut[3 * i: 3 * i + 3, 3 * j: 3 * j + 3] = b
    assert np.linalg.eigvalsh(cut).min() < -1e-3 * np.abs(cut).max()


@pytest.mark.parametrize("body", [
    models.rod_swimmer(n_points=31, length=6.0),
    models.vesicle(subdivisions=1),
    ChainSystem(n_beads=12, tilt=0.3, stretch=1.1),
], ids=["rod", "vesicle", "chain"])
def test_each_kinds_load_jacobian_agrees_with_dense_finite_differences(body):
    x = body.initial_state()
    if isinstance(body, RodSystem):  # a bent, twisted state: every frame entry matters
        x = integrate.propagate(body, x, 0.0, 2e-3, "rk2", 1e-5)
    assert jacobian.jacobian_check(body, 1e-3, x) < 1e-6


def test_a_coupling_that_misses_a_dependence_is_caught():
    @dataclasses.dataclass(frozen=True)
    class NearSighted(RodSystem):
        load_jacobian = None  # the coloured differences over the coupling below

        def load_coupling(self):
            return sp.eye_array(self.n_rods * self.n_points)

    rod = NearSighted(n_points=15, length=3.0, preferred=(0.5, 0.0, 0.0))
    assert jacobian.jacobian_check(rod, 0.0, rod.initial_state()) > 0.1


def test_a_jacobian_of_the_wrong_shape_or_not_finite_is_named():
    @dataclasses.dataclass(frozen=True)
    class Flat(Forced):
        def stiff_jacobian(self, t, x):
            return np.ones((3, 3))

    @dataclasses.dataclass(frozen=True)
    class Nan(Forced):
        def stiff_jacobian(self, t, x):
            return np.full((2, 2), np.nan)

    with pytest.raises(BodyError, match=r"Flat\.stiff_jacobian\(t, state\) returned shape "
                                        r"\(3, 3\); expected \(2, 2\)"):
        integrate.run(Flat(), Flat().initial_state(), 0.0, 1.0, "ros2", 0.1)
    # non-finite entries in a run are a blow-up there (issue 50); at the probe, a BodyError
    with pytest.raises(integrate.BlowUpError,
                       match=r"Nan\.stiff_jacobian\(t, state\) returned NaN at t = 0"):
        integrate.run(Nan(), Nan().initial_state(), 0.0, 1.0, "ros2", 0.1)


def test_adaptive_steps_meet_the_tolerance_and_are_reproducible():
    system = Forced(lam=(-1.0, -1e4))
    x0 = system.initial_state()
    errors, steps = [], []
    for rtol in (1e-3, 1e-5):
        run = integrate.run(system, x0, 0.0, 1.0, "ros2", 1e-3, rtol=rtol, atol=rtol)
        again = integrate.run(system, x0, 0.0, 1.0, "ros2", 1e-3, rtol=rtol, atol=rtol)
        assert np.array_equal(run.state, again.state) and run.n_steps == again.n_steps
        errors.append(float(np.abs(run.state - system.exact(1.0)).max()))
        steps.append(run.n_steps)
        assert errors[-1] < 20 * rtol
    assert errors[1] < errors[0] / 10 and steps[1] > steps[0]
    fixed = integrate.Propagator(system, "ros2", 1e-3, rtol=1e-5)
    assert np.array_equal(fixed(0.0, 1.0, x0), run.state)


def test_tolerances_and_schemes_without_an_estimate_are_refused():
    system = Forced()
    with pytest.raises(ValueError, match=r"rtol: must be a finite number > 0, got -1"):
        integrate.Propagator(system, "ros2", 0.1, rtol=-1.0)
    with pytest.raises(ValueError, match=r"atol: must be a finite number > 0, got inf"):
        integrate.Propagator(system, "ros2", 0.1, rtol=1e-3, atol=math.inf)
    with pytest.raises(ValueError, match=r"rtol: the scheme 'lieuler' has no error estimate.*"
                                         r"'ros2'"):
        integrate.run(system, system.initial_state(), 0.0, 1.0, "lieuler", 0.1, rtol=1e-3)


def test_a_gmres_that_does_not_converge_is_a_named_blowup(monkeypatch):
    monkeypatch.setattr(solve, "GMRES_MAXITER", 1)
    monkeypatch.setattr(solve, "GMRES_ACCEPT", 1e-14)
    rod = models.rod_swimmer(n_points=21)
    with pytest.raises(BlowUpError, match=r"GMRES did not converge; use a smaller step.*"
                                          r"relative residual [0-9.e-]+ after 1 iterations"):
        integrate.run(rod, rod.initial_state(), 0.0, 1e-3, "ros2-krylov", 1e-3)


def test_a_body_without_a_stiff_part_steps_as_the_explicit_scheme():
    """No Jacobian (a system of rates only; rigid bodies): linearly implicit Euler is forward
    Euler, and ROS2 of an autonomous system is Heun's RK2."""
    system = Forced(lam=(-1.0, -3.0), jacobian_factor=None, forced=False)
    x0 = system.initial_state()
    for implicit, explicit in (("lieuler", "euler"), ("ros2", "rk2")):
        np.testing.assert_allclose(integrate.propagate(system, x0, 0.0, 1.0, implicit, 0.1),
                                   integrate.propagate(system, x0, 0.0, 1.0, explicit, 0.1),
                                   rtol=1e-14)


# ---- Parareal with an implicit coarse solver ----------------------------------------------------
STIFF_ROD = dict(n_points=201, epsilon=1.5)  # Euler's limit about 5.5e-5 s (docs/benchmarks.md)


def _stiff_rod_parareal(executor=None, coarse_scheme="ros2-krylov"):
    rod = models.rod_swimmer(**STIFF_ROD)
    fine = integrate.Propagator(rod, "rk2", 1e-5)
    coarse = integrate.Propagator(rod, coarse_scheme, 2.5e-4)  # 4.5x the explicit limit
    return parareal.run(fine, coarse, rod.initial_state(), t0=0.0, t1=2.5e-3, n_slices=5,
                        tol=0.0, max_iterations=3, executor=executor)


@pytest.fixture(scope="module")
def stiff_rod_serial():
    return _stiff_rod_parareal()


def test_parareal_with_an_implicit_coarse_solver_converges_on_a_stiff_rod(stiff_rod_serial):
    """An L-stable coarse step 4.5x beyond the explicit limit: each iteration gains about two
    digits at first (docs/stiff.md)."""
    inc = stiff_rod_serial.increments
    assert inc[1] < 0.02 * inc[0] and inc[2] < 0.2 * inc[1]


def test_processes_equal_serial_bit_for_bit_with_an_implicit_coarse_solver(stiff_rod_serial):
    with parallel.make_executor("processes", 2) as executor:
        result = _stiff_rod_parareal(executor)
    assert np.array_equal(result.states, stiff_rod_serial.states)
    assert result.increments == stiff_rod_serial.increments


def test_parareal_with_implicit_coarse_solvers_converges_on_a_vesicle_and_a_scene():
    """ROS2 on the exact Jacobian (ros2-krylov) as G, 6-20x the fine step, 8 slices and 3
    iterations: every iteration gains at least a factor 4 and the iterate approaches the serial
    fine solution (a rod above the wall beside a vesicle: docs/stiff.md)."""
    vesicle = models.vesicle(subdivisions=2)  # explicit limit about 8.4e-3
    rod = models.rod_swimmer(n_points=41, length=8.0, height=3.0)
    ves = models.vesicle(subdivisions=1, center=(4.0, 0.0, 6.0), viscosity=rod.viscosity,
                         shear_rate=0.0)
    scene = Scene(bodies=(rod, ves), viscosity=rod.viscosity, wall=True)
    for system, t1, fine_dt, coarse_dt in ((vesicle, 2.0, 2e-3, 0.05), (scene, 1e-3, 5e-6, 1e-4)):
        x0 = system.initial_state()
        fine = integrate.Propagator(system, "rk2", fine_dt)
        serial = fine(0.0, t1, x0)
        result = parareal.run(fine, integrate.Propagator(system, "ros2-krylov", coarse_dt), x0,
                              t0=0.0, t1=t1, n_slices=8, tol=0.0, max_iterations=3)
        inc = result.increments
        assert inc[1] < 0.25 * inc[0] and inc[2] < 0.25 * inc[1]
        assert float(np.abs(result.states[-1] - serial).max()) < 2 * inc[2]


def test_adaptive_auxiliary_solvers_of_an_extrapolated_coarse_solver():
    """rtol/atol reach every auxiliary solver; Richardson's fixed steps refuse them."""
    rod = models.rod_swimmer(n_points=21)
    coarse = parareal.extrapolated(rod, "ros2", 1e-4, lagrange={"epsilon": [1.03, 1.06]},
                                   rtol=1e-3, atol=1e-4)
    assert {(p.rtol, p.atol) for row in coarse.auxiliary for p in row} == {(1e-3, 1e-4)}
    with pytest.raises(ValueError, match=r"rtol: Richardson extrapolation \(m >= 1\) needs"):
        parareal.extrapolated(rod, "ros2", 1e-4, richardson={"m": 1, "r": 0.5}, rtol=1e-3)
    with pytest.raises(ValueError, match=r"rtol: the scheme 'euler' has no error estimate"):
        parareal.extrapolated(rod, "euler", 1e-4, rtol=1e-3)


# ---- the cost of an implicit step in predict's estimate of γ_G/γ_F -----------------------------
def _counting_rates(monkeypatch, system) -> list[int]:
    """Count the calls of ``system``'s rates (its class's method, wrapped)."""
    calls = [0]
    original = type(system).rates

    def rates(self, t, x):
        calls[0] += 1
        return original(self, t, x)

    monkeypatch.setattr(type(system), "rates", rates)
    return calls


@pytest.mark.parametrize("scheme", ["ros2", "ros2-krylov"])
def test_an_implicit_step_costs_at_least_the_evaluations_it_makes(monkeypatch, scheme):
    """The measured cost of a step, in rate evaluations, is at least the evaluations the step
    makes (counted: two stages and f_t for ROS2 on the beating rod, plus one per GMRES
    iteration), since the Jacobian, factorization and solves come on top."""
    from parastokes.coarse.step_cost import measured_evaluations

    rod = models.rod_swimmer(n_points=41, length=8.0, n_threads=1)
    calls = _counting_rates(monkeypatch, rod)
    integrate.run(rod, rod.initial_state(), 0.0, 2e-3, scheme, 2.5e-4)
    counted = calls[0] / 8
    assert counted >= 3  # f0, stage 2, f_t
    measured = measured_evaluations(rod, scheme, 0.0, 2e-3, 8)
    assert measured >= 0.8 * counted, (measured, counted)
    assert measured < 50 * counted  # the sparse algebra of 41 points is not a hundred sums


def test_predict_counts_stages_for_explicit_schemes_and_measures_implicit_ones(monkeypatch):
    from parastokes import config
    from parastokes.coarse import extrapolated, step_cost

    text = (
        'title = "stiff"\n[model]\nkind = "rod"\nn_points = 41\nlength = 8.0\n'
        '[time]\nt1 = 4e-3\n[fine]\nscheme = "rk2"\ndt = 2e-5\n'
        '[coarse]\nscheme = "euler"\ndt_ratio = 10\n[parareal]\nn_slices = 2\n'
    )
    cfg, resolved = config.loads(text)

    def no_body(*args, **kwargs):
        raise AssertionError("an explicit estimate builds no body")

    monkeypatch.setattr(extrapolated, "build_system", no_body)
    counted = cfg.coarse.gamma_ratio(cfg, resolved, 1)
    # eq.: N_G = 1, 10 coarse Euler steps (1 stage) against 100 fine RK2 steps (2 stages)
    assert counted == pytest.approx(10 * 1 / (100 * 2))
    monkeypatch.undo()
    cfg, resolved = config.loads(text, overrides=['coarse.scheme="ros2"'])
    seen = []
    real = step_cost.measured_evaluations

    def spy(system, scheme, *args, **kwargs):
        seen.append(scheme)
        return real(system, scheme, *args, **kwargs)

    monkeypatch.setattr(step_cost, "measured_evaluations", spy)
    implicit = cfg.coarse.gamma_ratio(cfg, resolved, 1)
    assert seen == ["ros2"]  # the fine RK2 at a fixed step is still counted, not timed
    assert implicit > 1.5 * counted  # ≥ 3 evaluations per step against Euler's 1
