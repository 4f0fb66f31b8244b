"""The files of a run directory while a run is in progress and after it (names only).

- ``checkpoint.npz``: Parareal's checkpoint (removed at the end when
  ``parareal.checkpoint`` is false);
- ``reference.npz``: the serial fine solution at T_0..T_n and its wall time, written after
  every slice n (``--resume`` continues the serial run after the last saved slice, bit for
  bit);
- ``history.npz``: X^k at T_N and the elapsed wall time after every iteration;
- ``blowup.npz``: after a numerical blow-up, the last good state, its time and which solver
  failed;
- ``summary.json`` and ``trajectory.h5`` (+ ``.xdmf``): the results.
"""

from __future__ import annotations

CHECKPOINT = "checkpoint.npz"


REFERENCE = "reference.npz"


HISTORY = "history.npz"


BLOWUP = "blowup.npz"


SUMMARY = "summary.json"


TRAJECTORY = "trajectory.h5"
