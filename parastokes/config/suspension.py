"""Suspensions: ``[[suspensions]]`` tables, each many copies of one body in a scene.

A table names a body (any kind whose section has a position key, :data:`POSITION_KEYS`, and
optionally an ``orientation`` quaternion: the rigid kinds, the vesicle's ``center``, a user's
kind with such a field) and where its copies go (:class:`~.schema.Suspension`,
:mod:`.placement`). :func:`expand` turns it into validated body sections named ``name0``,
``name1``, ... that join the scene's ``[[bodies]]`` (:mod:`.scene`), where every check of a
scene applies to them (names, the fluid, overlaps and the wall, :class:`parastokes.scene.Scene`).

Before anything is built, what the placement alone can tell is refused with the table's key:
keys that the placement does not use or lacks, a lattice whose spacing is smaller than the
body, a random placement that cannot reach its count (at once above random close packing,
:func:`.placement.packing`; else after :func:`.placement.random_centers` tried), a region or a
lattice or a pose of the file that reaches the wall, and copies that cannot fit in this
machine's memory (:func:`planned_bytes`, from their count and one body's size, before any
centre is computed or copy made).

The body's size is measured once on the body built from the table (wall off, at its own
position): its points' offsets from its position give the bounding radius (a sphere's radius)
and the extent along each axis; its ``epsilon`` gives the default gap.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from ..registry.kinds import BodySection
from . import placement
from .placement import PlacementError
from .schema import Suspension

__all__ = ["POSITION_KEYS", "Footprint", "expand", "planned_bytes", "position_key"]

#: The section keys a suspension sets to place a copy (the first one the section has).
POSITION_KEYS = ("position", "center")
#: Bytes of one copy's validated body section (a rigid sphere's: 3.6 kB, measured with
#: tracemalloc over 1,000 copies; docs/validation.md, "A suspension refused before it is built").
SECTION_BYTES = 3.6e3
#: The fewest states of 3 doubles per row that any run keeps: checks.estimated_bytes with one
#: slice and a one-stage scheme, 3 (1 + 1) + (1 + 1) + 1 + 2.
FEWEST_STATES = 11

#: The keys each placement uses besides ``name``, ``body``, ``placement``, ``orientations``.
_USES = {
    "lattice": {"center", "counts", "spacing", "gap"},
    "random": {"center", "region", "size", "radius", "count", "volume_fraction", "seed", "gap"},
    "file": {"file"},
}
_REQUIRED = {"lattice": ("center", "counts", "spacing"), "random": ("center",),
             "file": ("file",)}
_DEFAULTS = {"region": "box", "seed": 0, "orientations": "fixed"}


def position_key(section: type[BodySection]) -> str | None:
    """The key of ``section`` that holds the body's position (None if it has none)."""
    return next((k for k in POSITION_KEYS if k in section.model_fields), None)


class Footprint:
    """The points of ``template`` about its position: ``offsets`` (P, 3) in its own
    orientation ``q0``, the bounding ``radius``, and its blobs' ``epsilon``."""

    def __init__(self, template: BodySection, key: str) -> None:
        updates = {"wall": False} if "wall" in type(template).model_fields else {}
        system = template.model_copy(update=updates).build()
        state = system.initial_state()
        self.rows = len(state)
        points = np.asarray(system.positions(state), dtype=float)[:, :3]
        self.offsets = points - np.asarray(getattr(template, key), dtype=float)
        self.radius = float(np.max(np.linalg.norm(self.offsets, axis=1)))
        self.epsilon = float(getattr(system, "epsilon", 0.0))
        q0 = getattr(template, "orientation", None)
        self.q0 = None if q0 is None else np.asarray(q0, dtype=float) / np.linalg.norm(q0)

    def turned(self, quaternions: np.ndarray | None) -> np.ndarray:
        """The offsets of every copy (n, P, 3), turned from ``q0`` to its orientation."""
        if quaternions is None or self.q0 is None:
            return self.offsets[None]
        relative = placement.matrices(quaternions) @ placement.matrices(self.q0[None])[0].T
        return np.einsum("nab,pb->npa", relative, self.offsets)

    def default_gap(self) -> float:
        """The larger of a fifth of the bounding radius and 2 ε (blobs of two bodies apart)."""
        return max(0.2 * self.radius, 2.0 * self.epsilon)


def planned_bytes(count: int, rows: int, dense_bytes: float) -> float:
    """A lower bound on the memory of ``count`` copies of a body whose state has ``rows`` rows
    and whose solves keep ``dense_bytes`` of dense matrices: their validated sections
    (:data:`SECTION_BYTES`), their dense matrices, and the :data:`FEWEST_STATES` states of 3
    doubles per row of the smallest run."""
    return count * (SECTION_BYTES + dense_bytes + 24.0 * FEWEST_STATES * rows)


def _fits(count: int, key: str, template: BodySection, foot: Footprint) -> None:
    """PlacementError naming ``key`` when ``count`` copies of ``template`` cannot fit in this
    machine's memory (:func:`planned_bytes`; one body's size from its keys where its kind
    says, :meth:`~parastokes.registry.kinds.BodySection.planned_size`, else as built)."""
    from .checks import physical_memory  # (checks reads the schema, which reads this module)

    size = template.planned_size()
    rows, dense = (size.rows, size.dense_bytes) if size is not None else (foot.rows, 0.0)
    needed, memory = planned_bytes(count, rows, dense), physical_memory()
    if needed > memory:
        matrices = f" and dense mobility matrices of {dense / 2**20:.3g} MiB each" if dense else ""
        raise PlacementError(key, f"{count} bodies of {rows} rows{matrices} need more than "
                                  f"{needed / 2**30:.3g} GiB, and this machine has "
                                  f"{memory / 2**30:.3g} GiB; place fewer bodies")


def _key_issues(spec: Suspension, has_orientation: bool) -> list[tuple[str, str]]:
    """Keys the placement does not use, or lacks."""
    uses = _USES[spec.placement]
    out = []
    for key in _USES["lattice"] | _USES["random"] | _USES["file"]:
        value = getattr(spec, key)
        if key not in uses and value is not None and value != _DEFAULTS.get(key):
            places = [p for p, keys in _USES.items() if key in keys]
            out.append((key, f"only placement = {' or '.join(map(repr, places))} uses it; "
                             f"remove it (placement = {spec.placement!r})"))
    out += [(key, f"required by placement = {spec.placement!r}")
            for key in _REQUIRED[spec.placement] if getattr(spec, key) is None]
    if spec.placement == "random":
        if (spec.count is None) == (spec.volume_fraction is None):
            out.append(("count", "give either count or volume_fraction (one of the two)"))
        region_key, other = ("radius", "size") if spec.region == "sphere" else ("size", "radius")
        if getattr(spec, region_key) is None:
            out.append((region_key, f"required by region = {spec.region!r}"))
        if getattr(spec, other) is not None:
            out.append((other, f"region = {spec.region!r} uses {region_key}; remove it"))
    if spec.orientations == "random" and not has_orientation:
        out.append(("orientations", "this kind has no orientation key; use \"fixed\""))
    return out


def _lattice(spec: Suspension, template: BodySection, foot: Footprint, gap: float,
             turned: bool) -> np.ndarray:
    """The lattice's centres; PlacementError when neighbours would come closer than ``gap``
    or the copies cannot fit in memory (before the centres are computed)."""
    assert spec.counts is not None and spec.center is not None and spec.spacing is not None
    _fits(math.prod(spec.counts), "counts", template, foot)
    spacing = [spec.spacing] * 3 if isinstance(spec.spacing, float | int) else spec.spacing
    extent = (np.full(3, 2 * foot.radius) if turned
              else np.ptp(foot.offsets, axis=0))
    for axis, (n, d, size) in enumerate(zip(spec.counts, spacing, extent, strict=True)):
        if n > 1 and d < size + gap:
            raise PlacementError(
                "spacing", f"{d:g} along {'xyz'[axis]} is less than the body's extent "
                f"{size:.4g} plus the gap {gap:.4g}: neighbours would overlap or touch; raise "
                f"it to at least {size + gap:.4g}")
    return placement.lattice(spec.counts, [float(d) for d in spacing], spec.center)


def _random(spec: Suspension, template: BodySection, foot: Footprint, gap: float,
            wall: bool) -> np.ndarray:
    """Random centres; PlacementError for a region below the wall, a count beyond random close
    packing or memory (at once), or not reached."""
    assert spec.center is not None
    half = spec.radius if spec.region == "sphere" else 0.5 * (spec.size or [0, 0, 0])[2]
    assert half is not None
    bottom = spec.center[2] - half
    if wall and not bottom > 0.0:
        raise PlacementError(
            "center", f"the {spec.region} reaches down to z = {bottom:.4g}, on or below the wall "
            f"z = 0; raise center[2] above {half:.4g} or shrink the region")
    volume = placement.region_volume(spec.region, spec.size, spec.radius)
    body = 4.0 / 3.0 * math.pi * foot.radius**3
    count = spec.count
    if count is None:
        assert spec.volume_fraction is not None
        count = round(spec.volume_fraction * volume / body)
        if count < 1:
            raise PlacementError("volume_fraction", f"{spec.volume_fraction:g} of this region "
                                                    "holds no whole body; raise it or enlarge "
                                                    "the region")
    key = "count" if spec.count is not None else "volume_fraction"
    placement.holds_one(spec.region, spec.size, spec.radius, foot.radius)  # (before its count)
    distance = 2.0 * foot.radius + gap
    packed = placement.packing(count, spec.region, spec.size, spec.radius, foot.radius, distance)
    if count > 1 and packed > placement.RANDOM_CLOSE_PACKING:
        raise PlacementError(
            key, f"{count} bodies ask a volume fraction {count * body / volume:.3g} of the "
            f"{spec.region}, and with the gap around each they would fill {packed:.3g} of it, "
            f"more than random close packing ({placement.RANDOM_CLOSE_PACKING:g}; the random "
            f"placement reaches about 0.3): lower {key}, enlarge the region, lower gap, or use "
            "placement = \"lattice\"")
    _fits(count, key, template, foot)
    rng = np.random.default_rng(spec.seed)
    centers, drawn = placement.random_centers(count, spec.region, spec.center, spec.size,
                                              spec.radius, foot.radius, distance, rng)
    if len(centers) < count:
        raise PlacementError(
            key, f"random placement gave up: {len(centers)} of {count} bodies placed after "
            f"{drawn} tries (volume fraction {len(centers) * body / volume:.3g} of the "
            f"{count * body / volume:.3g} asked, {_with_gap(foot.radius, gap):.3g} times more "
            f"counting the gap); lower {key}, enlarge the region, lower gap, or use "
            "placement = \"lattice\"")
    return centers


def _with_gap(radius: float, gap: float) -> float:
    """How much more volume a body of bounding ``radius`` takes with half the ``gap`` around."""
    return (1.0 + 0.5 * gap / radius) ** 3


def _poses(spec: Suspension, template: BodySection, foot: Footprint, wall: bool
           ) -> tuple[np.ndarray, np.ndarray | None]:
    """Centres (n, 3) and orientations (n, 4) or None for the bodies' own."""
    gap = foot.default_gap() if spec.gap is None else spec.gap
    if gap < foot.epsilon:
        raise PlacementError("gap", f"{gap:g} is less than the bodies' ε = {foot.epsilon:.4g}: "
                                    "their blobs would overlap (the scene refuses bodies closer "
                                    "than ε); raise it")
    turned = spec.orientations == "random"
    if spec.placement == "lattice":
        centers = _lattice(spec, template, foot, gap, turned)
    elif spec.placement == "random":
        centers = _random(spec, template, foot, gap, wall)
    else:
        assert spec.file is not None
        poses = placement.read_poses(Path(spec.file))
        _fits(len(poses), "file", template, foot)
        if poses.shape[1] == 7 and foot.q0 is None:
            raise PlacementError("file", "7 numbers per line give orientations, but this kind "
                                         "has no orientation key; give x y z only")
        if poses.shape[1] == 7:
            return poses[:, :3].copy(), poses[:, 3:].copy()
        centers = poses
    if not turned:
        return centers, None
    rng = np.random.default_rng([spec.seed, 1])  # independent of the positions' stream
    return centers, placement.random_quaternions(len(centers), rng)


def _below_wall(spec: Suspension, foot: Footprint, centers: np.ndarray,
                quaternions: np.ndarray | None, prefix: str) -> tuple[str, str] | None:
    """The issue of the first copy whose points reach the wall z = 0, or None."""
    lowest = np.empty(len(centers))
    for start in range(0, len(centers), 256):
        q = None if quaternions is None else quaternions[start:start + 256]
        offsets = foot.turned(q)
        lowest[start:start + 256] = centers[start:start + 256, 2] + offsets[..., 2].min(axis=1)
    if np.all(lowest > 0.0):
        return None
    i = int(np.argmax(~(lowest > 0.0)))
    where = f"body {prefix}{i} reaches z = {lowest[i]:.4g}, on or below the wall z = 0"
    if spec.placement == "file":
        return "file", f"{where} (pose {i}, counted from 0); raise it by more than " \
                       f"{-lowest[i]:.4g}"
    return "center", f"{where}; raise center[2] by more than {-lowest[i]:.4g}"


def expand(spec: Suspension, template: BodySection, prefix: str, wall: bool
           ) -> list[BodySection]:
    """The copies of ``template`` that ``spec`` places (see the module), to be named ``prefix``
    + index; ``wall``: the scene's. A relative ``file`` is read from the current folder
    (:func:`parastokes.config.load` anchors it at the configuration file). Raises
    :class:`PlacementError` naming the key of ``spec`` to change (``"body."`` + a key of the
    body's table for the body itself)."""
    key = position_key(type(template))
    if key is None:
        raise PlacementError("body.kind", f"a {template.kind} has no position key "
                                          f"({' or '.join(POSITION_KEYS)}), so copies of it "
                                          "cannot be placed; give each as a [[bodies]] table")
    issues = _key_issues(spec, "orientation" in type(template).model_fields)
    if issues:
        raise PlacementError(*issues[0])
    if key in template.model_fields_set:
        raise PlacementError(f"body.{key}", "the suspension places the bodies; remove it")
    foot = Footprint(template, key)
    centers, quaternions = _poses(spec, template, foot, wall)
    if quaternions is not None and "orientation" in template.model_fields_set:
        by = ("the file" if spec.placement == "file" else "orientations = \"random\"")
        raise PlacementError("body.orientation", f"{by} turns the bodies; remove it")
    if wall:
        issue = _below_wall(spec, foot, centers, quaternions, prefix)
        if issue:
            raise PlacementError(*issue)
    out = []
    for i, center in enumerate(centers):
        update: dict[str, Any] = {key: [float(v) for v in center]}
        if quaternions is not None:
            update["orientation"] = [float(v) for v in quaternions[i]]
        out.append(type(template).model_validate(template.model_dump() | update))
    return out
