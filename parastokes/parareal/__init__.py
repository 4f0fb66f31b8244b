"""Parareal (Algorithm 1) with coarse solvers built by extrapolation (section 4 of the paper).

The engine works on any propagators ``P(t_start, t_end, x) -> x`` over numpy arrays; see
``docs/parareal.md``.
"""

from .algorithm import SCHEDULES, IterationReport, run, serial_solution, time_points
from .dmd import expansion as hodmd
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
    "hodmd",
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
]
