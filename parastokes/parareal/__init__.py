"""Parareal (Algorithm 1) with coarse solvers built by extrapolation (section 4 of the paper).

The engine works on any propagators ``P(t_start, t_end, x) -> x`` over numpy arrays; see
``docs/parareal.md``.
"""

from .algorithm import SCHEDULES, IterationReport, run, serial_solution, time_points
from .extrapolation import Extrapolated, extrapolated
from .metrics import relative_change
from .options import Checkpoint, Reporting, Stopping
from .result import PararealResult
from .schedule_model import Simulation, handover_latency, predict_schedules, simulate
from .slice_costs import SliceCosts, auxiliary_solvers, coarse_step_time, measure_slice_costs
from .speedup import (
    parareal_runtime,
    pipelined_runtime,
    predict,
    speedup,
    speedup_bound,
    speedup_pipelined,
    speedup_standard,
)
from .timings import Timings
from .transfer import OnCoarseGrid, Transfer
from .weights import lagrange_weights, richardson_weights, step_weights

__all__ = [
    "SCHEDULES",
    "Checkpoint",
    "Extrapolated",
    "IterationReport",
    "OnCoarseGrid",
    "PararealResult",
    "Reporting",
    "Simulation",
    "SliceCosts",
    "Stopping",
    "Timings",
    "Transfer",
    "auxiliary_solvers",
    "coarse_step_time",
    "extrapolated",
    "handover_latency",
    "lagrange_weights",
    "measure_slice_costs",
    "parareal_runtime",
    "pipelined_runtime",
    "predict",
    "predict_schedules",
    "relative_change",
    "richardson_weights",
    "run",
    "serial_solution",
    "simulate",
    "speedup",
    "speedup_bound",
    "speedup_pipelined",
    "speedup_standard",
    "step_weights",
    "time_points",
    "tune",
]


def __getattr__(name: str):
    """``tune`` (:func:`parastokes.tuning.tune`) and ``hodmd``
    (:func:`parastokes.coarse.hodmd.dmd.expansion`), imported on first use: the tuner and
    HODMD-Parareal build on this package."""
    if name == "tune":
        from ..tuning.search import tune

        return tune
    if name == "hodmd":
        from ..coarse.hodmd.dmd import expansion

        return expansion
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
