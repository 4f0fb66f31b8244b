"""The state of a Parareal run between iterations, and its atomic checkpoint file.

After iteration k, Algorithm 1 needs exactly: the iterate X_n^k (n = 0..N), the stored coarse
values G(T_n, T_{n-1}, X_{n-1}^k) reused by the next correction (eq. 11), and the history. These are
written to one ``.npz`` file through a temporary file and ``os.replace`` (atomic on POSIX), so an
interrupted write never leaves a damaged checkpoint. Arrays and floats round-trip exactly, so a
resumed run gives bit-identical results.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .timings import Timings

__all__ = ["Progress", "fingerprint", "load", "save"]

_FORMAT = 1


@dataclass
class Progress:
    """Algorithm 1 after iteration ``iteration`` (0 = after the initial serial sweep eq. 9)."""

    iteration: int
    states: np.ndarray  # X_n^k, shape (N + 1, *x0.shape)
    coarse_values: np.ndarray  # G(T_n, T_{n-1}, X_{n-1}^k) at index n - 1, shape (N, *x0.shape)
    increments: list[float] = field(default_factory=list)
    errors: list[float] | None = None
    timings: Timings = field(default_factory=Timings)


def fingerprint(
    x0: np.ndarray, t0: float, t1: float, n_slices: int, reference: np.ndarray | None
) -> str:
    """A digest of the problem, so that a checkpoint is only resumed by the run that wrote it."""
    digest = hashlib.sha256(repr((x0.shape, float(t0), float(t1), int(n_slices))).encode())
    digest.update(np.ascontiguousarray(x0).tobytes())
    if reference is not None:
        digest.update(np.ascontiguousarray(reference).tobytes())
    return digest.hexdigest()


def save(path: str | os.PathLike, progress: Progress, key: str) -> None:
    """Write ``progress`` atomically to ``path`` (an ``.npz`` file), tagged with ``key``."""
    path = Path(path)
    meta = {
        "format": _FORMAT,
        "key": key,
        "iteration": progress.iteration,
        "increments": progress.increments,
        "errors": progress.errors,
        "timings": progress.timings.to_dict(),
    }
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as handle:
        np.savez(
            handle,
            states=progress.states,
            coarse_values=progress.coarse_values,
            meta=np.array(json.dumps(meta)),
        )
        handle.flush()
        os.fsync(handle.fileno())
    os.replace(tmp, path)


def load(path: str | os.PathLike, key: str) -> Progress | None:
    """Read a checkpoint written by :func:`save`; None when ``path`` does not exist.

    Raises ValueError when the file belongs to another problem (its key differs).
    """
    path = Path(path)
    if not path.exists():
        return None
    with np.load(path, allow_pickle=False) as data:
        meta = json.loads(str(data["meta"]))
        if meta.get("format") != _FORMAT or meta.get("key") != key:
            raise ValueError(
                f"checkpoint {path} belongs to another problem (x0, t0, t1, n_slices or reference "
                "differ) or another format; remove it or choose another path"
            )
        return Progress(
            iteration=meta["iteration"],
            states=data["states"],
            coarse_values=data["coarse_values"],
            increments=meta["increments"],
            errors=meta["errors"],
            timings=Timings(**meta["timings"]),
        )
