"""Access to numba's CUDA target: real GPU or numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``).

``numba.cuda`` is imported only when GPU code is first used, so that ``import parastokes`` never
needs it. The simulator runs the same kernels in Python threads on the CPU (slow: for tests on
tiny sizes, as CI does); it must be chosen before ``numba.cuda`` is first imported.
"""

from __future__ import annotations

import os
from types import ModuleType

__all__ = ["INSTALL_HINT", "NO_DEVICE", "available", "cuda", "missing", "require", "simulated"]

INSTALL_HINT = 'pip install "parastokes[gpu]"'


def cuda() -> ModuleType:
    """The ``numba.cuda`` module (ImportError naming the ``gpu`` extra when it is missing)."""
    try:
        from numba import cuda as module
    except ImportError as exc:  # pragma: no cover - numba without a CUDA target
        raise ImportError(
            f"the GPU backend needs numba's CUDA target: {INSTALL_HINT} (numba-cuda)"
        ) from exc
    return module


def simulated() -> bool:
    """Whether the kernels run on numba-cuda's CPU simulator (``NUMBA_ENABLE_CUDASIM=1``)."""
    from numba import config

    return bool(config.ENABLE_CUDASIM) or os.environ.get("NUMBA_ENABLE_CUDASIM") == "1"


def available() -> bool:
    """Whether GPU kernels can run here: a CUDA GPU with its driver, or the simulator."""
    try:
        return bool(cuda().is_available())
    except Exception:
        return False


#: Why no GPU kernel can run where numba's CUDA target finds no device.
NO_DEVICE = (
    "no CUDA GPU is available (numba.cuda.is_available() is False): check the NVIDIA "
    f"driver and {INSTALL_HINT}; to test without a GPU, set NUMBA_ENABLE_CUDASIM=1 "
    "before starting Python (numba-cuda's simulator: slow, for tiny problems only)"
)


def missing() -> str | None:
    """Why GPU kernels cannot run here (numba's CUDA target not installed, or no device and no
    simulator), or None when they can (a GPU, or the simulator chosen, as the tests do).
    ``parastokes check`` asks this before a run would start its GPU executor."""
    try:
        cuda()
    except ImportError as error:
        return str(error)
    return None if available() else NO_DEVICE


def require() -> ModuleType:
    """``numba.cuda``, or a RuntimeError saying why no GPU kernel can run here."""
    module = cuda()
    if not available():
        raise RuntimeError(NO_DEVICE)
    return module
