"""``[coarse] kind = "hodmd"``: the HODMD-Parareal coarse-solver family (docs/hodmd.md).

G1 and G2 are sections of the extrapolated family (:class:`~parastokes.coarse.extrapolated.
Extrapolated`) nested as ``[coarse.g1]`` and ``[coarse.g2]``: a plain solver (one scheme and step),
one on a coarser grid (``grid_factor``, the spline transfer of eqs. 32-33), or an extrapolated one
(Lagrange nodes over Θ, Richardson over τ), which composes the two kinds of extrapolation. They
run over snapshot intervals h = slice / ``snapshots``, so their steps are resolved (and checked)
on h. Rules, checked before any solver is built (exit 2, one line per key):

- ``window`` (r_s, one per iteration, the last repeated): each in (0, 1]; W = round(r_s S) snapshot
  intervals must hold at least d + 1 snapshots (W >= d);
- ``d`` >= 1; ``svd_tolerance`` (ε1) and ``amplitude_tolerance`` (ε) in (0, 1);
- the step of a plain G1 or G2 (no Richardson steps) must divide h: otherwise the snapshots would
  not lie on the solver's own steps;
- the nested sections' own rules (nodes, weights, grid factor), named ``coarse.g1.*``.
"""

from __future__ import annotations

import statistics
from typing import Any, Literal

from pydantic import Field, field_validator

from ...core.contracts import System
from ...registry.coarse import CoarseResolution, CoarseSection
from ..extrapolated import Extrapolated, operation_counts
from .solver import HodmdCoarse, as_windows, traced_window

__all__ = ["PAIR_FLOPS", "Hodmd", "hodmd_flops"]

#: Floating-point operations of one Stokeslet pair in a rate evaluation (the MRS kernels with
#: wall images do about this many), used to put HODMD's SVDs on the scale of γ_F; an estimate:
#: the slice-cost probe measures the real ratio.
PAIR_FLOPS = 200.0


def hodmd_flops(rows: int, snapshots: int, d: int) -> float:
    """Flops of one HODMD of ``rows`` × ``snapshots`` data (upper bounds of the ranks): the two
    thin SVDs (4mn² + 22n³ each: J × K, then dN × (K − d + 1) with N <= K) and the amplitudes'
    least squares ((K N) × M with M <= K − d + 1: 2(KN)M²)."""
    k, n_rank = snapshots, min(rows, snapshots)
    width = max(1, k - d + 1)
    first = 4 * rows * k**2 + 22 * k**3
    second = 4 * d * n_rank * width**2 + 22 * width**3
    return float(first + second + 2 * k * n_rank * width**2)


class Hodmd(CoarseSection):
    """HODMD-Parareal (docs/hodmd.md): G2 over the whole slice, G1 over r_s of it, HODMD of their
    difference. ``[coarse.g1]`` (the accurate solver) and ``[coarse.g2]`` (the cheap one), both
    required, are sections of the extrapolated family (the keys of ``coarse (kind =
    "extrapolated")``), resolved on the snapshot interval h = slice / ``snapshots``."""

    kind: Literal["hodmd"] = Field("hodmd", description="The HODMD-Parareal coarse-solver family.")
    g1: Extrapolated = Field(description="The accurate coarse solver G1 (an extrapolated section).")
    g2: Extrapolated = Field(description="The cheap coarse solver G2 (an extrapolated section).")
    snapshots: int = Field(ge=2, description="S: snapshot intervals per slice (authors: 125).")
    window: list[float] = Field(
        default_factory=lambda: [0.5], min_length=1,
        description="r_s: the fraction of each slice G1 runs over, per iteration (the last is "
        "repeated; the authors' rod: [0.48, 0.52, 0.96]).",
    )
    d: int = Field(12, ge=1, description="HODMD's delayed copies (authors: 12).")
    svd_tolerance: float = Field(1e-8, description="ε1: HODMD's relative SVD tolerance.")
    amplitude_tolerance: float = Field(1e-8, description="ε: HODMD's relative mode tolerance.")
    initial: Literal["sweep", "global"] = Field(
        "sweep",
        description="The initial guess X^0: sweep (HODMD coarse steps, slice by slice) or global "
        "(the authors': G1 over the first initial_fraction of the slices, G2 over all, one HODMD "
        "of G1 - G2 extrapolated to the later slice ends).",
    )
    initial_fraction: float = Field(0.6, gt=0, le=1, description="global: the share of the "
                                    "slices G1 runs over (authors: 0.6).")
    initial_snapshots: int = Field(10, ge=1, description="global: snapshots per slice (authors: "
                                   "10).")
    initial_d: int = Field(10, ge=1, description="global: HODMD's delayed copies (authors: 10).")

    @field_validator("window", mode="before")
    @classmethod
    def _one_window(cls, value: Any) -> Any:
        """``window = 0.5`` is short for ``window = [0.5]``."""
        return [value] if isinstance(value, int | float) and not isinstance(value, bool) else value

    def _nested(self, name: str, cfg: Any, body: Any, h: float,
                issues: list[tuple[str, str]], warnings: list[str]) -> CoarseResolution:
        """Resolve ``[coarse.<name>]`` on the snapshot interval h, its keys renamed."""
        section: Extrapolated = getattr(self, name)
        own: list[tuple[str, str]] = []
        notes: list[str] = []
        result = section.resolve(cfg, body, h, own, notes)
        issues += [(key.replace("coarse.", f"coarse.{name}.", 1), text) for key, text in own]
        warnings += [note.replace("coarse.", f"coarse.{name}.", 1) for note in notes]
        if section.richardson.m == 0 and not own:
            steps = h / result.coarse_dt
            if abs(steps - round(steps)) > 1e-9 * steps:
                issues.append((
                    f"coarse.{name}.{'dt' if section.dt is not None else 'dt_ratio'}",
                    f"the step {result.coarse_dt:.6g} does not divide the snapshot interval "
                    f"h = {h:.6g} (slice / coarse.snapshots = {self.snapshots}): choose a step "
                    "h / n or another number of snapshots",
                ))
        return result

    def _check_global(self, cfg: Any, slice_length: float, solvers: tuple[Any, Any],
                      issues: list[tuple[str, str]]) -> None:
        """The global initial guess: enough snapshots for initial_d, steps dividing its h."""
        ran = min(cfg.parareal.n_slices, max(1, round(self.initial_fraction
                                                       * cfg.parareal.n_slices)))
        if ran * self.initial_snapshots < self.initial_d:
            issues.append((
                "coarse.initial_snapshots",
                f"G1 runs over {ran} slices of {self.initial_snapshots} snapshot intervals, fewer "
                f"than coarse.initial_d = {self.initial_d}: raise initial_snapshots or "
                "initial_fraction, or lower initial_d",
            ))
        h = slice_length / self.initial_snapshots
        for name, res in zip(("g1", "g2"), solvers, strict=True):
            steps = h / res.coarse_dt
            if getattr(self, name).richardson.m == 0 and abs(steps - round(steps)) > 1e-9 * steps:
                issues.append((
                    "coarse.initial_snapshots",
                    f"coarse.{name}'s step {res.coarse_dt:.6g} does not divide the interval "
                    f"h = {h:.6g} of the global initial guess (slice / initial_snapshots)",
                ))

    def windows(self) -> tuple[int, ...]:
        """W per iteration (snapshot intervals)."""
        return as_windows(self.window, self.snapshots)

    def resolve(self, cfg: Any, body: Any, slice_length: float,
                issues: list[tuple[str, str]], warnings: list[str]) -> CoarseResolution:
        """G1's and G2's resolutions on h, and the rules of the module docstring. Reported as
        τ_c = G1's step; ``coarse_steps`` = [G1 steps over the largest window, G2 steps over the
        slice]; N_G = 1 (a trace is one task: the auxiliary solvers of an extrapolated G1 or G2
        run one after the other in it), Σ|w| the larger of the two solvers'."""
        for name in ("svd_tolerance", "amplitude_tolerance"):
            value = getattr(self, name)
            if not 0.0 < value < 1.0:
                issues.append((f"coarse.{name}", f"must lie in (0, 1), got {value:g}"))
        bad = [r for r in self.window if not 0.0 < r <= 1.0]
        if bad:
            issues.append(("coarse.window", f"every r_s must lie in (0, 1], got {bad}"))
        elif min(self.windows()) < self.d:
            r_min = min(self.window)
            issues.append((
                "coarse.window",
                f"r_s = {r_min:g} gives a window of W = {min(self.windows())} snapshot intervals "
                f"(of coarse.snapshots = {self.snapshots}); HODMD with coarse.d = {self.d} needs "
                f"W >= d (d + 1 snapshots): raise the window or the snapshots, or lower d",
            ))
        h = slice_length / self.snapshots
        g1 = self._nested("g1", cfg, body, h, issues, warnings)
        g2 = self._nested("g2", cfg, body, h, issues, warnings)
        if self.initial == "global":
            self._check_global(cfg, slice_length, (g1, g2), issues)
        widest = max(self.windows()) if not bad else self.snapshots
        return CoarseResolution(
            g1.coarse_dt, g1.coarse_base_dt,
            [max(g1.coarse_steps) * widest, max(g2.coarse_steps) * self.snapshots],
            g1.coarse_points, {**g2.lagrange, **g1.lagrange},
            1, max(g1.weight_sum, g2.weight_sum),
        )

    def _resolve_nested(self, cfg: Any, resolved: Any) -> tuple[Any, Any]:
        """The nested sections' resolutions again (for build and the cost estimate)."""
        body = cfg.model.resolve()
        h = resolved.slice_length / self.snapshots
        return tuple(getattr(self, name).resolve(cfg, body, h, [], []) for name in ("g1", "g2"))

    def build(self, cfg: Any, resolved: Any, system: System) -> HodmdCoarse:
        """The tracing coarse solver of :mod:`.solver` with G1, G2 built by their sections."""
        g1_res, g2_res = self._resolve_nested(cfg, resolved)
        return HodmdCoarse(
            system,
            self.g1.build(cfg, g1_res, system),
            self.g2.build(cfg, g2_res, system),
            self.snapshots, self.windows(), self.d,
            self.svd_tolerance, self.amplitude_tolerance,
            None if self.initial == "sweep" else
            (self.initial_fraction, self.initial_snapshots, self.initial_d),
        )

    def gamma_ratio(self, cfg: Any, resolved: Any, cores: int) -> float:
        """γ_G/γ_F of one coarse step (a trace and its correction), from operation counts:

        G1 over the mean trace window (iterations 1..K), G2 over the slice, each as rate
        evaluations times (points)² in ceil(N_G / cores) rounds, plus one HODMD per column group
        (:func:`hodmd_flops`) at :data:`PAIR_FLOPS` flops per Stokeslet pair."""
        g1, g2 = self._resolve_nested(cfg, resolved)
        iterations = cfg.parareal.max_iterations or 3
        traced = statistics.mean(traced_window(self.windows(), k)
                                 for k in range(1, iterations + 1))
        fine, (one, two) = operation_counts(cfg, resolved, [(self.g1, g1), (self.g2, g2)])
        solves = (g1.n_auxiliary * one * traced * g1.coarse_points**2
                  + g2.n_auxiliary * two * self.snapshots * g2.coarse_points**2)
        rows = resolved.n_points * 3  # one column group of three (rods: X, D1, D2, D3)
        groups = 4 if cfg.model.kind == "rod" else 1
        svd = hodmd_flops(rows, self.windows()[-1] + 1, self.d)
        return (solves + groups * svd / PAIR_FLOPS) / fine

