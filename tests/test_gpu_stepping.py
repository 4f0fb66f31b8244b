"""Batched solves on the GPU (parastokes.gpu.stepping / .batch) against integrate.run on the CPU.

Each batch mixes members with their own Θ, start time, step and step count. Measured in the
simulator: max |GPU - CPU| = 1.1e-16 (rods) and 7e-18 (vesicle) for motions of 1e-4 to 3e-2,
monitors equal; the tolerance is 1e-12 of the motion.
"""

import numpy as np
import pytest
from gpu_setup import fast_simulator, gpu, small_rods, small_vesicle  # noqa: F401 (an autouse fixture)

from parastokes import integrate
from parastokes.gpu import batch as gpu_batch

pytestmark = pytest.mark.gpu


def _members(system, theta):
    """Three calls (propagator, (t0, t1, x)): Θ⁰; another Θ and start; another step count."""
    x0 = system.initial_state()
    if x0.shape[1] == 3:
        x0 = x0 * np.array([1.004, 1.0, 0.998])  # a stretched vesicle, so that the springs act
    other = system.with_params(**theta)
    return [
        (integrate.Propagator(system, "rk2", 1e-2), (0.0, 0.03, x0)),
        (integrate.Propagator(other, "rk2", 1e-2), (0.1, 0.12, x0)),
        (integrate.Propagator(system, "rk2", 2.5e-2), (0.0, 0.05, x0)),
    ]


def _compare(calls):
    assert all(gpu_batch.batch_key(fn, args) is not None for fn, args in calls)  # on the GPU
    outcomes = gpu_batch.run_calls([(fn, args, {}) for fn, args in calls])
    for (fn, args), (ok, value) in zip(calls, outcomes, strict=True):
        assert ok, value
        cpu = fn(*args)
        motion = np.abs(cpu - args[2]).max()
        assert motion > 1e-6
        assert np.abs(value - cpu).max() <= 1e-12 * motion


@pytest.mark.parametrize("scheme", ["euler", "rk2", "rk4"])
def test_rods_batch_matches_cpu(scheme):
    rods = small_rods()
    calls = [(integrate.Propagator(fn.system, scheme, fn.dt), args)
             for fn, args in _members(rods, {"bending": 1.3, "epsilon": 0.9, "viscosity": 1.5})]
    _compare(calls)


def test_vesicle_batch_matches_cpu():
    vesicle = small_vesicle()
    _compare(_members(vesicle, {"stiffness": 0.12, "epsilon": vesicle.epsilon * 1.1}))


def test_blow_up_fails_its_member_only_at_the_cpu_step():
    rods = small_rods()
    x0 = rods.initial_state()
    calm = integrate.Propagator(rods, "euler", 1e-2)
    wild = integrate.Propagator(rods.with_params(viscosity=1e-4), "euler", 1e-2)
    outcomes = gpu_batch.run_calls([(calm, (0.0, 0.05, x0), {}), (wild, (0.0, 0.05, x0), {})])
    assert outcomes[0][0]
    ok, error = outcomes[1]
    assert not ok and isinstance(error, integrate.BlowUpError)
    with pytest.raises(integrate.BlowUpError) as cpu:
        wild(0.0, 0.05, x0)
    assert (error.step, error.reason) == (cpu.value.step, cpu.value.reason)
    assert error.monitor == pytest.approx(cpu.value.monitor, rel=1e-12)
    assert np.abs(error.last_state - cpu.value.last_state).max() <= 1e-12


def test_other_calls_run_hosted_or_on_the_cpu():
    class Custom(type(small_rods())):
        pass

    custom = Custom(**{**small_rods().__dict__})
    x0 = custom.initial_state()
    calls = [(integrate.Propagator(custom, "rk2", 1e-2), (0.0, 0.02, x0), {}),
             (np.add, (1.0, 2.0), {}),
             (integrate.Propagator(small_rods(), "rk2", 1e-2), (0.0, 0.0, x0), {})]
    assert gpu_batch.batch_key(calls[0][0], calls[0][1]) is None  # a subclass may differ
    assert gpu_batch.hosted_call(*calls[0])  # its own code on the host, products on the GPU
    launches = []
    outcomes = gpu_batch.run_calls(calls, launches=launches)
    cpu = calls[0][0](0.0, 0.02, x0)
    assert np.abs(outcomes[0][1] - cpu).max() <= 1e-12 * np.abs(cpu - x0).max()
    assert launches == [1, 1, 1, 1]  # 2 RK2 steps of 2 stages, alone in its batch
    assert outcomes[1] == (True, 3.0)
    assert np.array_equal(outcomes[2][1], x0)  # no step: the projected start state


def test_gpu_available_in_these_tests():
    assert gpu.available()


@pytest.mark.parametrize("wall", [False, True])
def test_chain_batch_matches_cpu_from_its_own_device_parts(wall):
    """The chain (kinds/chain/device.py): springs, bending, load and shear; at the wall with the
    full kernel and the shear added there."""
    from parastokes.kinds.chain import ChainSystem

    chain = ChainSystem(n_beads=5, stiffness=20.0, bending=2.0, shear_rate=1.0, epsilon=0.3,
                        load=(0.0, 0.0, -0.5), wall=wall, height=2.0 if wall else 0.0, tilt=0.3,
                        stretch=1.05)
    _compare(_members(chain, {"stiffness": 25.0, "bending": 1.5, "epsilon": 0.35,
                              "viscosity": 1.2}))


def test_a_users_body_runs_from_its_own_device_parts():
    """tests/user_body.py registers tests/user_body_device.py (docs/extending.md)."""
    from user_body import SedimentingCloud

    cloud = SedimentingCloud(n_points=6, epsilon=0.3)
    _compare(_members(cloud, {"epsilon": 0.35, "viscosity": 1.2}))


def test_a_body_without_device_parts_is_named():
    from parastokes.gpu import stepping

    class Custom(type(small_rods())):
        pass

    custom = Custom(**{**small_rods().__dict__})
    with pytest.raises(stepping.NoDevicePartsError, match="Custom has no device parts"):
        stepping.solve(integrate.SCHEMES["rk2"],
                       [stepping.Member(custom, custom.initial_state(), 0.0, 1e-2, 1)], 1.0)


def test_a_scene_runs_batched_from_its_bodies_device_parts():
    """A rod and a chain above the wall in shear: one velocity kernel over both with ε per source,
    each body's parts on its rows; Θ of both bodies varied per member."""
    from parastokes.kinds.chain import ChainSystem
    from parastokes.scene import Scene

    rods = small_rods(n_rods=1)
    chain = ChainSystem(n_beads=4, stiffness=20.0, bending=2.0, epsilon=0.3, viscosity=1.0,
                        shear_rate=0.5, wall=True, height=4.0, tilt=0.2, stretch=1.05)
    scene = Scene((rods, chain), viscosity=1.0, wall=True, shear_rate=0.5)
    _compare(_members(scene, {"rod.bending": 1.3, "chain.epsilon": 0.35, "chain.stiffness": 25.0,
                              "viscosity": 1.2}))


def test_a_scene_with_a_body_without_device_parts_names_it():
    from user_body import SedimentingCloud

    from parastokes.gpu import stepping
    from parastokes.scene import Scene

    class Slow(SedimentingCloud):  # a subclass: its physics may differ, so no device parts
        angular = False

        def loads(self, t, state):
            return np.zeros_like(state), None

        def body_rates(self, u, w):
            return u

    scene = Scene((small_vesicle(viscosity=1.0, shear_rate=0.0), Slow(n_points=4)), viscosity=1.0)
    with pytest.raises(stepping.NoDevicePartsError, match="scene body 'slow': Slow has no device"):
        stepping.device_parts(scene)
