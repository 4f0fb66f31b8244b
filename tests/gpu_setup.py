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
import threading
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


def _serialize_simulator_shared_arrays() -> None:
    """Make the simulator's ``cuda.shared.array`` atomic across the threads of a block.

    numba-cuda's simulator (``FakeCUDAShared.array``) finds a block's shared array by the calling
    line, allocating it on first use with an unlocked look-up-then-store. When Python switches
    threads between the two, two threads of one block get different arrays and a reduction reads
    the wrong partial sums: with the short switch interval of :func:`fast_simulator` this failed
    about 1 run in 20 (tests/test_gpu_kernels.py, tests/test_gpu_stepping.py). The replacement
    below does the same look-up under a lock; the device, where the tests can also run, is not
    concerned.
    """
    import numpy as np
    from numba.core import types
    from numba.cuda.simulator import kernelapi
    from numba.np import numpy_support

    unlocked = kernelapi.FakeCUDAShared.array
    lock = threading.Lock()

    def array(self, shape, dtype, alignment=None):
        if shape == 0 or alignment is not None:  # dynamic shared memory; the error for alignment
            return unlocked(self, shape, dtype, alignment)
        if isinstance(dtype, types.Type):
            dtype = numpy_support.as_dtype(dtype)
        caller = sys._getframe(1)
        key = (caller.f_code.co_filename, caller.f_lineno)
        with lock:
            if key not in self._allocations:
                self._allocations[key] = np.empty(shape, dtype)
            return self._allocations[key]

    kernelapi.FakeCUDAShared.array = array


if os.environ.get("NUMBA_ENABLE_CUDASIM") == "1":
    _serialize_simulator_shared_arrays()


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
