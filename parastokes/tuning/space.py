"""The search space of ``parastokes tune``: the coarse solvers of eq. 30 that the tuner considers.

A candidate (:class:`Settings`) is a scheme for the auxiliary solvers, Lagrange nodes for a subset
of the parameters Θ (eqs. 17-25), Richardson depth m and ratio r (eqs. 26-28), a coarse-grid factor
(rods, eqs. 32-33) and, once the stability analysis has chosen it, the base step τ. Nodes are placed
on the side of θ⁰ that relaxes the step limit (larger ε and μ, smaller bending modulus or spring
stiffness, as in Tables 3-8), starting at a relative distance ``reach`` from θ⁰ with a spacing
that is a fraction of the reach: by default (:data:`REACH`) the rods' reach / 4 (Table 4 G¹: ε from
5.2σ_f in steps of 0.05σ_f for ε⁰ = 5σ_f). A system may give its own levels and spacing in an
optional class attribute ``tuning_reach`` (the vesicle's reach the nodes of Tables 7-8).

A scheme with an error estimate (``integrate.SCHEMES[name].adaptive``, and ``"auto"``) also gives
adaptive candidates: every auxiliary solver takes adaptive steps within ``rtol`` (and ``atol``),
one candidate per value of the ladder :attr:`Space.coarse_rtols`, as fixed-step candidates take
one per step fraction (a Rosenbrock scheme, which also takes fixed steps, only when the ladder is
given: ``--schemes ros2`` alone searches what it did before). Richardson extrapolation needs the
fixed steps r^q τ of eq. 26, so adaptive candidates have m = 0 (``parareal.adaptive_tolerances``);
the embedded explicit pairs and ``"auto"`` take adaptive steps only (``config.check`` refuses them
on a fixed step).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from .. import integrate
from ..core.contracts import System
from ..parareal.extrapolation import extrapolated
from ..parareal.weights import lagrange_weights, richardson_weights, validate_richardson

__all__ = ["COARSE_RTOLS", "DIRECTION", "REACH", "Settings", "Space", "TuningError",
           "adaptive_only", "reach_table", "takes_rtol"]

#: The default rtol ladder of adaptive coarse candidates (``Space.coarse_rtols``).
COARSE_RTOLS = (1e-2, 1e-3, 1e-4)


def takes_rtol(scheme: str) -> bool:
    """Whether ``scheme`` has an error estimate for adaptive steps (``"auto"`` included)."""
    return integrate.lookup(scheme).adaptive


def adaptive_only(scheme: str) -> bool:
    """Whether ``scheme`` takes adaptive steps only: ``"auto"`` and the embedded explicit pairs
    (on a fixed step a pair is its high-order member, which ``config.check`` refuses)."""
    s = integrate.lookup(scheme)
    return s.adaptive and not s.implicit

#: The side of θ⁰ on which a parameter's nodes relax the step limit (+1 above, -1 below).
DIRECTION = {"epsilon": 1, "viscosity": 1, "bending": -1, "stiffness": -1}

#: Per parameter: the relative distance of the first node from θ⁰ at reach levels 0, 1, 2, and
#: the node spacing as a fraction of that distance (the rods' tables, Tables 3-6).
REACH: dict[str, tuple[tuple[float, float, float], float]] = {
    "epsilon": ((0.02, 0.04, 0.08), 0.25),
    "viscosity": ((0.1, 0.3, 0.6), 0.25),
    "bending": ((0.05, 0.1, 0.2), 0.25),
    "stiffness": ((0.05, 0.1, 0.2), 0.25),
}


class TuningError(ValueError):
    """Bad input to the tuner, found before the search: the message names what to change."""


def reach_table(system: System) -> dict[str, tuple[tuple[float, float, float], float]]:
    """:data:`REACH` updated by the system's optional ``tuning_reach`` (same layout), checked."""
    table = dict(REACH)
    for name, entry in dict(getattr(system, "tuning_reach", None) or {}).items():
        try:
            levels, spacing = entry
            levels, spacing = tuple(float(v) for v in levels), float(spacing)
        except (TypeError, ValueError):
            levels, spacing = (), math.nan
        if (name not in DIRECTION or len(levels) != 3 or not spacing > 0
                or not all(0.0 < v < (1.0 if DIRECTION[name] < 0 else math.inf) for v in levels)):
            raise TuningError(
                f"tune: {type(system).__name__}.tuning_reach[{name!r}] = {entry!r} is not "
                "((d0, d1, d2), spacing) with three positive relative distances and a positive "
                f"spacing fraction for one of {sorted(DIRECTION)} (distances below 1 for the "
                "parameters whose nodes lie below θ⁰); fix the class attribute"
            )
        table[name] = (levels, spacing)
    return table


@dataclass(frozen=True)
class Settings:
    """One coarse solver of eq. 30 (``dt`` is the base step τ of eq. 26; None before it is set)."""

    scheme: str
    lagrange: tuple[tuple[str, tuple[float, ...]], ...] = ()
    m: int = 0
    r: float | None = None
    grid: int = 1
    dt: float | None = None
    reach: int | None = None
    step_fraction: float = 1.0
    name: str | None = field(default=None, compare=False)
    rtol: float | None = None  # adaptive steps of every auxiliary solver (dt: the first step)
    atol: float | None = None

    def __post_init__(self) -> None:
        validate_richardson(self.m, self.r)

    @property
    def adaptive(self) -> bool:
        """True when the auxiliary solvers take adaptive steps (``rtol``)."""
        return self.rtol is not None

    @property
    def n_auxiliary(self) -> int:
        """N_G = N_θ1 N_θ2 N_θ3 (m + 1)."""
        return math.prod(len(nodes) for _, nodes in self.lagrange) * (self.m + 1)

    @property
    def coarse_dt(self) -> float:
        """τ_c = r^m τ, the smallest auxiliary step (the tables' convention, section 5.1)."""
        assert self.dt is not None
        return self.dt * (self.r or 1.0) ** self.m

    @property
    def ratio(self) -> float:
        """The Richardson ratio r, 1 without Richardson (m = 0; m >= 1 without r is refused when
        the settings are made, by ``parareal.validate_richardson``)."""
        return 1.0 if self.r is None else self.r

    @property
    def plain(self) -> bool:
        """True for G_{Θ⁰,τ} itself: no extrapolation, the fine grid."""
        return not self.lagrange and self.m == 0 and self.grid == 1

    def weight_sum(self, theta0: Mapping[str, float]) -> float:
        """``Σ_j Σ_q |w_j v_q|`` for geometric steps (eqs. 22, 27): how much the combination
        amplifies what its members leave undamped."""
        w = 1.0
        if self.lagrange:
            names = [name for name, _ in self.lagrange]
            nodes = [list(values) for _, values in self.lagrange]
            w = float(np.abs(lagrange_weights([theta0[n] for n in names], nodes)).sum())
        v = 1.0
        if self.m:
            order = integrate.scheme_order(self.scheme)
            v = float(np.abs(richardson_weights(self.m, self.ratio, order)).sum())
        return w * v

    def corner(self) -> dict[str, float]:
        """The most restrictive node: for each parameter the node nearest θ⁰ (its step limit
        bounds every auxiliary solver's)."""
        return {
            name: (values[0] if DIRECTION[name] > 0 else values[-1])
            for name, values in self.lagrange
        }

    def label(self) -> str:
        parts = [self.scheme]
        for name, values in self.lagrange:
            parts.append(f"{name}×{len(values)}")
        if self.reach is not None and self.lagrange:
            parts.append(f"reach {self.reach}")
        if self.m:
            parts.append(f"m={self.m} r={self.ratio:g}")
        if self.grid > 1:
            parts.append(f"grid {self.grid}")
        if self.step_fraction != 1.0:
            parts.append(f"{self.step_fraction:g}·τ_safe")
        if self.adaptive:
            parts.append(f"rtol {self.rtol:g}" + ("" if self.atol is None
                                                   else f" atol {self.atol:g}"))
        text = ", ".join(parts) if len(parts) > 1 else f"{self.scheme}, plain"
        return text if self.name is None else f"{self.name}: {text}"

    def build(self, system: System) -> Any:
        """The propagator of eq. 30 on ``system`` (``parareal.extrapolated``)."""
        assert self.dt is not None
        return extrapolated(
            system,
            self.scheme,
            self.dt,
            lagrange={name: list(values) for name, values in self.lagrange} or None,
            richardson={"m": self.m, "r": self.r} if self.m else None,
            grid=self.grid if self.grid > 1 else None,
            rtol=self.rtol,
            atol=self.atol,
        )

    def as_dict(self, fine_dt: float | None = None) -> dict[str, Any]:
        """JSON-ready settings: the [coarse] keys plus N_G and the base step."""
        out: dict[str, Any] = {
            "label": self.label(),
            "scheme": self.scheme,
            "dt": None if self.dt is None else self.coarse_dt,
            "base_dt": self.dt,
            "lagrange": {name: list(values) for name, values in self.lagrange},
            "richardson": {"m": self.m, "r": self.r},
            "grid_factor": self.grid,
            "n_auxiliary": self.n_auxiliary,
            "rtol": self.rtol,
            "atol": self.atol,
        }
        if fine_dt is not None and self.dt is not None:
            out["dt_ratio"] = self.coarse_dt / fine_dt
        return out

    def coarse_table(self) -> dict[str, Any]:
        """The [coarse] section of a configuration (nodes in absolute units)."""
        table: dict[str, Any] = {"scheme": self.scheme, "dt": self.coarse_dt}
        if self.lagrange:
            table["lagrange"] = {
                name: {"nodes": list(values), "unit": "absolute"} for name, values in self.lagrange
            }
        if self.m:
            table["richardson"] = {"m": self.m, "r": self.r}
        if self.grid > 1:
            table["grid_factor"] = self.grid
        if self.adaptive:
            table["rtol"] = self.rtol
            if self.atol is not None:
                table["atol"] = self.atol
        return table


def nodes_for(name: str, theta0: float, reach: float, count: int,
              spacing: float = 0.25) -> tuple[float, ...]:
    """``count`` nodes from θ⁰(1 ± reach) away from θ⁰ in steps of θ⁰·reach·spacing, increasing."""
    sign = DIRECTION[name]
    values = [theta0 * (1.0 + sign * reach * (1.0 + spacing * i)) for i in range(count)]
    return tuple(sorted(float(f"{v:.12g}") for v in values))


@dataclass(frozen=True)
class Space:
    """What the tuner may choose; every field narrows the search (``parastokes tune`` options and
    the config's optional ``[tune]`` table set them).

    - ``schemes``: schemes of the auxiliary solvers;
    - ``parameters``: the parameters that may be extrapolated, first the one every extrapolated
      candidate uses (default ε): the subsets are that one with any of the others, e.g. (ε),
      (ε, μ), (ε, a), (ε, μ, a); empty: no Lagrange extrapolation;
    - ``reach``: node distance levels (:data:`REACH`, or the system's ``tuning_reach``);
      ``nodes``: node counts of the first parameter (the others use at most 3);
    - ``richardson``: depths m to try, with ratio ``r``; ``grid_factors``: coarse grids (rods);
    - ``step_fractions``: coarse steps as fractions of the largest safe step;
    - ``coarse_rtols``: the rtol ladder of the adaptive candidates, atol = rtol: of the schemes
      that take adaptive steps only (:func:`adaptive_only`; None: :data:`COARSE_RTOLS`), and,
      when given, of every scheme that takes rtol (:func:`takes_rtol`: the Rosenbrock ones);
    - ``max_weight``: candidates with ``Σ|w_j v_q|`` above it are pruned before any measurement;
    - ``extra``: solvers with their own step (e.g. the paper's, :func:`settings_from_config`),
      always measured, never pruned;
    - ``leading``: candidates searched before every other one (after ``extra``), in the order
      of their estimates, each screened and measured before the next begins; unlike ``extra``
      they take the safe step times their ``step_fraction``, and the budget and the pruning
      bind them as any candidate (``plan``'s ladder of the plain implicit coarse solver,
      docs/planning.md); one already in the space is moved forward, not repeated.
    """

    schemes: tuple[str, ...] = ("euler", "rk2")
    parameters: tuple[str, ...] | None = None
    reach: tuple[int, ...] = (0, 1, 2)
    nodes: tuple[int, ...] = (2, 3, 4, 5)
    richardson: tuple[int, ...] = (0, 1)
    r: float = 0.83
    grid_factors: tuple[int, ...] = (1,)
    step_fractions: tuple[float, ...] = (1.0, 0.6)
    coarse_rtols: tuple[float, ...] | None = None
    max_weight: float = 1e6
    extra: tuple[Settings, ...] = field(default=())
    leading: tuple[Settings, ...] = field(default=())

    def check(self, params: Mapping[str, float], grid_ok: Any) -> None:
        """Raise :class:`TuningError` for choices the system cannot take."""
        choices = {"schemes": self.schemes, "reach": self.reach, "nodes": self.nodes,
                   "richardson": self.richardson, "grid_factors": self.grid_factors,
                   "step_fractions": self.step_fractions}
        empty = [name for name, values in choices.items() if not values]
        if empty:
            raise TuningError(f"tune: nothing to choose from in {', '.join(empty)}; give at least "
                              "one value (or leave the option out for its default)")
        parameters = self.parameters or ()
        if len(set(parameters)) < len(parameters):
            raise TuningError(f"tune: parameters {list(parameters)} name one twice; give each once")
        for scheme in (*self.schemes, *(s.scheme for s in self.leading)):
            if scheme not in integrate.SCHEMES and scheme != integrate.AUTO.name:
                known = [*sorted(integrate.SCHEMES), integrate.AUTO.name]
                raise TuningError(f"tune: unknown scheme {scheme!r}; use one of {known}")
        self._check_rtols()
        for name in parameters:
            if name not in params or name not in DIRECTION:
                known = sorted(set(params) & set(DIRECTION))
                raise TuningError(f"tune: cannot extrapolate in {name!r}; this system has {known}")
        if any(level not in (0, 1, 2) for level in self.reach):
            raise TuningError(f"tune: reach levels are 0, 1, 2, got {list(self.reach)}")
        if any(n < 1 for n in self.nodes) or any(m < 0 for m in self.richardson):
            raise TuningError("tune: node counts must be >= 1 and Richardson depths >= 0")
        if not 0.0 < self.r < 1.0:
            raise TuningError(f"tune: the Richardson ratio r must lie in (0, 1), got {self.r}")
        if any(not 0.0 < f <= 1.0 for f in self.step_fractions):
            raise TuningError("tune: step fractions must lie in (0, 1]")
        for factor in self.grid_factors:
            if isinstance(factor, bool) or not isinstance(factor, int) or factor < 1:
                raise TuningError(f"tune: grid factors must be integers >= 1, got {factor!r}")
            if factor > 1 and not grid_ok(factor):
                raise TuningError(
                    f"tune: grid factor {factor} does not fit this system (it must divide the "
                    "number of rod segments of the run and of the pilot); drop it"
                )
        for given in self.extra:
            if given.grid > 1 and not grid_ok(given.grid):
                raise TuningError(
                    f"tune: the compared solver {given.label()} has grid factor {given.grid}, "
                    "which does not divide the number of rod segments of the run and of the "
                    "pilot; compare it on a run whose rods it fits, or change --pilot-points"
                )

    def rtols(self) -> tuple[float, ...]:
        """The rtol ladder of the adaptive candidates (:data:`COARSE_RTOLS` when not given)."""
        return COARSE_RTOLS if self.coarse_rtols is None else self.coarse_rtols

    def _check_rtols(self) -> None:
        """The adaptive candidates' rules (:class:`TuningError` naming what to change): a ladder
        only with a scheme that takes it, every rtol one that ``integrate.tolerances`` accepts,
        and m = 0 among the Richardson depths for a scheme that takes adaptive steps only
        (Richardson's weights, eq. 27, need the fixed steps r^q τ)."""
        adaptive = [s for s in self.schemes if takes_rtol(s)]
        if not adaptive:
            if self.coarse_rtols is not None:
                names = sorted(s for s in (*integrate.SCHEMES, integrate.AUTO.name)
                               if takes_rtol(s))
                raise TuningError(f"tune: coarse rtols {list(self.coarse_rtols)} given, but none "
                                  f"of the schemes {list(self.schemes)} takes adaptive steps; "
                                  f"add one of {names} to the schemes, or drop the rtols")
            return
        if not self.rtols():
            raise TuningError("tune: nothing to choose from in coarse_rtols; give at least one "
                              "value (or leave the option out for its default)")
        for rtol in self.rtols():
            try:
                integrate.tolerances(adaptive[0], rtol, None)
            except ValueError as error:
                raise TuningError(f"tune: coarse rtol {rtol!r}: {error}") from None
            if not rtol < 1.0:
                raise TuningError(f"tune: coarse rtol {rtol:g} must lie below 1 (a relative "
                                  "error per step); give smaller coarse rtols")
        only = [s for s in adaptive if adaptive_only(s)]
        if only and 0 not in self.richardson:
            raise TuningError(f"tune: the schemes {only} take adaptive steps only, and "
                              "Richardson extrapolation needs the fixed steps r^q τ of eq. 26: "
                              f"the Richardson depths {list(self.richardson)} leave them no "
                              "candidate; add 0 to the Richardson depths, or drop those schemes")

    def subsets(self, params: Mapping[str, float]) -> list[tuple[str, ...]]:
        """None, then the first parameter with every combination of the others (Table 5 G³
        extrapolates in (ε, a) without μ, G¹ in all three)."""
        order = self.parameters
        if order is None:
            order = tuple(name for name in params if name in DIRECTION)
            order = tuple(sorted(order, key=lambda n: n != "epsilon"))
        if not order:
            return [()]
        rest = order[1:]
        return [()] + [(order[0], *combo) for k in range(len(rest) + 1)
                       for combo in itertools.combinations(rest, k)]

    def candidates(self, params: Mapping[str, float],
                   reach: Mapping[str, tuple[tuple[float, ...], float]] | None = None,
                   ) -> Iterator[Settings]:
        """Every structure of the space (without step), plain solvers first; ``reach`` is the
        node table (:func:`reach_table`, default :data:`REACH`). A scheme gives fixed-step
        candidates (one per step fraction) unless it takes adaptive steps only, and adaptive
        ones (one per rtol of the ladder, m = 0) when it takes adaptive steps only, or takes
        rtol and the ladder is given."""
        reach = REACH if reach is None else reach
        seen: set[Settings] = set()
        for scheme, subset, m, grid in itertools.product(
            self.schemes, self.subsets(params), self.richardson, self.grid_factors
        ):
            r = self.r if m else None
            if not subset:
                found = [Settings(scheme, (), m, r, grid)]
            else:
                found = [
                    Settings(
                        scheme,
                        tuple(
                            (name, nodes_for(name, params[name], reach[name][0][level],
                                             count if i == 0 else min(count, 3),
                                             reach[name][1]))
                            for i, name in enumerate(subset)
                        ),
                        m,
                        r,
                        grid,
                        reach=level,
                    )
                    for level, count in itertools.product(self.reach, self.nodes)
                ]
            fixed = not adaptive_only(scheme)
            laddered = not fixed or (self.coarse_rtols is not None and takes_rtol(scheme))
            rtols = self.rtols() if laddered and m == 0 else ()
            for settings in found:
                if any(v <= 0.0 for _, values in settings.lagrange for v in values):
                    continue  # nodes below θ⁰ that reach zero: not a physical system
                items = ([replace(settings, step_fraction=f) for f in self.step_fractions]
                         if fixed else [])
                items += [replace(settings, rtol=rtol) for rtol in rtols]
                for item in items:
                    if item not in seen:
                        seen.add(item)
                        yield item


def parse_space(options: Mapping[str, Any], base: Space | None = None) -> Space:
    """A :class:`Space` from a mapping of its field names (the ``[tune]`` table or CLI flags)."""
    base = base or Space()
    values: dict[str, Any] = {}
    for key, value in options.items():
        if value is None:
            continue
        if key not in Space.__dataclass_fields__ or key in ("extra", "leading"):
            raise TuningError(f"tune: unknown option {key!r}")
        if isinstance(value, Sequence) and not isinstance(value, str):
            value = tuple(value)
        values[key] = value
    return replace(base, **values)


def settings_from_config(cfg: Any, resolved: Any, name: str | None = None) -> Settings:
    """The coarse solver of a validated configuration (``config.load``), with its own step."""
    coarse = cfg.coarse
    if coarse.kind != "extrapolated":
        raise TuningError(f"tune compares extrapolated coarse solvers; {name or 'this'} "
                          f"configuration's is of the family {coarse.kind!r}")
    m, r = coarse.richardson.m, coarse.richardson.r
    return Settings(
        coarse.scheme,
        tuple((name, tuple(values)) for name, values in resolved.lagrange.items()),
        m,
        r if m else None,
        coarse.grid_factor,
        dt=resolved.coarse_base_dt,
        name=name,
        rtol=coarse.rtol,
        atol=coarse.atol,
    )
