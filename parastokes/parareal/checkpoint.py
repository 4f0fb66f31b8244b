"""The state of a Parareal run between iterations, and its atomic checkpoint file.

After iteration k, Algorithm 1 needs exactly: the iterate X_n^k (n = 0..N), the stored coarse
values G(T_n, T_{n-1}, X_{n-1}^k) reused by the next correction (eq. 11), and the history. These are
written to one ``.npz`` file through a temporary file and ``os.replace`` (atomic on POSIX,
:func:`parastokes.core.files.atomic_write`), so an interrupted write never leaves a damaged
checkpoint. Arrays and floats round-trip exactly, so a resumed run gives bit-identical results.

The checkpoint carries a fingerprint (:func:`fingerprint`): a digest of the problem (x0, t0, t1,
N, reference) plus whatever the caller names as determining the iterates (``identity``: the command
line passes the resolved model, time, fine, coarse and slice settings and the package version). A
checkpoint is resumed only by a run with the same fingerprint; otherwise :class:`CheckpointMismatch`
names every differing key.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..core.files import CorruptFileError, read_npz, write_npz
from .timings import Timings

__all__ = ["CheckpointMismatch", "Progress", "differences", "fingerprint", "load", "save"]

_FORMAT = 2

#: The fingerprint key of the digest of x0, t0, t1, n_slices and the reference.
PROBLEM = "problem"


@dataclass
class Progress:
    """Algorithm 1 after iteration ``iteration`` (0 = after the initial serial sweep eq. 9)."""

    iteration: int
    states: np.ndarray  # X_n^k, shape (N + 1, *x0.shape)
    coarse_values: np.ndarray  # G(T_n, T_{n-1}, X_{n-1}^k) at index n - 1, shape (N, *x0.shape)
    increments: list[float] = field(default_factory=list)
    errors: list[float] | None = None
    timings: Timings = field(default_factory=Timings)
    #: further arrays saved with it (the learned correction's training data, :mod:`.learned`)
    extra: dict[str, np.ndarray] = field(default_factory=dict)


class CheckpointMismatch(ValueError):
    """A checkpoint written by another problem; ``differences`` lists ``(key, saved, now)``."""

    def __init__(self, path: str | os.PathLike, found: list[tuple[str, Any, Any]]) -> None:
        self.path = Path(path)
        self.differences = found
        parts = [
            "the initial state, time interval, number of slices or serial reference"
            if key == PROBLEM
            else f"{key} ({saved!r} in the checkpoint, {now!r} now)"
            for key, saved, now in found
        ]
        super().__init__(
            f"checkpoint {path} belongs to another problem: {'; '.join(parts)} differ; "
            "remove it or choose another path"
        )


def fingerprint(
    x0: np.ndarray,
    t0: float,
    t1: float,
    n_slices: int,
    reference: np.ndarray | None,
    identity: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """What a checkpoint must match to be resumed: ``{"problem": digest of x0, t0, t1, n_slices
    and reference}`` plus the entries of ``identity`` (JSON values, e.g. flattened config keys)."""
    digest = hashlib.sha256(repr((x0.shape, float(t0), float(t1), int(n_slices))).encode())
    digest.update(np.ascontiguousarray(x0).tobytes())
    if reference is not None:
        digest.update(np.ascontiguousarray(reference).tobytes())
    out = json.loads(json.dumps(dict(identity or {})))  # as it will read back
    return {**out, PROBLEM: digest.hexdigest()}


def differences(saved: Mapping[str, Any], now: Mapping[str, Any]) -> list[tuple[str, Any, Any]]:
    """``(key, saved value, current value)`` for every key whose values differ (None: absent)."""
    keys = sorted(set(saved) | set(now))
    return [(k, saved.get(k), now.get(k)) for k in keys if saved.get(k) != now.get(k)]


def save(path: str | os.PathLike, progress: Progress, key: Mapping[str, Any]) -> None:
    """Write ``progress`` atomically to ``path`` (an ``.npz`` file), tagged with ``key``, with
    its ``extra`` arrays."""
    meta = {
        "format": _FORMAT,
        "key": dict(key),
        "iteration": progress.iteration,
        "increments": progress.increments,
        "errors": progress.errors,
        "timings": progress.timings.to_dict(),
    }
    write_npz(path, meta, states=progress.states, coarse_values=progress.coarse_values,
              **progress.extra)


def load(path: str | os.PathLike, key: Mapping[str, Any]) -> Progress | None:
    """Read a checkpoint written by :func:`save`; None when ``path`` does not exist.

    Raises :class:`CheckpointMismatch` (a ValueError naming the differing keys) when the file
    belongs to another problem, and :class:`~parastokes.core.files.CorruptFileError` when it is
    damaged, of another format or not a checkpoint.
    """
    path = Path(path)
    if not path.exists():
        return None
    meta, arrays = read_npz(path, required=("states", "coarse_values"))
    if meta.get("format") != _FORMAT or not isinstance(meta.get("key"), dict):
        raise CorruptFileError(
            path,
            "not a checkpoint of this version of parastokes",
            "remove it to start afresh, or resume with the version that wrote it",
        )
    found = differences(meta["key"], key)
    if found:
        raise CheckpointMismatch(path, found)
    try:
        return Progress(
            iteration=int(meta["iteration"]),
            states=arrays["states"],
            coarse_values=arrays["coarse_values"],
            increments=list(meta["increments"]),
            errors=meta["errors"],
            timings=Timings(**meta["timings"]),
            extra={name: value for name, value in arrays.items()
                   if name not in ("states", "coarse_values")},
        )
    except (KeyError, TypeError, ValueError) as error:
        raise CorruptFileError(path, f"an incomplete checkpoint ({error!r})") from None
