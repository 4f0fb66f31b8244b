"""Files the package writes and reads back: atomic writes, and reads that name a damaged file.

Every file is written to a temporary name beside its destination, flushed to disk and renamed over
it (``os.replace``, atomic on POSIX), so a reader, or a run that is killed mid-write, sees either
the old complete file or the new complete one. A file that cannot be read back (truncated, not
written by parastokes, another format) raises :class:`CorruptFileError`, a ``ValueError`` whose
message names the file and what to do (the command line exits with status 2).
"""

from __future__ import annotations

import json
import os
import zipfile
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import IO, Any

import numpy as np

__all__ = ["CorruptFileError", "atomic_write", "read_npz", "write_npz", "write_text"]


class CorruptFileError(ValueError):
    """A file the package reads back is damaged or foreign; ``path`` names it."""

    def __init__(self, path: str | os.PathLike, problem: str, remedy: str = "") -> None:
        self.path = Path(path)
        remedy = remedy or "remove it (a run writes it anew) or point to the right file"
        super().__init__(f"{self.path}: {problem}; {remedy}")


def atomic_write(path: str | os.PathLike, write: Callable[[IO[bytes]], Any]) -> None:
    """Call ``write(handle)`` on a temporary file beside ``path``, then rename it to ``path``."""
    path = Path(path)
    tmp = path.with_name(f"{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "wb") as handle:
            write(handle)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_npz(path: str | os.PathLike, meta: Mapping[str, Any], **arrays: np.ndarray) -> None:
    """Write ``arrays`` and the JSON-ready ``meta`` to an ``.npz`` file atomically."""
    text = json.dumps(meta, allow_nan=True)
    # (numpy >= 2.1 stubs read **arrays as possibly its keyword allow_pickle; numpy < 2.1 would
    # store allow_pickle=... as one more array, so it is not passed)
    atomic_write(
        path,
        lambda handle: np.savez(handle, meta=np.array(text), **arrays),  # type: ignore[arg-type]
    )


def write_text(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    data = text.encode()
    atomic_write(path, lambda handle: handle.write(data))


def read_npz(
    path: str | os.PathLike, required: tuple[str, ...] = ()
) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Read a file written by :func:`write_npz`: ``(meta, arrays)``; the arrays ``required`` must
    be there. Raises :class:`CorruptFileError` naming the file when it cannot be read back."""
    try:
        with np.load(path, allow_pickle=False) as data:
            if not hasattr(data, "files") or "meta" not in data.files:
                raise CorruptFileError(path, "not a parastokes array file (no 'meta' record)")
            meta = json.loads(str(data["meta"]))
            missing = [name for name in required if name not in data.files]
            if not isinstance(meta, dict) or missing:
                raise CorruptFileError(path, f"not a parastokes array file (missing {missing})")
            return meta, {k: data[k] for k in data.files if k != "meta"}
    except CorruptFileError:
        raise
    except FileNotFoundError:
        raise
    except (OSError, EOFError, ValueError, KeyError, zipfile.BadZipFile) as error:
        # numpy reports a damaged or foreign file as any of these; its advice to load it "with
        # allow_pickle" does not apply (parastokes never writes pickles)
        reason = "not a NumPy array file" if "pickle" in str(error) else str(error)
        raise CorruptFileError(path, f"damaged or not written by parastokes ({reason})") from None
