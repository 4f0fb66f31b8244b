"""Parareal on rigid and prescribed-motion bodies converges to the serial fine solution: a
bacterium near the wall, and a scene of a rigid sphere beside a rod swimmer (one coupled solve per
evaluation). The process pool gives the serial executor's iterates bit for bit, and the
pipelined schedule converges to the same solution."""

from __future__ import annotations

import math

import numpy as np
import pytest

from parastokes import integrate, models, parallel, parareal
from parastokes.kinds.rigid import Bacterium, Helix, RigidBody, Sphere, Spheroid
from parastokes.scene import Scene

N_SLICES = 4


def bacterium():
    shape = Bacterium(Spheroid(1.0, 0.5, 40), Helix(0.25, 2.0, 1.5, 24), 0.25, 2 * math.pi * 10)
    return RigidBody(shape=shape, epsilon=0.2, viscosity=1e-3, wall=True,
                     position=(0.0, 0.0, 1.2), orientation=(0.995, 0.0, 0.0998, 0.0))


def sphere_and_rod():
    rod = models.rod_swimmer(1, 31, 1.0, length=6.0, wavelength=6.0)
    sphere = RigidBody(shape=Sphere(1.0, 40), epsilon=0.35, viscosity=rod.viscosity, wall=True,
                       position=(3.0, 2.5, 12.0), force=(0.0, 0.0, -3.8e-4))
    return Scene((rod, sphere), viscosity=rod.viscosity, wall=True)


CASES = {
    "bacterium": (bacterium, 0.02, 1e-3, {"epsilon": [0.24, 0.26]}),
    "scene": (sphere_and_rod, 1e-4, 1e-6, {"rod.epsilon": [1.12, 1.13]}),
}


def solve(name, executor=None, schedule="standard"):
    make, t1, dt, nodes = CASES[name]
    system = make()
    x0 = system.initial_state()
    fine = integrate.Propagator(system, "rk2", dt)
    coarse = parareal.extrapolated(system, "euler", 5 * dt, lagrange=nodes)
    reference = parareal.serial_solution(fine, x0, 0.0, t1, N_SLICES)
    result = parareal.run(fine, coarse, x0, 0.0, t1, N_SLICES, tol=0.0,
                          max_iterations=N_SLICES, reference=reference,
                          positions=system.positions, project=system.project,
                          executor=executor, schedule=schedule)
    return result, reference


@pytest.fixture(scope="module", params=sorted(CASES))
def serial(request):
    return request.param, solve(request.param)


def test_parareal_converges_to_the_serial_fine_solution(serial):
    _, (result, reference) = serial
    errors = np.asarray(result.errors)
    assert errors[0] > 1e-9  # the coarse solver is not the fine one
    assert np.all(np.diff(errors) < 0) or errors[-1] < 1e-13
    assert errors[-1] < 1e-12  # k = N: the serial fine solution, to round-off
    np.testing.assert_allclose(result.states[-1], reference[-1], atol=1e-11)


def test_processes_equal_serial_bit_for_bit(serial):
    name, (result, _) = serial
    with parallel.make_executor("processes", 2) as executor:
        pooled, _ = solve(name, executor)
    for a, b in zip(pooled.states, result.states, strict=True):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(pooled.increments, result.increments)


def test_pipelined_schedule_converges_too(serial):
    name, _ = serial
    if name != "bacterium":
        pytest.skip("one case suffices: the schedule does not depend on the body")
    with parallel.make_executor("processes", 2) as executor:
        pipelined, _ = solve(name, executor, schedule="pipelined")
    assert pipelined.errors[-1] < 1e-12
