"""A trajectory written as the runner writes it, for the tests of what a run's files hold."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np

from parastokes import config, integrate
from parastokes.output import trajectory as io


def write_frames(directory: Path, text: str, times: np.ndarray, dt: float) -> tuple:
    """The model of the configuration ``text`` moved by RK2 steps of ``dt`` from its initial
    state to each of ``times``, the states written to ``directory/trajectory.h5`` as run
    "serial" (with its rates, for the bodies that save their motion): (system, states)."""
    cfg, resolved = config.loads(text)
    system = cfg.model.build(1)
    states = [system.initial_state()]
    for t0, t1 in itertools.pairwise(times):
        states.append(integrate.propagate(system, states[-1], t0=t0, t1=t1, scheme="rk2",
                                          dt=dt))
    layout = cfg.model.layout(system, cfg.output.frames, None)
    with io.TrajectoryWriter(directory / "trajectory.h5", layout,
                             config=config.resolved_dict(cfg, resolved),
                             rates=system.rates) as writer:
        for t, x in zip(times, states, strict=True):
            writer.append("serial", t, x)
    return system, states
