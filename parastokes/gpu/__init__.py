"""GPU backend (numba's CUDA target): batched kernels, batched solves and the executor that
batches Parareal's parallel work. Optional: ``pip install "parastokes[gpu]"``; without a GPU, set
``NUMBA_ENABLE_CUDASIM=1`` to run it on numba-cuda's simulator (tests, tiny sizes).

- :mod:`.kernels`: the velocity kernels for B configurations in one launch, per-member ε and μ;
- :mod:`.stepping`: B solves of one system kind advanced together, states on the device (the
  generic driver: each kind's device parts come from its own folder, found by exact type);
- :mod:`.scene`: a scene's device parts, composed of its bodies';
- :mod:`.batch`: which submitted calls form a batch;
- :mod:`.hosted`: the solves of systems without device parts (rigid bodies: GMRES), run on the
  host with their fluid products batched in GPU launches;
- :mod:`.executor`: :class:`GPUExecutor` (``parallel.make_executor("gpu")``);
- :func:`velocity`: the batched kernels on host arrays (for checks and benchmarks).

Importing this package imports ``numba.cuda``; ``import parastokes`` does not. See docs/parallel.md.
"""

from .device import available, simulated
from .executor import GPUExecutor
from .stepping import Launch
from .velocity import velocity

__all__ = ["GPUExecutor", "Launch", "available", "simulated", "velocity"]
