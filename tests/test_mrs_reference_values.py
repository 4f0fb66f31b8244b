"""The eight reference values of ``shared/physics.md`` section 2, through both code paths.

One source, one target, μ = 1, ε = 0.25: the kernel times a force f or a torque n, in free space
and above the wall z = 0, linear (u) and angular (w) velocity. Each value is checked to 1e-9
through the public compiled entry :func:`parastokes.mrs.velocity` and through the numpy oracle
:func:`parastokes.mrs.reference.velocity`.
"""

import numpy as np
import pytest

from parastokes import mrs

X = np.array([[0.7, -0.3, 1.1]])
Y = np.array([[0.2, 0.4, 0.8]])
F = np.array([[1.0, -2.0, 0.5]])
N = np.array([[-0.3, 0.6, 1.2]])
EPS, MU = 0.25, 1.0

# (wall, source) -> (u, w), copied from the table of physics.md section 2.
TABLE = {
    (False, "f"): (
        (0.0934357322, -0.1578497598, 0.0515548169),
        (-0.0130366679, -0.0026073336, 0.0156440015),
    ),
    (True, "f"): (
        (0.0650315130, -0.1022173942, 0.0446434020),
        (-0.0090064760, -0.0002692412, 0.0143833906),
    ),
    (False, "n"): (
        (0.0481335590, 0.0325609370, -0.0042470787),
        (-0.0027362132, 0.0004758632, -0.0273621319),
    ),
    (True, "n"): (
        (0.0442846994, 0.0293148343, -0.0027627688),
        (-0.0011808942, -0.0028843123, -0.0329275613),
    ),
}


@pytest.mark.parametrize("path", [mrs.velocity, mrs.reference.velocity], ids=["compiled", "oracle"])
@pytest.mark.parametrize("source", ["f", "n"])
@pytest.mark.parametrize("wall", [False, True], ids=["free", "wall"])
def test_reference_value(path, source, wall):
    """u and w from f (or from n alone, with zero force) match the table to 1e-9."""
    forces, torques = (F, None) if source == "f" else (np.zeros((1, 3)), N)
    u, w = path(X, Y, forces, torques=torques, epsilon=EPS, mu=MU, wall=wall, angular=True)
    u_ref, w_ref = TABLE[(wall, source)]
    np.testing.assert_allclose(u[0], u_ref, rtol=0, atol=1e-9)
    np.testing.assert_allclose(w[0], w_ref, rtol=0, atol=1e-9)


@pytest.mark.parametrize("wall", [False, True], ids=["free", "wall"])
def test_force_and_torque_superpose(wall):
    """Force and torque together give the sum of the two table rows (one call, both sources)."""
    u, w = mrs.velocity(X, Y, F, torques=N, epsilon=EPS, mu=MU, wall=wall, angular=True)
    (uf, wf), (un, wn) = TABLE[(wall, "f")], TABLE[(wall, "n")]
    np.testing.assert_allclose(u[0], np.add(uf, un), rtol=0, atol=2e-9)
    np.testing.assert_allclose(w[0], np.add(wf, wn), rtol=0, atol=2e-9)


@pytest.mark.parametrize("mu", [1e-6, 0.5, 3.0])
def test_viscosity_divides(mu):
    """Velocities scale as 1/μ (the table is for μ = 1)."""
    u = mrs.velocity(X, Y, F, epsilon=EPS, mu=mu, wall=True)
    np.testing.assert_allclose(u[0] * mu, TABLE[(True, "f")][0], rtol=0, atol=1e-9)
