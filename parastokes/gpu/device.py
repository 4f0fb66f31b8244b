"""Access to numba's CUDA target: real GPU or numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``).

``numba.cuda`` is imported only when GPU code is first used, so that ``import parastokes`` never
needs it. The simulator runs the same kernels in Python threads on the CPU (slow: for tests on
tiny sizes, as CI does); it must be chosen before ``numba.cuda`` is first imported.
"""

from __future__ import annotations

import os
from types import ModuleType

__all__ = ["INSTALL_HINT", "available", "cuda", "require", "simulated"]

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


def require() -> ModuleType:
    """``numba.cuda``, or a RuntimeError saying why no GPU kernel can run here."""
    module = cuda()
    if not available():
        raise RuntimeError(
            "no CUDA GPU is available (numba.cuda.is_available() is False): check the NVIDIA "
            f"driver and {INSTALL_HINT}; to test without a GPU, set NUMBA_ENABLE_CUDASIM=1 "
            "before starting Python (numba-cuda's simulator: slow, for tiny problems only)"
        )
    return module
