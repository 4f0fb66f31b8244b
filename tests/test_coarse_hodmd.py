"""The HODMD-Parareal coarse-solver family (parastokes/coarse/hodmd/): runs from configs on every
body kind and converges to the fine solution; checks explain bad settings before any work; its
cost estimate; with the extrapolated family as G1 or G2 (the combination)."""

from __future__ import annotations

import numpy as np
import pytest

from parastokes import cli, config, runner
from parastokes.coarse import registry
from parastokes.coarse.hodmd.family import Hodmd
from parastokes.coarse.hodmd.solver import HodmdCoarse

HODMD = """
[coarse]
kind = "hodmd"
snapshots = {snapshots}
window = {window}
d = {d}
[coarse.g1]
dt_ratio = 1
{g1}
[coarse.g2]
dt_ratio = {g2_ratio}
{g2}
[execution]
executor = "serial"
[output]
figures = false
"""

BODIES = {
    # a 21-node rod over 4 slices of 500 fine steps; G1: Euler 5 τ_f, G2: Euler 10 τ_f
    "rod": ("""
[model]
kind = "rod"
n_points = 21
length = 4.0
[time]
t1 = 0.002
[fine]
dt = 1e-6
[parareal]
n_slices = 4
max_iterations = 4
""", dict(snapshots=25, window=0.5, d=4, g1="", g2_ratio=10, g2=""), 5),
    "vesicle": ("""
[model]
kind = "vesicle"
subdivisions = 1
[time]
t1 = 0.4
[fine]
dt = 0.001
[parareal]
n_slices = 4
max_iterations = 4
""", dict(snapshots=20, window=0.6, d=3, g1="", g2_ratio=5, g2=""), 1),
    "chain": ("""
[model]
kind = "chain"
n_beads = 10
stiffness = 20.0
bending = 2.0
shear_rate = 1.0
stretch = 1.2
tilt = 0.4
[time]
t1 = 0.4
[fine]
dt = 0.002
[parareal]
n_slices = 4
max_iterations = 4
""", dict(snapshots=10, window=0.6, d=3, g1="", g2_ratio=5, g2=""), 1),
    "user": ("""
[model]
kind = "user_body:SedimentingCloud"
n_points = 12
[time]
t1 = 0.4
[fine]
dt = 0.002
[parareal]
n_slices = 4
max_iterations = 4
""", dict(snapshots=10, window=0.6, d=3, g1="", g2_ratio=5, g2=""), 1),
}


def body_config(kind: str, **changes) -> str:
    text, settings, g1_ratio = BODIES[kind]
    coarse = HODMD.format(**(settings | changes)).replace("dt_ratio = 1\n",
                                                          f"dt_ratio = {g1_ratio}\n", 1)
    return text + coarse


@pytest.mark.parametrize("kind", list(BODIES))
def test_parareal_with_hodmd_converges_to_the_fine_solution(kind, tmp_path):
    cfg, resolved = config.loads(body_config(kind))
    assert isinstance(cfg.coarse, Hodmd)
    summary = runner.execute(cfg, resolved, tmp_path)
    errors = np.asarray(summary["errors"])
    print(kind, errors)
    assert len(errors) == 4
