"""The bead-spring chain (parastokes/kinds/chain/): mechanics, relaxation against the linearized
modes, tumbling in shear flow against Jeffery's orbit, drag against the Stokes/Kirkwood-Riseman
estimate and slender-body theory, and use from a TOML config and through Parareal."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from parastokes import config, integrate, mrs, parareal
from parastokes import run as runner
from parastokes.kinds.chain import ChainSystem, chain_energy, chain_forces
from parastokes.output import trajectory as io


def bent(system: ChainSystem, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return system.initial_state() + 0.2 * rng.normal(size=(system.n_beads, 3))


def test_forces_are_minus_the_energy_gradient_and_balance():
    s = ChainSystem(n_beads=7, stiffness=3.0, bending=2.0, bond=1.3)
    x = bent(s)
    f = chain_forces(x, s.bond, s.stiffness, s.bending)
    h = 1e-6
    grad = np.zeros_like(x)
    for i in range(x.shape[0]):
        for j in range(3):
            e = np.zeros_like(x)
            e[i, j] = h
            grad[i, j] = (chain_energy(x + e, s.bond, s.stiffness, s.bending)
                          - chain_energy(x - e, s.bond, s.stiffness, s.bending)) / (2 * h)
    np.testing.assert_allclose(f, -grad, atol=1e-7 * np.abs(f).max())
    np.testing.assert_allclose(f.sum(axis=0), 0.0, atol=1e-12)  # internal forces: no net force
    np.testing.assert_allclose(np.cross(x, f).sum(axis=0), 0.0, atol=1e-12)  # nor torque


def test_a_straight_chain_at_rest_length_feels_no_force():
    s = ChainSystem(n_beads=9, bending=5.0)
    np.testing.assert_array_equal(s.rates(0.0, s.initial_state()), 0.0)


def test_stretched_chain_relaxes_at_the_rate_of_its_slowest_linearized_mode():
    """Bond extensions e = D x - b of a straight chain along x obey, to first order, de/dt =
    -k D M Dᵀ e, M the x-x block of the regularized Stokeslet mobility of the beads (bending does
    not act on collinear perturbations). Started in the slowest mode, e(t) = e(0) exp(-λ t)."""
    s = ChainSystem(n_beads=8, stiffness=2.0, bending=1.0, epsilon=0.25)
    x0 = s.initial_state()
    n = s.n_beads
    unit = np.zeros((n, 3))
    m = np.empty((n, n))
    for j in range(n):
        unit[:] = 0.0
        unit[j, 0] = 1.0
        m[:, j] = mrs.velocity(x0, x0, unit, epsilon=s.epsilon, mu=s.viscosity)[:, 0]
    d = np.diff(np.eye(n), axis=0)
    rates, modes = np.linalg.eigh(s.stiffness * d @ m @ d.T)
    slowest, mode = rates[0], modes[:, 0]
    start = x0.copy()
    start[1:, 0] += np.cumsum(1e-4 * mode)
    t1 = 1.0 / slowest
    x1 = integrate.propagate(s, start, 0.0, t1, "rk4", t1 / 200)
    extension = np.diff(x1[:, 0]) - s.bond
    np.testing.assert_allclose(extension, 1e-4 * mode * math.exp(-1.0), rtol=1e-3, atol=1e-9)
    np.testing.assert_allclose(x1[:, 1:], 0.0, atol=1e-15)  # stays on the line


def test_uniformly_stretched_chain_returns_to_its_rest_length():
    s = ChainSystem(n_beads=10, stretch=1.3, stiffness=5.0)
    x = integrate.propagate(s, s.initial_state(), 0.0, 40.0, "rk2", 0.02)
    assert s.monitor(s.initial_state()) == pytest.approx(0.3)
    assert s.monitor(x) < 1e-3 * s.monitor(s.initial_state())
    np.testing.assert_allclose(x.mean(axis=0), 0.0, atol=1e-12)  # no net force: centre stays


def test_stiff_chain_tumbles_in_shear_flow_along_jefferys_orbit():
    """A straight chain of point forces is an infinitely thin rod: Jeffery's orbit with B = 1,
    dφ/dt = -γ̇ sin²φ, i.e. cot φ(t) = cot φ0 + γ̇ t. Started tilted against the flow (φ0 = π -
    0.3) it turns end over end through the vertical to φ = 0.3."""
    g, phi0 = 0.2, math.pi - 0.3
    s = ChainSystem(n_beads=6, stiffness=100.0, bending=20.0, epsilon=0.2, shear_rate=g,
                    tilt=phi0)
    x, t = s.initial_state(), 0.0
    period = 2.0 / math.tan(0.3) / g
    for _ in range(5):
        x = integrate.propagate(s, x, t, t + period / 5, "rk2", 0.01)
        t += period / 5
        end_to_end = x[-1] - x[0]
        phi = math.atan2(end_to_end[2], end_to_end[0]) % math.pi
        assert phi == pytest.approx(math.atan2(1.0, 1.0 / math.tan(phi0) + g * t), abs=2e-3)
    assert phi == pytest.approx(0.3, abs=2e-3)  # turned by π - 0.6 through the vertical
    assert s.monitor(x) < 0.01  # and stayed straight and unstretched


def sedimenting(n: int, direction: np.ndarray, epsilon: float = 0.1):
    s = ChainSystem(n_beads=n, epsilon=epsilon, bending=0.0,
                    load=tuple(float(v) for v in direction))
    return s, s.rates(0.0, s.initial_state()).mean(axis=0)


@pytest.mark.parametrize("axis", [0, 2], ids=["parallel", "perpendicular"])
def test_drag_of_a_straight_chain_is_the_kirkwood_riseman_sum(axis):
    """Every bead a Stokes sphere of the blob's radius a = 2ε/3 (self mobility 1/(4πμ ε)) and the
    Oseen tensor between beads: U = F [1/(4πμ ε) + (1/N) Σ_{i≠j} (1 + cos²)/(8πμ r_ij)]."""
    n = 16
    direction = np.eye(3)[axis]
    s, u = sedimenting(n, direction)
    r = np.abs(np.subtract.outer(np.arange(n), np.arange(n))) * s.bond
    pair = (2.0 if axis == 0 else 1.0) / (8 * math.pi * s.viscosity * r[r > 0])
    estimate = 1.0 / (4 * math.pi * s.viscosity * s.epsilon) + pair.sum() / n
    assert u[axis] == pytest.approx(estimate, rel=5e-3)
    np.testing.assert_allclose(np.delete(u, axis), 0.0, atol=1e-14)


def test_long_chains_drag_like_slender_bodies():
    """Slender-body theory (Batchelor 1970): a rod of length L pulled by F_tot moves with
    U_perp = F_tot (ln(L/a) + c_perp) / (4πμ L) across and U_par = F_tot (ln(L/a) + c_par) /
    (2πμ L) along its axis, so the coefficient of ln L is 1 in both (their drag ratio tends to 2).
    The slopes are fitted between chains of 64, 256 and 1024 beads (ε = b/2)."""
    points = []
    for n in (64, 256, 1024):
        length = n - 1.0
        _, parallel = sedimenting(n, np.array([1.0, 0.0, 0.0]), epsilon=0.5)
        _, perpendicular = sedimenting(n, np.array([0.0, 0.0, 1.0]), epsilon=0.5)
        points.append((math.log(length), 2 * math.pi * length * parallel[0] / n,
                       4 * math.pi * length * perpendicular[2] / n))  # F = 1 per bead: F_tot = n
    (l0, a0, b0), (_, _, _), (l2, a2, b2) = points
    assert (a2 - a0) / (l2 - l0) == pytest.approx(1.0, abs=0.03)
    assert (b2 - b0) / (l2 - l0) == pytest.approx(1.0, abs=0.03)
    slopes = [((p[1] - q[1]) / (p[0] - q[0])) for q, p in itertools.pairwise(points)]
    assert abs(slopes[1] - 1.0) < abs(slopes[0] - 1.0)  # closer to 1 the longer the chain


CHAIN_TOML = """\
title = "a stretched chain relaxing in shear flow"

[model]
kind = "chain"
n_beads = 10
stiffness = 20.0
bending = 2.0
shear_rate = 1.0
stretch = 1.2
tilt = 0.4

[time]
t1 = 0.4

[fine]
scheme = "rk2"
dt = 0.002

[coarse]
scheme = "euler"
dt = 0.02
lagrange = {{ {lagrange} }}
richardson = {richardson}

[parareal]
n_slices = 4
tol = 1e-9
max_iterations = 4

[execution]
executor = "serial"
allow_oversubscribe = true

[output]
formats = ["png"]
"""


@pytest.mark.parametrize(
    ("lagrange", "richardson"),
    [("stiffness = [16.0, 18.0]", "{ m = 0 }"), ("", "{ m = 1, r = 0.5 }")],
    ids=["lagrange", "richardson"],
)
def test_a_chain_runs_from_a_config_through_parareal(tmp_path, lagrange, richardson):
    cfg, resolved = config.loads(CHAIN_TOML.format(lagrange=lagrange, richardson=richardson))
    assert resolved.theta0 == {"epsilon": 0.25, "viscosity": 1.0, "stiffness": 20.0,
                               "bending": 2.0}
    summary = runner.execute(cfg, resolved, tmp_path)
    errors = summary["errors"]
    assert errors[-1] < 1e-9 < errors[0] and errors == sorted(errors, reverse=True)
    data = io.read_trajectory(tmp_path / "trajectory.h5")
    body = data["bodies"]["chain_0"]
    assert body["kind"] == "chain" and body["positions"].shape == (5, 10, 3)
    assert (tmp_path / "structure.png").exists()
    assert 'TopologyType="Polyline"' in (tmp_path / "trajectory.xdmf").read_text()


def test_chain_parameters_extrapolate_like_any_other():
    s = ChainSystem(n_beads=6, stiffness=20.0, bending=2.0, shear_rate=1.0, stretch=1.1)
    coarse = parareal.extrapolated(s, "euler", 0.01, lagrange={"bending": [1.6, 1.8]},
                                   richardson={"m": 1, "r": 0.5})
    fine = integrate.Propagator(s, "rk4", 0.001)
    x0 = s.initial_state()
    err_plain = np.abs(integrate.propagate(s, x0, 0.0, 0.1, "euler", 0.01)
                       - fine(0.0, 0.1, x0)).max()
    err_extrapolated = np.abs(coarse(0.0, 0.1, x0) - fine(0.0, 0.1, x0)).max()
    assert err_extrapolated < err_plain


def test_a_chain_in_a_blocked_fluid_moves_exactly_as_in_the_plain_one():
    """The fluid is a value: the process-block implementation gives the same bits (Remark 1)."""
    from parastokes import parallel
    from parastokes.parallel import spatial

    s = ChainSystem(n_beads=9, stiffness=20.0, bending=2.0, shear_rate=1.0, stretch=1.1,
                    wall=True, height=2.0, tilt=0.2)
    x0 = s.initial_state()
    with parallel.make_executor("serial") as ex:
        blocked = spatial.fine_solver(s, "rk2", 0.002, executor=ex, n_blocks=3)
        np.testing.assert_array_equal(blocked(0.0, 0.02, x0),
                                      integrate.propagate(s, x0, 0.0, 0.02, "rk2", 0.002))
