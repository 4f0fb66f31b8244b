"""Shared by the GPU tests: run them on numba-cuda's simulator (CI has no GPU), and tiny systems.

The simulator is chosen here, before ``numba.cuda`` is first imported, unless the environment sets
``PARASTOKES_GPU_TESTS=device`` (then the tests run on the machine's GPU). It runs every CUDA
thread in Python: the systems below have a few points and the runs a few steps. Its scheduler polls
its threads in a loop that holds the GIL for Python's whole switch interval (5 ms) at a time; the
fixture :func:`fast_simulator` (used by every GPU test module) shortens that interval during the
tests, which makes them about 4x faster.
"""

import os
import sys
from collections.abc import Iterator

import numba
import pytest

from parastokes import models

if os.environ.get("PARASTOKES_GPU_TESTS") != "device" and "numba.cuda" not in sys.modules:
    os.environ["NUMBA_ENABLE_CUDASIM"] = "1"
    numba.config.reload_config()

cuda = pytest.importorskip("numba.cuda", reason="numba's CUDA target is not installed")
if not cuda.is_available():
    pytest.skip("no CUDA GPU and the simulator was not chosen in time", allow_module_level=True)

gpu = pytest.importorskip("parastokes.gpu")


@pytest.fixture(autouse=True)
def fast_simulator() -> Iterator[None]:
    """Python's GIL switch interval at 0.1 ms for the test (restored after it)."""
    previous = sys.getswitchinterval()
    sys.setswitchinterval(1e-4)
    yield
    sys.setswitchinterval(previous)


def small_rods(**kw):
    """Two swimmers of 4 points each above the wall, slow enough for steps of ~1e-2."""
    args = dict(n_rods=2, n_points=4, length=3.0, epsilon=0.8, wavelength=4.0, amplitude=0.2,
                frequency=20.0, viscosity=1.0, height=2.0, spacing=2.0)
    return models.rod_swimmer(**(args | kw))


def small_vesicle(**kw):
    """The 12-vertex icosphere in shear flow."""
    args = dict(subdivisions=0, shear_rate=1.0, stiffness=0.1, viscosity=0.1)
    return models.vesicle(**(args | kw))
