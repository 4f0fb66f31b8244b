"""The solves of the iteration in progress, kept on disk so that a stopped run loses none of them.

The checkpoint (:mod:`.checkpoint`) holds Algorithm 1 after a completed iteration, but one
iteration of a long run can take hours (40 fine solves of a rod over T = 1/40 each). A
:class:`SolveMemo` keeps every fine solve (eq. 10) and coarse step (eqs. 9 and 11) of the iteration
in progress as it completes, one file per solve in a directory beside the checkpoint
(``checkpoint.npz`` -> ``checkpoint.solves/``). A resumed run takes a solve from the memo instead
of computing it when the run's fingerprint, the solve (kind, slice, iteration) and a digest of its
input (T_{n-1}, T_n and the state, bit for bit) all match, so it reaches the same iterates, to the
last bit, as a run that was never stopped. A kept coarse step also holds the steps its adaptive
auxiliary solvers took (``{accepted, rejected, switches}``, None on fixed steps), so the counts of a
resumed run (``Timings.coarse_steps``) are those of the session that computed the step, not
recomputed. The solves of an iteration are forgotten once its checkpoint is written, and all of
them when the run returns.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import re
import shutil
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..core.files import CorruptFileError, read_npz, write_npz

__all__ = ["SolveMemo", "memo_directory"]

logger = logging.getLogger(__name__)

#: The kinds of solve a memo holds.
KINDS = ("fine", "coarse")

#: A kept solve's file name (written by ``SolveMemo._file``).
_NAME = re.compile(rf"(?P<kind>{'|'.join(KINDS)})-k(?P<k>\d+)-n(?P<n>\d+)\.npz")


def memo_directory(checkpoint: str | os.PathLike) -> Path:
    """Where the memo of the checkpoint file ``checkpoint`` lives: its name with ``.solves``."""
    path = Path(checkpoint)
    return path.with_name(path.stem + ".solves")


class SolveMemo:
    """Solves of one Parareal run's iteration in progress, on disk (see the module docstring).

    ``key`` is the run's checkpoint fingerprint (:func:`.checkpoint.fingerprint`): a memo left by
    another problem never matches.
    """

    def __init__(self, directory: str | os.PathLike, key: Mapping[str, Any]) -> None:
        self.directory = Path(directory)
        self._key = json.dumps(dict(key), sort_keys=True).encode()

    def _file(self, kind: str, n: int, k: int) -> Path:
        if kind not in KINDS:
            raise ValueError(f"kind must be one of {KINDS}, got {kind!r}")
        return self.directory / f"{kind}-k{k}-n{n}.npz"

    def _digest(self, kind: str, n: int, k: int, t0: float, t1: float, x: np.ndarray) -> str:
        x = np.ascontiguousarray(x)
        digest = hashlib.sha256(self._key)
        digest.update(repr((kind, int(n), int(k), float(t0), float(t1), x.dtype.str)).encode())
        digest.update(repr(x.shape).encode())
        digest.update(x.tobytes())
        return digest.hexdigest()

    def get(
        self, kind: str, n: int, k: int, t0: float, t1: float, x: np.ndarray
    ) -> tuple[np.ndarray, float, dict[str, int] | None] | None:
        """The value, wall time and adaptive step counts (None when not counted) of the solve
        ``kind`` of slice n in iteration k from (t0, x) to t1, when the memo holds it for exactly
        this input; else None."""
        path = self._file(kind, n, k)
        if not path.exists():
            return None
        try:
            meta, arrays = read_npz(path, required=("value",))
        except CorruptFileError as error:  # written atomically, so only damage gets here
            logger.warning("parareal: ignoring a damaged saved solve (%s)", error)
            return None
        if meta.get("digest") != self._digest(kind, n, k, t0, t1, x):
            return None
        return arrays["value"], float(meta["seconds"]), meta.get("steps")

    def put(
        self,
        kind: str,
        n: int,
        k: int,
        t0: float,
        t1: float,
        x: np.ndarray,
        value: np.ndarray,
        seconds: float,
        steps: dict[str, int] | None = None,
    ) -> None:
        """Keep the solve's ``value`` (with its wall time ``seconds`` and the adaptive step
        counts ``steps`` of a coarse step), written atomically."""
        self.directory.mkdir(parents=True, exist_ok=True)
        meta = {"digest": self._digest(kind, n, k, t0, t1, x), "seconds": float(seconds),
                "steps": steps}
        write_npz(self._file(kind, n, k), meta, value=np.asarray(value))

    def count(self) -> int:
        """How many solves the memo holds."""
        return len(list(self.directory.glob("*.npz"))) if self.directory.is_dir() else 0

    def forget(self, through: int) -> None:
        """Forget the solves of iterations up to ``through`` (the checkpoint holds them now); the
        pipelined schedule may have kept some of later iterations already."""
        if not self.directory.is_dir():
            return
        for path in self.directory.glob("*.npz"):
            match = _NAME.fullmatch(path.name)
            if match is None or int(match["k"]) <= through:
                path.unlink(missing_ok=True)
        if not any(self.directory.iterdir()):
            self.directory.rmdir()

    def clear(self) -> None:
        """Forget every solve."""
        shutil.rmtree(self.directory, ignore_errors=True)
