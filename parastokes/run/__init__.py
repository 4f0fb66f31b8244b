"""One run of a configuration: the serial fine solution, Parareal (Algorithm 1), or both, with all
outputs (summary.json, trajectory.h5 + .xdmf, figures) in one directory. Used by the CLI.

The directory is owned by the run (:mod:`parastokes.output.rundir`: a lock naming PID and host, no
silent overwrite, results written to ``DIR/.partial/`` and moved into place whole when the run has
completed). One module per concern:

- :mod:`.execution`: :func:`execute`, the run end to end;
- :mod:`.identity`: what determines a run (``--resume`` with any difference is refused);
- :mod:`.serial` and :mod:`.parareal`: the two solves, saved as they go so that ``--resume``
  continues them;
- :mod:`.frames`: which states become the trajectory's frames, and their writing;
- :mod:`.advice`: after a blow-up, the last good state saved and what to change;
- :mod:`.speedups`: eqs. 14-15 of the run; :mod:`.report`: progress reporting;
- :mod:`.layout`: the names of a run directory's files;
- :mod:`.session`: the executor started and warmed up (:mod:`.warmup`) for the run.
"""

from .execution import execute
from .identity import fine_identity, identity
from .layout import BLOWUP, CHECKPOINT, HISTORY, REFERENCE, SUMMARY, TRAJECTORY
from .report import Reporter, ReporterLike
from .speedups import speedup_table

__all__ = [
    "BLOWUP",
    "CHECKPOINT",
    "HISTORY",
    "REFERENCE",
    "SUMMARY",
    "TRAJECTORY",
    "Reporter",
    "ReporterLike",
    "execute",
    "fine_identity",
    "identity",
    "speedup_table",
]
