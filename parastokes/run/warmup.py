"""A worker warm-up that can be unpickled without importing numba.

A process or MPI worker unpickles its warm-up before it sets its thread limits
(``parallel.worker.configure_worker`` exports ``NUMBA_NUM_THREADS``); a warm-up holding a system
would import numba first, with the default thread count, and numba then refuses to compile
("Cannot set NUMBA_NUM_THREADS to a different value once the threads have been launched") when its
cache is cold, e.g. on a fresh checkout. This module imports only the standard library, and the
system is unpickled when the warm-up runs, after the limits are set.
"""

from __future__ import annotations

import pickle
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # numpy is not imported here (see above)
    from ..core.contracts import System

__all__ = ["WarmUp"]


class WarmUp:
    """Take one tiny step with ``integrate.run`` (the system's compiled loop, if it has one) and
    evaluate ``system.rates`` once, so that a worker loads (or compiles) what its solvers call
    before timing starts."""

    def __init__(self, system: System) -> None:
        self.system = pickle.dumps(system)

    def __call__(self) -> None:
        from ..integrate import BlowUpError, run  # numba is imported only now (thread limits)

        system = pickle.loads(self.system)
        x = system.initial_state()
        system.rates(0.0, x)
        try:
            run(system, x, 0.0, 1e-12, "euler", 1e-12)
        except BlowUpError:  # the run's own solve meets it, and names the solver and slice
            pass
