"""Surface point clouds of rigid bodies, in the body frame (docs/bodies.md, "Rigid bodies").

Every shape is a small frozen dataclass (it pickles in a few hundred bytes and is a cache key);
its points are computed on demand (:func:`body_points`, cached). The body frame's first axis
e1 = x is the body's axis (of a spheroid, a rod, a helix, a bacterium; a squirmer swims along
it); the body's reference point (its centre, where the external torque and Ω are taken) is the
origin.

- :class:`Sphere`: ``n_points`` on the sphere of ``radius`` (a Fibonacci spiral: any N, nearly
  uniform spacing h ≈ sqrt(4π a²/N));
- :class:`Spheroid`: the same points stretched to semi-axes (``axial``, ``radius``, ``radius``);
- :class:`Rod`: a straight tube along x, rings of points on its side and one on each end;
- :class:`Helix`: a slender helical filament along x, ``n_points`` on its centre line
  (radius, pitch, turns; right-handed for ``handedness`` = 1);
- :class:`PointCloud`: any user cloud, given as a tuple of points or loaded from a ``.npy`` /
  text file or a ``"module:function"`` that returns an (N, 3) array;
- :class:`Bacterium`: a head (sphere or spheroid) and a helical flagellum behind it on the
  axis, the flagellum turning about x at ``motor_rate`` relative to the head (its phase φ is a
  state column); the body frame is the head's. Its default is E. coli's: a left-handed
  flagellum turning counter-clockwise seen from behind (docs/bodies.md, "Bacterium: sign
  conventions").

A shape offers ``points(phase) -> (N, 3)``, ``moving(phase) -> (N, 3)`` (the surface velocity
relative to the body frame of its own parts, e.g. a rotating flagellum; zero for a rigid
shape) and ``phase_rate`` (dφ/dt, zero without a motor).
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any, Protocol

import numpy as np
from scipy.spatial import cKDTree

from ...core import plugins
from ...core.files import read_input

__all__ = [
    "Bacterium",
    "Helix",
    "PointCloud",
    "Rod",
    "Shape",
    "Sphere",
    "Spheroid",
    "body_points",
    "fibonacci_sphere",
    "spacing",
]

GOLDEN_ANGLE = math.pi * (3.0 - math.sqrt(5.0))


class Shape(Protocol):
    """What a rigid body needs of its shape."""

    @property
    def phase_rate(self) -> float: ...

    def points(self, phase: float = 0.0) -> np.ndarray: ...

    def moving(self, phase: float = 0.0) -> np.ndarray: ...

    def contains(self, points: np.ndarray) -> np.ndarray: ...


def _count(name: str, n: int, least: int) -> None:
    if isinstance(n, bool) or not isinstance(n, int) or n < least:
        raise ValueError(f"{name}: must be an integer >= {least}, got {n!r}")


def _positive(**values: float) -> None:
    for name, value in values.items():
        if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
            raise ValueError(f"{name}: must be a finite number > 0, got {value!r}")


def fibonacci_sphere(n: int) -> np.ndarray:
    """``n`` nearly evenly spaced points on the unit sphere (a golden-angle spiral), (n, 3)."""
    i = np.arange(n) + 0.5
    x = 1.0 - 2.0 * i / n
    r = np.sqrt(1.0 - x * x)
    angle = GOLDEN_ANGLE * np.arange(n)
    return np.stack([x, r * np.cos(angle), r * np.sin(angle)], axis=1)


class _Rigid:
    """A shape without moving parts."""

    phase_rate = 0.0

    def points(self, phase: float = 0.0) -> np.ndarray:
        return np.array(body_points(self))

    def moving(self, phase: float = 0.0) -> np.ndarray:
        return np.zeros((len(body_points(self)), 3))

    def contains(self, points: np.ndarray) -> np.ndarray:
        """Which body-frame ``points`` lie inside the body (none for an open shape)."""
        return np.zeros(len(points), dtype=bool)

    def _make(self) -> np.ndarray:
        raise NotImplementedError


@dataclass(frozen=True)
class Sphere(_Rigid):
    """``n_points`` on the sphere of ``radius`` about the origin."""

    radius: float = 1.0
    n_points: int = 642

    def __post_init__(self) -> None:
        _positive(radius=self.radius)
        _count("n_points", self.n_points, 4)

    def contains(self, points: np.ndarray) -> np.ndarray:
        return np.linalg.norm(points, axis=1) < self.radius

    def _make(self) -> np.ndarray:
        return self.radius * fibonacci_sphere(self.n_points)


@dataclass(frozen=True)
class Spheroid(_Rigid):
    """``n_points`` on the spheroid of semi-axes (``axial``, ``radius``, ``radius``): prolate for
    axial > radius, oblate for axial < radius."""

    axial: float = 2.0
    radius: float = 1.0
    n_points: int = 642

    def __post_init__(self) -> None:
        _positive(axial=self.axial, radius=self.radius)
        _count("n_points", self.n_points, 4)

    def contains(self, points: np.ndarray) -> np.ndarray:
        scaled = points / np.array([self.axial, self.radius, self.radius])
        return np.einsum("ij,ij->i", scaled, scaled) < 1.0

    def _make(self) -> np.ndarray:
        return fibonacci_sphere(self.n_points) * np.array([self.axial, self.radius, self.radius])


@dataclass(frozen=True)
class Rod(_Rigid):
    """A straight tube (a rod) of ``length`` and ``radius`` along x, centred: ``rings`` rings of
    ``around`` points on its side (each ring turned half a step from the last) and one point on
    each flat end."""

    length: float = 10.0
    radius: float = 0.5
    rings: int = 40
    around: int = 8

    def __post_init__(self) -> None:
        _positive(length=self.length, radius=self.radius)
        _count("rings", self.rings, 2)
        _count("around", self.around, 3)

    @property
    def n_points(self) -> int:
        return self.rings * self.around + 2

    def contains(self, points: np.ndarray) -> np.ndarray:
        return ((np.abs(points[:, 0]) < 0.5 * self.length)
                & (points[:, 1] ** 2 + points[:, 2] ** 2 < self.radius**2))

    def _make(self) -> np.ndarray:
        x = np.linspace(-0.5 * self.length, 0.5 * self.length, self.rings)
        step = 2.0 * math.pi / self.around
        stagger = 0.5 * (np.arange(self.rings) % 2)[:, None]
        angle = step * (np.arange(self.around)[None, :] + stagger)
        side = np.stack([np.broadcast_to(x[:, None], angle.shape), self.radius * np.cos(angle),
                         self.radius * np.sin(angle)], axis=-1).reshape(-1, 3)
        ends = np.array([[x[0], 0.0, 0.0], [x[-1], 0.0, 0.0]])
        return np.concatenate([side, ends])


def helix_line(radius: float, pitch: float, turns: float, n: int, handedness: int,
               start: float) -> np.ndarray:
    """``n`` points evenly spaced in arc length on the helix (s, R cos ks, h R sin ks), k = 2π/λ,
    h = ``handedness``, s from ``start`` over ``turns`` pitches (its axis along x). For h = 1
    the curve turns counter-clockwise about +x as it advances along +x, a right-handed screw
    (its torsion τ = h k / (1 + k²R²) is positive); h = -1 is its mirror image, left-handed."""
    s = start + np.linspace(0.0, turns * pitch, n)
    k = 2.0 * math.pi / pitch
    return np.stack([s, radius * np.cos(k * s), handedness * radius * np.sin(k * s)], axis=1)


@dataclass(frozen=True)
class Helix(_Rigid):
    """A slender helical filament along x, centred on the origin: ``radius`` R, ``pitch`` λ,
    ``turns`` (its length along the axis is turns · λ), ``n_points`` on its centre line,
    right-handed for ``handedness`` = 1, left-handed for -1."""

    radius: float = 0.2
    pitch: float = 2.0
    turns: float = 3.0
    n_points: int = 120
    handedness: int = 1

    def __post_init__(self) -> None:
        _positive(radius=self.radius, pitch=self.pitch, turns=self.turns)
        _count("n_points", self.n_points, 2)
        if self.handedness not in (1, -1):
            raise ValueError(f"handedness: 1 (right) or -1 (left), got {self.handedness!r}")

    def _make(self) -> np.ndarray:
        return helix_line(self.radius, self.pitch, self.turns, self.n_points, self.handedness,
                          -0.5 * self.turns * self.pitch)


def load_points(source: str) -> np.ndarray:
    """An (N, 3) cloud from a ``.npy`` file, a text file of three columns (a regular file of at
    most 64 MiB: :func:`parastokes.core.files.read_input`), or a ``"module:function"`` returning
    one; ValueError naming the source and the problem."""
    if ":" in source and not Path(source).exists():
        make = plugins.import_target(source, source, ValueError)
        points = np.asarray(make(), dtype=float)
    else:
        path = Path(source)
        if not path.exists():
            raise ValueError(f"points: no file {source!r}; give a .npy or text file of (N, 3) "
                             "points, or a \"module:function\" that returns them")
        raw = read_input(path, "points")
        points = (np.load(io.BytesIO(raw), allow_pickle=False) if path.suffix == ".npy" else
                  np.loadtxt(io.StringIO(raw.decode("utf-8")), ndmin=2))
    points = np.asarray(points, dtype=float)
    if points.ndim != 2 or points.shape[1] != 3 or len(points) < 1:
        raise ValueError(f"points: {source!r} must give an (N, 3) array, got {points.shape}")
    if not np.isfinite(points).all():
        raise ValueError(f"points: {source!r} has non-finite coordinates")
    return points


@dataclass(frozen=True)
class PointCloud(_Rigid):
    """A user's surface: ``points`` (a tuple of (x, y, z) in the body frame, about the body's
    reference point) or ``source`` (a file or ``"module:function"``, :func:`load_points`)."""

    points_: tuple[tuple[float, float, float], ...] = ()
    source: str = ""

    def __post_init__(self) -> None:
        if bool(self.points_) == bool(self.source):
            raise ValueError("a point cloud needs either points or source (not both)")
        body_points(self)  # errors now, not at the first step

    @classmethod
    def of(cls, points: Any) -> PointCloud:
        """A cloud of the (N, 3) array ``points``."""
        array = np.asarray(points, dtype=float)
        if array.ndim != 2 or array.shape[1] != 3:
            raise ValueError(f"points: need an (N, 3) array, got shape {array.shape}")
        return cls(points_=tuple((float(x), float(y), float(z)) for x, y, z in array))

    def _make(self) -> np.ndarray:
        return load_points(self.source) if self.source else np.array(self.points_, dtype=float)


#: The default motor rate of a bacterium, rad/s: 10 turns a second relative to its head, about
#: -e1 (counter-clockwise seen from behind the cell, E. coli's run; the class's and a
#: configuration's default; experiments/bacterium_wall.toml sets 100 turns a second).
MOTOR_RATE = -2.0 * math.pi * 10
#: The default handedness of a bacterium's flagellum: -1, left-handed (E. coli's normal form).
LEFT_HANDED = -1


@dataclass(frozen=True)
class Bacterium:
    """A ``head`` (a :class:`Sphere` or :class:`Spheroid` about the origin) and a helical
    flagellum (``tail``, a :class:`Helix` whose axis is the body's x axis) behind it: the
    flagellum starts ``gap`` behind the head's rear (x = -axial - gap) and turns relative to the
    head at the angular velocity ``motor_rate`` e1 (rad/s, right-hand rule about the body axis
    e1, which points from the flagellum to the head): ``motor_rate`` < 0 turns it
    counter-clockwise seen from behind the cell (looking from the tail toward the head), as
    E. coli's motor does in a run. The head counter-rotates so that the whole is free of torque
    (the mobility solve finds Ω). The default, a left-handed flagellum at -2π·10 rad/s, is
    E. coli's: it swims head first (along +e1). The flagellum's rows follow the head's; at phase
    φ the flagellum is turned by φ about e1."""

    head: Sphere | Spheroid = Sphere(1.0, 200)
    tail: Helix = Helix(0.25, 2.0, 3.0, 100, LEFT_HANDED)
    gap: float = 0.25
    motor_rate: float = MOTOR_RATE

    def __post_init__(self) -> None:
        if not isinstance(self.head, Sphere | Spheroid):
            raise ValueError(f"head: a Sphere or a Spheroid, got {type(self.head).__name__}")
        if not isinstance(self.tail, Helix):
            raise ValueError(f"tail: a Helix, got {type(self.tail).__name__}")
        _positive(gap=self.gap)
        if not math.isfinite(self.motor_rate):
            raise ValueError(f"motor_rate: must be finite, got {self.motor_rate!r}")

    @property
    def phase_rate(self) -> float:
        return float(self.motor_rate)

    @property
    def head_rows(self) -> int:
        return self.head.n_points

    def _tail(self) -> np.ndarray:
        t = self.tail
        rear = self.head.axial if isinstance(self.head, Spheroid) else self.head.radius
        start = -(rear + self.gap + t.turns * t.pitch)
        return helix_line(t.radius, t.pitch, t.turns, t.n_points, t.handedness, start)

    def points(self, phase: float = 0.0) -> np.ndarray:
        head, tail = body_points(self.head), body_points(self)
        c, s = math.cos(phase), math.sin(phase)
        turned = tail.copy()
        turned[:, 1] = c * tail[:, 1] - s * tail[:, 2]
        turned[:, 2] = s * tail[:, 1] + c * tail[:, 2]
        return np.concatenate([head, turned])

    def contains(self, points: np.ndarray) -> np.ndarray:
        """Points inside the head (the flagellum is a slender filament)."""
        return self.head.contains(points)

    def moving(self, phase: float = 0.0) -> np.ndarray:
        """ω_m e1 × x at the flagellum's points (its axis is the x axis), zero on the head."""
        x = self.points(phase)
        out = np.zeros_like(x)
        tail = slice(self.head_rows, None)
        out[tail, 1] = -self.motor_rate * x[tail, 2]
        out[tail, 2] = self.motor_rate * x[tail, 1]
        return out

    def _make(self) -> np.ndarray:
        return self._tail()


@lru_cache(maxsize=64)
def body_points(shape: Any) -> np.ndarray:
    """The body-frame points of a shape's rigid part (read-only; a :class:`Bacterium`: its
    flagellum at phase 0), computed once per shape value."""
    points = np.ascontiguousarray(shape._make(), dtype=float)
    points.setflags(write=False)
    return points


@lru_cache(maxsize=64)
def spacing(shape: Any) -> float:
    """The largest distance from a point of the shape to its nearest neighbour (phase 0): the
    coarsest gap in the surface that the blobs of width ε must cover."""
    points = shape.points(0.0)
    if len(points) < 2:
        return math.inf
    distance, _ = cKDTree(points).query(points, k=2)
    return float(distance[:, 1].max())
