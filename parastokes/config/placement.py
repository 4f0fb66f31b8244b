"""Where the bodies of a suspension go (``[[suspensions]]``, :mod:`.suspension`): centres on a
lattice, at random without overlap in a box or a sphere, or read from a file, and orientations.

Every function here is pure geometry on numbers (no body is built) and raises
:class:`PlacementError` naming the key of the ``[[suspensions]]`` table that has to change.

Random placement is random sequential addition: uniform candidate centres in the region (each
body's bounding sphere inside it), a candidate kept when it is at least ``distance`` from every
centre kept so far (a grid of cells of that size finds the neighbours), until ``count`` are kept
or :func:`tries_allowed` candidates have been drawn. Packing spheres this way jams near a volume
fraction of 0.38 (Torquato, Uche & Stillinger, Phys. Rev. E 74, 061308 (2006)): asking for more
ends with the effort spent (:mod:`.suspension` names the key). A count whose exclusion spheres
(diameter ``distance``) would fill more than :data:`RANDOM_CLOSE_PACKING` of the region
(:func:`packing`) is refused at once, before any candidate is drawn: no random packing is denser.
"""

from __future__ import annotations

import io
import itertools
import math
import warnings
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ..core.files import InputFileError, read_input

__all__ = [
    "RANDOM_CLOSE_PACKING",
    "PlacementError",
    "holds_one",
    "lattice",
    "matrices",
    "packing",
    "random_centers",
    "random_quaternions",
    "read_poses",
    "region_volume",
    "tries_allowed",
]

class PlacementError(ValueError):
    """A suspension that cannot be placed: ``key`` (a key of its table) and what to change."""

    def __init__(self, key: str, message: str) -> None:
        super().__init__(message)
        self.key = key


def lattice(counts: list[int], spacing: list[float], center: list[float]) -> np.ndarray:
    """The centres (nx ny nz, 3) of a lattice of ``counts`` bodies along x, y, z, ``spacing``
    apart, centred on ``center``; x varies slowest, z fastest."""
    axes = [(np.arange(n) - 0.5 * (n - 1)) * d + c
            for n, d, c in zip(counts, spacing, center, strict=True)]
    return np.array(list(itertools.product(*axes)), dtype=float).reshape(-1, 3)


def region_volume(region: str, size: list[float] | None, radius: float | None) -> float:
    """The volume of a ``"box"`` of edges ``size`` or a ``"sphere"`` of ``radius``."""
    if region == "sphere":
        assert radius is not None
        return 4.0 / 3.0 * math.pi * radius**3
    assert size is not None
    return float(np.prod(size))


#: Random close packing of equal spheres, the densest random packing (about 0.64: Scott &
#: Kilgour, J. Phys. D 2, 863 (1969)); random sequential addition jams well below, near 0.38, and
#: the placement here reaches 0.31-0.32 within its tries (measured: docs/validation.md, "A
#: suspension refused before it is built").
RANDOM_CLOSE_PACKING = 0.64


def packing(count: int, region: str, size: list[float] | None, radius: float | None,
            body_radius: float, distance: float) -> float:
    """The volume fraction that ``count`` spheres of diameter ``distance`` (the distance kept
    between centres) would fill of the region they lie in: the region (box of edges ``size`` or
    sphere of ``radius``) whose centres stay ``body_radius`` inside it, grown by half the
    ``distance``; at most 1 for any placement (the spheres are disjoint)."""
    grow = distance - 2.0 * body_radius  # (the region shrunk by the radius, grown by d/2)
    if region == "sphere":
        assert radius is not None
        volume = 4.0 / 3.0 * math.pi * (radius + 0.5 * grow) ** 3
    else:
        assert size is not None
        volume = float(np.prod([edge + grow for edge in size]))
    return count * math.pi / 6.0 * distance**3 / volume


def tries_allowed(count: int) -> int:
    """How many candidate centres random placement draws at most for ``count`` bodies."""
    return 1000 + 200 * count


def _candidates(rng: np.random.Generator, n: int, region: str, center: np.ndarray,
                half: np.ndarray) -> np.ndarray:
    """``n`` uniform points in the box of half edges ``half`` or the ball of radius ``half[0]``
    about ``center``."""
    if region == "box":
        return center + half * (2.0 * rng.random((n, 3)) - 1.0)
    direction = rng.normal(size=(n, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    return center + direction * (half[0] * rng.random((n, 1)) ** (1.0 / 3.0))


def holds_one(region: str, size: list[float] | None, radius: float | None,
              body_radius: float) -> list[float]:
    """The region's extent (``[radius]`` or ``size``); PlacementError naming its key when it is
    too small for one body of bounding radius ``body_radius``."""
    extent = [float(radius or 0.0)] if region == "sphere" else list(size or [])
    key = "radius" if region == "sphere" else "size"
    if min(extent) <= body_radius:
        raise PlacementError(key, f"the {region} ({key} {_numbers(extent)}) is too small for "
                                  f"one body of bounding radius {body_radius:.4g}; enlarge it")
    return extent


def random_centers(count: int, region: str, center: list[float], size: list[float] | None,
                   radius: float | None, body_radius: float, distance: float,
                   rng: np.random.Generator) -> tuple[np.ndarray, int]:
    """Up to ``count`` centres (n, 3) in the region (box of edges ``size`` or sphere of
    ``radius`` about ``center``) whose bodies (bounding spheres of ``body_radius``) lie inside
    it, pairwise at least ``distance`` apart (random sequential addition, see the module), and
    the number of candidates drawn: fewer than ``count`` when :func:`tries_allowed` did not
    suffice."""
    extent = holds_one(region, size, radius, body_radius)
    half = np.array(extent, dtype=float) / (1.0 if region == "sphere" else 2.0) - body_radius
    mid = np.asarray(center, dtype=float)
    cells: dict[tuple[int, ...], list[int]] = {}
    kept = np.empty((count, 3))
    n, drawn, limit = 0, 0, tries_allowed(count)
    d2 = distance * distance
    while n < count and drawn < limit:
        batch = _candidates(rng, min(256, limit - drawn), region, mid, half)
        drawn += len(batch)
        for point in batch:
            cell = tuple(int(v) for v in np.floor(point / distance))
            near = [j for offset in itertools.product((-1, 0, 1), repeat=3)
                    for j in cells.get(tuple(c + o for c, o in zip(cell, offset, strict=True)),
                                       ())]
            if near and np.min(np.sum((kept[near] - point) ** 2, axis=1)) < d2:
                continue
            kept[n] = point
            cells.setdefault(cell, []).append(n)
            n += 1
            if n == count:
                break
    return kept[:n], drawn


def random_quaternions(count: int, rng: np.random.Generator) -> np.ndarray:
    """``count`` unit quaternions (w, x, y, z) of uniformly random rotations."""
    xyzw = Rotation.random(count, random_state=rng).as_quat()
    return np.ascontiguousarray(np.roll(np.atleast_2d(xyzw), 1, axis=1))


def matrices(quaternions: np.ndarray) -> np.ndarray:
    """The rotation matrices (n, 3, 3) of unit quaternions (n, 4) given as (w, x, y, z)."""
    return Rotation.from_quat(np.roll(quaternions, -1, axis=1)).as_matrix().reshape(-1, 3, 3)


def _numbers(values: list[float]) -> str:
    return "[" + ", ".join(f"{v:g}" for v in values) + "]" if len(values) > 1 else f"{values[0]:g}"


def read_poses(path: Path) -> np.ndarray:
    """The poses of ``path``: (n, 3) centres or (n, 7) centres and quaternions (w, x, y, z),
    normalized; a ``.npy`` array or a text file (spaces or commas, ``#`` comments), a regular
    file of at most 64 MiB (:func:`parastokes.core.files.read_input`: a million bodies of seven
    numbers fit)."""
    try:
        raw = read_input(path, "poses")
        if path.suffix == ".npy":
            data = np.load(io.BytesIO(raw), allow_pickle=False)
        else:
            text = raw.decode("utf-8").replace(",", " ")
            with warnings.catch_warnings():  # a file without numbers: refused below, by shape
                warnings.simplefilter("ignore", UserWarning)
                data = np.loadtxt(text.splitlines(), ndmin=2)
    except InputFileError as error:
        raise PlacementError("file", str(error)) from None
    except (OSError, ValueError, UnicodeDecodeError) as error:
        raise PlacementError("file", f"cannot read {path}: {error}") from None
    data = np.asarray(data, dtype=float)
    if data.ndim != 2 or len(data) == 0 or data.shape[1] not in (3, 7):
        raise PlacementError("file", f"{path}: expected one body per line with 3 numbers (x y z) "
                                     f"or 7 (x y z qw qx qy qz), got an array of shape "
                                     f"{data.shape}")
    bad = np.flatnonzero(~np.isfinite(data).all(axis=1))
    if len(bad):
        raise PlacementError("file", f"{path}: pose {bad[0]} (counted from 0, as the bodies) "
                                     "holds a value that is not a finite number")
    if data.shape[1] == 7:
        norms = np.linalg.norm(data[:, 3:], axis=1)
        zero = np.flatnonzero(norms == 0.0)
        if len(zero):
            raise PlacementError("file", f"{path}: pose {zero[0]} (counted from 0): the "
                                         "quaternion is zero, no rotation; give a unit "
                                         "quaternion (1 0 0 0: none)")
        data[:, 3:] /= norms[:, None]
    return data
