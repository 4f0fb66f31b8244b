"""The ``parastokes`` command line (docs/tutorial.md).

::

    parastokes run CONFIG.toml --out DIR [--resume | --overwrite] [--set KEY=VALUE ...]
    parastokes demo --out DIR [--resume | --overwrite] [--set KEY=VALUE ...]
    parastokes plot DIR [DIR ...] [--out FIGDIR] [--formats png pdf]
    parastokes plot --benchmark FILE.json [--out FIGDIR] [--formats png pdf]
    parastokes check CONFIG.toml [CONFIG.toml ...] [--set KEY=VALUE ...]
    parastokes predict CONFIG.toml --cores N [N ...] [--workers W] [--ratio R | --measured DIR]
                       [--iterations K]
    parastokes tune CONFIG.toml --cores N --target ETA --out TUNED.toml [--budget SECONDS]
    parastokes flow RUN_DIR [--frame I | --time T | --average T0 T1] [--plane z=5 | --box ...]
    parastokes movie RUN_DIR [--out swim.mp4] [--flow]

Exit codes (:class:`ExitCode`): 0 success; 1 unexpected error (a bug: please report the traceback);
2 bad configuration or usage, or an output directory or file that cannot be used (in use by another
run, a finished run without ``--overwrite``, damaged, unwritable); 3 numerical blow-up (a step too
large for the problem, or bodies that touched: the message names the solver, time and step, and the
last good state is saved; also a stability monitor above its limit at the end with
``--monitor-fatal``, the results written); 4 worker or parallel failure (a worker died or raised;
rerun with ``--resume`` to continue from the last completed iteration and the solves completed
since); 130 interrupted (Ctrl-C), 143 terminated (SIGTERM: ``kill``, ``timeout``, Slurm's time
limit), 129 hung up (SIGHUP): in these three cases the workers are stopped, the checkpoint is
consistent and ``--resume`` continues.

An MPI launch of several processes without ``-m mpi4py.futures`` would run the whole problem once
per process: it is refused with the command line to use.

Progress bars (tqdm) are drawn only when stderr is a terminal, only by the manager (rank 0 of an
MPI launch) and never with ``--quiet``; ``--quiet`` also silences the tables (errors still go to
stderr).
"""

from .console import Console
from .exits import ExitCode, Terminated, exit_code, report
from .launch import shadowing_note
from .main import main
from .predict import estimated_gamma_ratio, measured_auxiliary_ratio
from .run import demo_text

__all__ = [
    "Console",
    "ExitCode",
    "Terminated",
    "demo_text",
    "estimated_gamma_ratio",
    "exit_code",
    "main",
    "measured_auxiliary_ratio",
    "report",
    "shadowing_note",
]
