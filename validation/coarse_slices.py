"""Why the quick runs of Table 5 G^1, G^2, Table 7 G^1, G^2 and Table 8 G^1-G^3 blew up.

The extrapolated coarse solvers of these tables combine 24-36 auxiliary forward-Euler solvers, each
run close to its own step limit, with Lagrange weights of total size sum |w_j| up to 1.7e5. This
script measures, for docs/validation.md ("Where our runs of the paper's coarse solvers differ"):

1. step limits: the largest stable Euler step of G_{Theta^0} and of the most restrictive node
   Theta^j of each coarse solver (smallest epsilon, largest modulus, smallest viscosity), against
   the step the paper gives it. Rods (the quick rod, M = 61, sigma_f = 0.2): by bisection,
   ``integrate.largest_stable_step`` over 4e-3 s. Vesicle: 2/lambda_max, lambda_max the largest
   eigenvalue magnitude of the linearization J = M(X0) K / mu at the initial sphere (Stokeslet
   matrix M of eq. 6, spring stiffness matrix K of (14) at rest length, exact since J scales as
   kappa / mu at fixed epsilon); checked against a bisection for Theta^0 of Table 7.
2. the scalar model of the stiffest mode (vesicle): the combination sum_j w_j sum_q v_q
   (1 - h_q lambda_j)^(n_q) over one slice, next to G_{Theta^0}'s (1 - h lambda_0)^n;
3. the linearized combined coarse map DG over one slice on position perturbations: its spectral
   radius rho (growth per slice under repeated coarse steps) and, for the rods, its norm
   (``validation.map_norm``: the whole finite-difference Jacobian for the rods, ARPACK for the
   vesicle; the vesicle's norm from its whole Jacobian with ``--dense-norms``, :func:`dense_map`,
   merged into the saved JSON), for the former quick slices and for the paper's slice T/N_c,
   with rho of its two extreme auxiliary solvers for comparison;
4. the initial coarse sweep: the stability monitor of every combined state X_n^0 (the blow-up check
   of ``integrate`` runs inside each auxiliary solver, not on the combination), for the former quick
   slices and the paper's slices, on the quick rod and on the paper's M = 301 rod.

Usage (from the repository root): ``python -m validation.coarse_slices [--out DIR]``; about 10 min
on two shared cores. Writes ``OUT/coarse_slices.json`` and prints the tables.
"""

from __future__ import annotations

import argparse
import itertools
import json
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import scipy.linalg

from parastokes import config, integrate, models, parareal
from parastokes.coarse.extrapolated import Extrapolated
from parastokes.config.build import build_coarse, build_system
from validation import map_norm
from validation.quick_errors import perturbed
from validation.report import print_claims, toml_values, write_results

ROOT = Path(__file__).resolve().parents[1]
EXPERIMENTS = ROOT / "experiments"

#: Configurations, the slice length of the former quick variant, and the paper's T / N_c.
CASES = {
    "table5_g1": (1e-3, 0.025),
    "table5_g2": (1e-3, 0.025),
    "table7_g1": (0.125, 2.5),
    "table7_g2": (0.125, 2.5),
    "table8_g1": (0.25, 2.5),
    "table8_g2": (0.25, 2.5),
    "table8_g3": (0.25, 2.5),
}
#: Quick variants that were not failing (multi-parameter Lagrange): ||DG|| over their quick slices.
CONTROLS = {
    "table3_g2": 1e-3,
    "table4_g1": 1e-3,
    "table4_g2": 1e-3,
    "table4_g3": 1e-3,
    "table5_g3": 1e-3,
    "table7_g3": 0.125,
}


def load(name: str, t1: float | None = None, n_slices: int = 4, quick: bool = True,
         sets: Sequence[str] = ()):
    """(cfg, resolved, system, coarse) of an experiment, optionally with other slices and other
    ``sets`` (``KEY=VALUE`` as ``parastokes run --set`` takes them)."""
    path = EXPERIMENTS / ("quick" if quick else "") / f"{name}.toml"
    slices = [] if t1 is None else [f"time.t1={t1}", f"parareal.n_slices={n_slices}"]
    cfg, resolved = config.load(path, [*slices, *sets])
    system = build_system(cfg, resolved)
    return cfg, resolved, system, build_coarse(cfg, resolved, system)


def restrictive_node(resolved) -> dict[str, float]:
    """The node set's most restrictive Theta^j: smallest epsilon and viscosity, largest modulus."""
    theta = dict(resolved.theta0)
    for name, nodes in resolved.lagrange.items():
        theta[name] = max(nodes) if name in ("bending", "stiffness") else min(nodes)
    return theta


# ---- 1. step limits ----------------------------------------------------------------------------
def rod_limits(log, full_rod: bool = False) -> list[dict]:
    """Largest stable Euler steps (units of tau_f) of the quick rod (M = 61, over 4e-3 s) for
    Theta^0 and each coarse solver's most restrictive node; with ``full_rod`` also Table 5's on
    the paper's M = 301 rod (over 2e-3 s)."""
    rows = []
    cases = [
        ("Fig. 3, eps^1 = 5.1 sigma_f", {"epsilon": 5.1 * 0.2}, 61, 10.0),
        ("Fig. 3, eps^1 = 5.6 sigma_f", {"epsilon": 5.6 * 0.2}, 61, 18.0),
        ("Table 4 Theta^0 (G^4)", {"epsilon": 5 * 0.2}, 61, 10.0),
    ]
    for name in ("table4_g1", "table4_g2", "table4_g3", "table5_g1", "table5_g2", "table5_g3"):
        _, resolved = config.load(EXPERIMENTS / "quick" / f"{name}.toml")
        ratio = resolved.coarse_base_dt / resolved.fine_dt  # tau = tau_c / r^m, the largest step
        for m in (61, 301) if full_rod and name in ("table5_g1", "table5_g2") else (61,):
            if name == "table5_g1":
                cases.append(("Table 5 Theta^0", dict(resolved.theta0), m, float("nan")))
            cases.append((f"{name} node", restrictive_node(resolved), m, ratio))
    for label, theta, m, ratio in cases:
        base = models.rod_swimmer(n_points=m, length=0.2 * (m - 1), epsilon=1.0)
        span = 4e-3 if m == 61 else 2e-3
        system = base.with_params(**theta)
        limit = integrate.largest_stable_step(system, "euler", span, 2e-6, 2e-4, rtol=0.02) / 1e-6
        rows.append(
            {
                "case": label,
                "n_points": m,
                "epsilon/sigma_f": theta["epsilon"] / base.ds,
                "bending": theta.get("bending", 1.0),
                "viscosity/mu0": theta.get("viscosity", 1e-6) / 1e-6,
                "limit/tau_f": limit,
                "paper_step/tau_f": ratio,
                "fraction": ratio / limit,
            }
        )
        log(f"rod limit {label} (M = {m}): {limit:.1f} tau_f, paper step {ratio:.3g} tau_f")
    return rows


class VesicleSpectrum:
    """lambda_max of J = M K / mu for the quick vesicle (eq. 6 Stokeslets, (14) springs)."""

    def __init__(self) -> None:
        self.system = models.vesicle()
        x = self.system.initial_state()
        n = len(x)
        self.l_max = self.system.epsilon / 0.3
        edges = self.system.edges
        # -K = B B^T with one column per spring: d_hat at node i, -d_hat at node j
        b = np.zeros((3 * n, len(edges)))
        for e, (i, j) in enumerate(edges):
            d = (x[j] - x[i]) / np.linalg.norm(x[j] - x[i])
            b[3 * i : 3 * i + 3, e] = d
            b[3 * j : 3 * j + 3, e] = -d
        self.b = b
        self.x = x
        self.cache: dict[float, float] = {}

    def mobility(self, epsilon: float) -> np.ndarray:
        r = self.x[:, None, :] - self.x[None, :, :]
        r2 = (r**2).sum(-1)
        re3 = (r2 + epsilon**2) ** 1.5
        h1 = (r2 + 2 * epsilon**2) / (8 * np.pi * re3)
        h2 = 1 / (8 * np.pi * re3)
        blocks = h1[:, :, None, None] * np.eye(3) + h2[:, :, None, None] * (
            r[:, :, :, None] * r[:, :, None, :]
        )
        n = len(self.x)
        return blocks.transpose(0, 2, 1, 3).reshape(3 * n, 3 * n)

    def unit(self, epsilon: float) -> float:
        """lambda_max for kappa = mu = 1 (lambda scales as kappa / mu)."""
        key = round(epsilon, 12)
        if key not in self.cache:
            s = self.b.T @ self.mobility(epsilon) @ self.b  # same nonzero spectrum as M (-K)
            top = len(s) - 1  # the largest eigenvalue only (a third of the time of all of them)
            self.cache[key] = float(scipy.linalg.eigvalsh(s, subset_by_index=[top, top])[0])
        return self.cache[key]

    def lam(self, theta: dict[str, float]) -> float:
        return self.unit(theta["epsilon"]) * theta["stiffness"] / theta["viscosity"]


def vesicle_limits(spectrum: VesicleSpectrum, log) -> list[dict]:
    rows = []
    seen = set()
    for name in (
        "table7_g1",
        "table7_g2",
        "table7_g3",
        "table7_g4",
        "table8_g1",
        "table8_g2",
        "table8_g3",
    ):
        _cfg, resolved = config.load(EXPERIMENTS / "quick" / f"{name}.toml")
        tau_f = resolved.fine_dt
        key = (name[:6], tau_f)
        if key not in seen:
            seen.add(key)
            lam0 = spectrum.lam(resolved.theta0)
            rows.append(
                {
                    "case": f"{name[:6]} Theta^0",
                    "lambda_max": lam0,
                    "limit/tau_f": 2 / lam0 / tau_f,
                    "paper_step/tau_f": float("nan"),
                    "fraction": float("nan"),
                }
            )
        theta = restrictive_node(resolved) if resolved.lagrange else resolved.theta0
        lam = spectrum.lam(theta)
        ratio = resolved.coarse_base_dt / tau_f
        limit = 2 / lam / tau_f
        rows.append(
            {
                "case": f"{name} node" if resolved.lagrange else f"{name} (Theta^0)",
                "lambda_max": lam,
                "limit/tau_f": limit,
                "paper_step/tau_f": ratio,
                "fraction": ratio / limit,
            }
        )
        log(f"vesicle limit {rows[-1]['case']}: {limit:.2f} tau_f, paper step {ratio:.3g} tau_f")
    return rows


def vesicle_bisection_check(log) -> dict:
    """The linearized limit against a bisection, for Table 7's Theta^0 (over 0.5 s)."""
    system = models.vesicle()
    limit = integrate.largest_stable_step(system, "euler", 0.5, 1e-3, 1e-2, rtol=0.02)
    log(f"vesicle Table 7 Theta^0 bisection: {limit / 1e-3:.2f} tau_f")
    return {"bisection/tau_f": limit / 1e-3}


# ---- 2. scalar model ---------------------------------------------------------------------------
def combination(name: str, span: float) -> dict:
    """The coarse solver of ``experiments/quick/NAME.toml`` over one slice of length ``span``:
    its auxiliary parameter sets ``thetas`` (Lagrange nodes, eq. 30), their weights ``w``, the
    Richardson steps actually taken (``used``, ``counts``) and their weights ``v`` (eq. 28), and
    ``sum_abs_weights`` = sum |w_j v_q|, the factor by which the combination can amplify."""
    cfg, resolved = config.load(EXPERIMENTS / "quick" / f"{name}.toml")
    names = list(resolved.lagrange)
    thetas = [
        dict(resolved.theta0, **dict(zip(names, combo, strict=True)))
        for combo in itertools.product(*(resolved.lagrange[n] for n in names))
    ]
    w = parareal.lagrange_weights(
        [resolved.theta0[n] for n in names], [resolved.lagrange[n] for n in names]
    ).ravel()
    coarse = cfg.coarse
    if not isinstance(coarse, Extrapolated):
        raise TypeError(f"{name}: the scalar model needs an extrapolated coarse solver")
    r = coarse.richardson
    steps = [resolved.coarse_base_dt * (r.r or 1.0) ** q for q in range(r.m + 1)]
    counts = [integrate.n_steps(0.0, span, h) for h in steps]
    used = [span / n for n in counts]
    v = parareal.step_weights(used, 1)
    return {"resolved": resolved, "thetas": thetas, "w": w, "v": v, "used": used,
            "counts": counts, "sum_abs_weights": float(np.abs(np.multiply.outer(w, v)).sum())}


def scalar_model(spectrum: VesicleSpectrum, name: str, span: float) -> dict:
    """The stiffest mode's factor over one slice: combined, G_{Theta^0}, largest auxiliary."""
    c = combination(name, span)
    resolved, thetas, w, v, used, counts = (
        c[k] for k in ("resolved", "thetas", "w", "v", "used", "counts")
    )
    lams = np.array([spectrum.lam(t) for t in thetas])
    combined = sum(
        wj * sum(vq * (1 - hq * lj) ** nq for vq, hq, nq in zip(v, used, counts, strict=True))
        for wj, lj in zip(w, lams, strict=True)
    )
    lam0 = spectrum.lam(resolved.theta0)
    return {
        "span": span,
        "steps": counts,
        "combined": float(combined),
        "auxiliary_max": float(np.abs(1 - used[0] * lams).max() ** counts[0]),
        "theta0": float((1 - used[0] * lam0) ** counts[0]),
        "sum_abs_weights": c["sum_abs_weights"],
    }


# ---- 3. amplification --------------------------------------------------------------------------
def amplification(name: str, span: float, seed: int = 0) -> dict:
    """The linearized map DG over one slice [0, span] from the initial state: its spectral radius
    rho ("combined"; the growth per slice of a perturbation) and, for the rods, its norm; also rho
    of the first and last auxiliary solver (``validation.map_norm``: the whole Jacobian for the
    rods, ARPACK for the vesicle)."""
    _, resolved, system, coarse = load(name)
    inner = getattr(coarse, "propagator", coarse)
    x0 = system.initial_state()

    def measure(propagator) -> dict:
        return map_norm.linearization(lambda x: propagator(0.0, span, x), system.positions, x0,
                                      seed)

    aux = [p for row in inner.auxiliary for p in row]
    combined = measure(inner)
    return {
        "span": span,
        "coarse_steps": integrate.n_steps(0.0, span, resolved.coarse_dt),
        "combined": combined["rho"],
        "norm": combined["norm"],
        "method": combined["method"],
        "calls": combined["calls"],
        "auxiliary": [measure(aux[0])["rho"], measure(aux[-1])["rho"]],
    }


def dense_map(name: str, span: float, sets: Sequence[str] = (),
              checkpoint: Path | None = None) -> dict:
    """rho(DG) and ‖DG‖ of the combined coarse map over [0, span] from its whole forward-difference
    Jacobian (``map_norm.dense_resumable``), whatever its size: for the vesicle (3M = 1926) 1927
    calls of G, with ``checkpoint`` (a ``.npy`` path) to resume; ``sets`` as in :func:`load` (e.g.
    ``model.subdivisions=1``, a 42-point vesicle, for a CI-sized twin)."""
    _, resolved, system, coarse = load(name, sets=sets)
    inner = getattr(coarse, "propagator", coarse)
    probe = map_norm.Probe(lambda x: inner(0.0, span, x), system.positions, system.initial_state())
    rho, norm = map_norm.dense_resumable(probe, checkpoint)
    return {"span": span, "coarse_steps": integrate.n_steps(0.0, span, resolved.coarse_dt),
            "rho_dense": rho, "norm": norm, "calls": probe.calls}


# ---- 4. initial sweep --------------------------------------------------------------------------
_SHORT, _PAPER = "former quick", "paper"
#: The initial sweeps of section 4 (``sweep``'s arguments: slices, name, T, N_c, quick rod), by
#: their name in ``[coarse_slices_more]``; ``rod301_*`` on the paper's M = 301 rod.
SWEEPS: dict[str, tuple[str, str, float, int, bool]] = {
    "rod61_former": (_SHORT, "table5_g1", 4e-3, 4, True),
    "rod61_paper": (_PAPER, "table5_g1", 0.1, 4, True),
    "vesicle_former": (_SHORT, "table7_g1", 0.5, 4, True),
    "vesicle_paper": (_PAPER, "table7_g1", 7.5, 3, True),
    "rod301_former": (_SHORT, "table5_g1", 4e-3, 4, False),
    "rod301_paper": (_PAPER, "table5_g1", 0.075, 3, False),
    "rod301_g2_paper": (_PAPER, "table5_g2", 0.075, 3, False),
    # Table 8 G^1: stable over the paper's slices, but X^0 leaves the area limit (reported apart)
    "table8_paper": ("paper, Table 8", "table8_g1", 5.0, 2, True),
}


def sweep(
    kind: str, name: str, t1: float, n_slices: int, quick: bool = True, perturb: float = 0.0
) -> dict:
    """Monitor of every combined X_n^0 and the largest auxiliary monitor, until a blow-up
    (``perturb``: the start's round-off perturbation of ``quick_errors.perturbed``)."""
    _cfg, resolved, system, coarse = load(name, t1, n_slices, quick)
    inner = getattr(coarse, "propagator", coarse)
    times = parareal.time_points(0.0, t1, n_slices)
    x = perturbed(system.initial_state(), perturb)
    combined, auxiliary, blowup = [], [], None
    for n in range(1, n_slices + 1):
        _steps, v = inner.plan(times[n - 1], times[n])
        coefficients = np.multiply.outer(inner.lagrange_weights, v).ravel()
        values, worst = [], 0.0
        try:
            for p in (p for row in inner.auxiliary for p in row):
                run = integrate.run(p.system, x, times[n - 1], times[n], p.scheme, p.dt)
                values.append(run.state)
                worst = max(worst, run.max_monitor)
        except integrate.BlowUpError as exc:
            blowup = {"slice": n, "t": exc.t, "monitor": exc.monitor}
            break
        x = system.project(sum(c * g for c, g in zip(coefficients, values, strict=True)))
        combined.append(system.monitor(x))
        auxiliary.append(worst)
    return {
        "slices": kind,
        "name": name,
        "n_points": resolved.n_points,
        "slice": t1 / n_slices,
        "coarse_steps": resolved.coarse_steps,
        "limit": system.monitor_limit,
        "combined": combined,
        "auxiliary": auxiliary,
        "blowup": blowup,
    }


def run_all(log=print, full_rod: bool = True) -> dict:
    start = time.perf_counter()
    spectrum = VesicleSpectrum()
    results: dict = {"rod_limits": rod_limits(log, full_rod)}
    results["vesicle_limits"] = vesicle_limits(spectrum, log)
    results["vesicle_bisection"] = vesicle_bisection_check(log)
    results["scalar_model"] = {
        name: [scalar_model(spectrum, name, s) for s in CASES[name]]
        for name in CASES
        if name.startswith(("table7", "table8"))
    }
    results["amplification"] = {}
    for name, spans in CASES.items():
        results["amplification"][name] = [amplification(name, s) for s in spans]
        log(
            f"||DG|| {name}: "
            + ", ".join(
                f"{a['coarse_steps']} steps {a['combined']:.3g}"
                for a in results["amplification"][name]
            )
        )
    results["controls"] = {name: amplification(name, s) for name, s in CONTROLS.items()}
    results["sweeps"] = [
        sweep(*args) for key, args in SWEEPS.items() if full_rod or not key.startswith("rod301")
    ]
    for s in results["sweeps"]:
        log(
            f"sweep {s['slices']} {s['name']} M={s['n_points']} slice {s['slice']:g}: combined "
            f"{[f'{m:.2e}' for m in s['combined']]} blow-up {s['blowup']}"
        )
    results["runtime_s"] = time.perf_counter() - start
    results["claims"] = claims(results)
    return results


def claims(results: dict) -> dict[str, bool]:
    """The statements of docs/validation.md, evaluated on the numbers."""
    amp = results["amplification"]
    paper_fractions = [
        r["fraction"]
        for r in results["rod_limits"] + results["vesicle_limits"]
        if r["fraction"] == r["fraction"]
    ]
    v0 = next(r for r in results["vesicle_limits"] if r["case"] == "table7 Theta^0")
    short = [s for s in results["sweeps"] if s["slices"] == "former quick"]
    long = [s for s in results["sweeps"] if s["slices"] == "paper"]
    return {
        "every auxiliary step of the paper lies below its own limit (fraction < 1)": max(
            paper_fractions
        )
        < 1.0,
        "and close to it, as the paper says (fraction > 0.7)": min(paper_fractions) > 0.7,
        "linearized vesicle limit agrees with the bisection within 5%": abs(
            results["vesicle_bisection"]["bisection/tau_f"] / v0["limit/tau_f"] - 1
        )
        < 0.05,
        "over the former quick slices rho(DG) of the combined map is at least 5": min(
            a[0]["combined"] for a in amp.values()
        )
        > 5,
        "over the paper's slices it is below 1.3": max(
            a[1]["combined"] for a in amp.values()
        )
        < 1.3,
        "rho(DG) of every auxiliary solver alone is below 1.3": max(
            max(x["auxiliary"]) for a in amp.values() for x in a
        )
        < 1.3,
        "the non-failing rod quick variants have rho(DG) below 1.3 over their slices": max(
            c["combined"] for n, c in results["controls"].items() if n != "table7_g3"
        )
        < 1.3,
        "Table 7 G^3 (one parameter): rho(DG) about 2 over its quick slice": 1.5
        < results["controls"]["table7_g3"]["combined"]
        < 3,
        "scalar model: combined factor > 1 over the former quick slices": all(
            abs(m[0]["combined"]) > 1 for m in results["scalar_model"].values()
        ),
        "scalar model: combined factor < 1 over the paper's slices": all(
            abs(m[1]["combined"]) < 1 for m in results["scalar_model"].values()
        ),
        "former quick slices: the initial sweep leaves the limit or blows up": all(
            s["blowup"] or max(s["combined"]) > s["limit"] for s in short
        ),
        "paper's slices: the initial sweep of the rods and Table 7 G^1 stays within the limit": all(
            not s["blowup"] and max(s["combined"]) < s["limit"] for s in long
        ),
    }


#: The rows of the page's vesicle table (``vesicle_limits`` cases).
VESICLE_ROWS = (
    "table7_g4 (Theta^0)",
    "table7_g1 node",
    "table7_g2 node",
    "table7_g3 node",
    "table8 Theta^0",
    "table8_g1 node",
    "table8_g2 node",
    "table8_g3 node",
)


def documented_numbers(results: dict) -> dict[str, list[float] | float]:
    """The numbers docs/validation.md section 2 prints from ``results``: the group
    ``coarse_slices`` of docs/numbers.toml, in the order of the page's tables (NaN where a row has
    no paper step)."""
    rods = [r for r in results["rod_limits"] if r["n_points"] == 61]
    # the page's first vesicle row is Table 7's Theta^0 with G^4's step
    by_case = {r["case"]: r for r in results["vesicle_limits"]}
    vesicles = [by_case[c] for c in VESICLE_ROWS]
    amp = results["amplification"]
    scalar = [m for name in CASES if name in results["scalar_model"]
              for m in results["scalar_model"][name]]
    return {
        "rod_limit": [r["limit/tau_f"] for r in rods],
        "rod_fraction": [r["fraction"] for r in rods],
        "rod_limit_m301": [r["limit/tau_f"] for r in results["rod_limits"] if r["n_points"] == 301],
        "vesicle_lambda": [r["lambda_max"] for r in vesicles],
        "vesicle_limit": [r["limit/tau_f"] for r in vesicles],
        "vesicle_fraction": [r["fraction"] for r in vesicles],
        "vesicle_bisection": results["vesicle_bisection"]["bisection/tau_f"],
        "dg_former": [amp[name][0]["combined"] for name in CASES],
        "dg_paper": [amp[name][1]["combined"] for name in CASES],
        "dg_norm_former": [amp[name][0].get("norm", float("nan")) for name in CASES],
        "dg_norm_paper": [amp[name][1].get("norm", float("nan")) for name in CASES],
        "dg_auxiliary_min": [min(min(a["auxiliary"]) for a in amp[name]) for name in CASES],
        "dg_auxiliary_max": [max(max(a["auxiliary"]) for a in amp[name]) for name in CASES],
        "dg_controls": [results["controls"][name]["combined"] for name in CONTROLS],
        "scalar_combined": [m["combined"] for m in scalar],
        "scalar_auxiliary": [m["auxiliary_max"] for m in scalar],
        "scalar_theta0": [m["theta0"] for m in scalar],
    }


def amplifications(names: Sequence[str], log=print) -> dict:
    """Section 3 alone: ``{"amplification": ..., "controls": ...}`` for ``names`` (of CASES and
    CONTROLS)."""
    found: dict = {"amplification": {}, "controls": {}}
    for name in names:
        if name in CASES:
            found["amplification"][name] = [amplification(name, s) for s in CASES[name]]
        if name in CONTROLS:
            found["controls"][name] = amplification(name, CONTROLS[name])
        found_here = found["amplification"].get(name, []) + [found["controls"].get(name, {})]
        log(f"rho(DG) {name}: " + ", ".join(f"{a['coarse_steps']} steps {a['combined']:.6g}"
                                            for a in found_here if a))
    return found


def merge(results: dict, parts: Sequence[dict]) -> dict:
    """``results`` with the section-3 entries of ``parts`` replaced, claims re-evaluated (keeps the
    saved order of the cases)."""
    for part in parts:
        for key in ("amplification", "controls"):
            results[key].update(part[key])
    results["claims"] = claims(results)
    return results


def main(argv: Sequence[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "figures")
    parser.add_argument("--no-full-rod", action="store_true", help="skip the M = 301 sweeps")
    parser.add_argument(
        "--amplification-only", nargs="*", metavar="NAME",
        help="recompute section 3 only (for NAMEs of CASES/CONTROLS, default all) and merge it "
        "into the saved OUT/coarse_slices.json",
    )
    parser.add_argument(
        "--dense-norms", nargs="+", metavar="NAME",
        help="‖DG‖ over the former quick slice of CASES NAME (the vesicle's) from the whole "
        "Jacobian (1927 calls of G each, 7 to 21 min on one shared core), "
        "merged into the saved OUT/coarse_slices.json",
    )
    parser.add_argument("--checkpoints", type=Path, default=None,
                        help="with --dense-norms: keep the Jacobians' columns in "
                        "DIR/NAME_former.npy and resume from them")
    args = parser.parse_args(argv)
    path = args.out / "coarse_slices.json"
    if args.dense_norms:
        unknown = sorted(set(args.dense_norms) - set(CASES))
        if unknown:
            parser.error(f"--dense-norms: unknown {unknown}; choose from {list(CASES)}")
        results = json.loads(path.read_text())
        for name in args.dense_norms:
            where = args.checkpoints / f"{name}_former.npy" if args.checkpoints else None
            found = dense_map(name, CASES[name][0], checkpoint=where)
            former = results["amplification"][name][0]
            former.update(norm=found["norm"], rho_dense=found["rho_dense"])
            print(f"{name}: ‖DG‖ {found['norm']:.6g}, rho {found['rho_dense']:.6g} "
                  f"({found['calls']} calls)")
    elif args.amplification_only is not None:
        names = args.amplification_only or [*CASES, *CONTROLS]
        unknown = sorted(set(names) - set(CASES) - set(CONTROLS))
        if unknown:
            parser.error(f"--amplification-only: unknown {unknown}; choose from "
                         f"{[*CASES, *CONTROLS]}")
        start = time.perf_counter()
        results = merge(json.loads(path.read_text()), [amplifications(names)])
        results["amplification_runtime_s"] = time.perf_counter() - start
    else:
        results = run_all(full_rod=not args.no_full_rod)
    write_results(results, path)
    print_claims(results)
    print(f"[coarse_slices] values:\n{toml_values(documented_numbers(results))}")
    print(f"written to {path}")
    return results


if __name__ == "__main__":
    main()
