"""BLAS threads of the solves: at most the fluid's ``n_threads`` (docs/design.md, "BLAS threads").

The LU factorizations and triangular solves (scipy's OpenBLAS) start one thread per core by
default, while the compiled kernels (numba) and the worker processes already share those cores:
on a shared 2-core machine one 366² solve then took 0.28 s instead of 4 ms (docs/benchmarks.md,
"Rigid and prescribed-motion bodies"). :func:`blas_threads` limits every BLAS library loaded in
the process (threadpoolctl) to the thread count of the fluid's kernels for the duration of a
solve and restores it afterwards, so no ``OPENBLAS_NUM_THREADS`` is needed.

:data:`LAPACK` serializes the solves' calls of scipy's LAPACK across the threads of a process
(the hosted solves of the GPU executor, :mod:`parastokes.gpu.hosted`, run in threads): scipy's
OpenBLAS ``getrs`` (``scipy.linalg.lu_solve``) is not safe to call from several threads at once.
Measured here (scipy 1.17.1 with its OpenBLAS 0.3.30): four threads each solving with one LU
corrupt the heap within 200 calls ("malloc(): corrupted top size"), with ``OPENBLAS_NUM_THREADS=1``
too; numpy's matmul and ``linalg.solve`` in the same test do not.
"""

from __future__ import annotations

import contextlib
import functools
import threading
from collections.abc import Iterator

from threadpoolctl import ThreadpoolController

from ..mrs.velocity import thread_count

__all__ = ["LAPACK", "blas_threads"]

#: Held around every call of scipy's LAPACK in the solves (see the module).
LAPACK = threading.Lock()


@functools.cache
def _controller() -> ThreadpoolController:
    """The BLAS libraries of this process, found once (numpy's and scipy's are loaded when
    :mod:`parastokes.mobility` is imported; finding them again costs about a millisecond)."""
    return ThreadpoolController()


@contextlib.contextmanager
def blas_threads(n_threads: int | None) -> Iterator[int]:
    """Run the enclosed BLAS calls on at most ``n_threads`` threads (the kernels' count,
    :func:`parastokes.mrs.velocity.thread_count`: default 1); the libraries' own counts are
    restored on exit. Yields the limit."""
    n = thread_count(n_threads)
    with _controller().limit(limits=n, user_api="blas"):
        yield n
