"""Extrapolated coarse solvers on a shortened rod: the analogues of Figs. 3 and 5 of the paper.

Section 5.1.1 of the paper runs one swimmer of 301 nodes (sigma_f = 0.2, L = 60) up to T = 1 on 40
slices with tau_f = 1e-6. That is far beyond two shared cores, so this script keeps what sets the
stiffness (the node spacing sigma_f = 0.2, epsilon^0 = 5 sigma_f, Table 2's moduli, the fine step
tau_f = 1e-6 of RK2) and shortens the rest: by default M = 61 nodes (L = 12), T = 1e-2 (a fifth of
a beat period 2 pi / f = 0.05) on N_c = 5 slices. Every coarse solver is forward Euler; every
coarse step divides a slice exactly.

- Fig. 3: for epsilon^1 / sigma_f in {5.1, 5.2, 5.4, 5.6} and epsilon^j = epsilon^1 + (j - 1) 0.05
  sigma_f (j = 1..4): tau_max, the largest Euler step that keeps the rod length within 1% over
  [0, T] with epsilon^1 alone (``integrate.largest_stable_step``); tau_c, the largest step at most
  ``margin`` tau_max at which the extrapolated solver sum_j w_j G_{epsilon^j, tau_c} keeps the
  limit through Parareal's initial sweep (:func:`within_limit`); and eta^1 (eq. 34) of Parareal
  with that solver. The same without the margin is recorded as the ``edge``. The plain solver
  G_{epsilon^0, tau} gets the same treatment for comparison.
- Fig. 5: eta^1 against N_epsilon at tau_c = 10 tau_f, epsilon^1 = 5.1 sigma_f, without (G^3 of
  Table 3) and with (G^4) Richardson extrapolation m = 1, r = 0.83; tau_c is then the smaller step
  r tau of G^4 (section 5.1), so its larger step is tau = tau_c / r. N_epsilon = 1 is the plain
  perturbed solver G_{epsilon^1, tau_c}; G_{epsilon^0, tau_c} is the reference line.

eta^1 needs one Parareal iteration per coarse solver against the serial fine solution (computed
once). Results go to ``OUT/rod_extrapolation[_quick].json`` and ``OUT/rod_fig3[_quick].png``,
``OUT/rod_fig5[_quick].png``; the qualitative claims of ``docs/validation.md`` are evaluated by
:func:`claims` (also run by ``tests/test_validation_script.py``).

Usage (from the repository root): ``python -m validation.rod_extrapolation [--quick] [--out DIR]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from parastokes import integrate, models, parareal
from parastokes.kinds.rod.system import RodSystem
from validation.report import print_claims, toml_values, write_results

__all__ = [
    "FULL",
    "QUICK",
    "Setup",
    "claims",
    "documented_numbers",
    "epsilon_nodes",
    "fig3",
    "fig5",
    "first_iteration",
    "main",
    "markdown_tables",
    "plot_fig3",
    "plot_fig5",
    "reference_solution",
    "run_all",
    "within_limit",
]


@dataclass(frozen=True)
class Setup:
    """The shortened run. Lengths in μm, times in s; epsilons in units of sigma_f = L / (M - 1)."""

    n_points: int = 61
    length: float = 12.0
    epsilon0: float = 5.0
    tau_f: float = 1e-6
    t_end: float = 1e-2
    n_slices: int = 5
    fig3_epsilon1: tuple[float, ...] = (5.1, 5.2, 5.4, 5.6)
    fig3_n_nodes: int = 4
    node_spacing: float = 0.05
    fig5_epsilon1: float = 5.1
    fig5_tau_ratio: float = 10.0
    fig5_n_nodes: tuple[int, ...] = (1, 2, 3, 4, 5, 6)
    richardson_r: float = 0.83
    #: Bracket of the stability bisection in units of tau_f, and its relative width.
    search: tuple[float, float] = (5.0, 40.0)
    search_rtol: float = 0.01
    #: Fig. 3's tau_c is at most ``margin`` times the largest stable step (see docs/validation.md).
    margin: float = 0.95

    @property
    def sigma_f(self) -> float:
        """Node spacing sigma_f = Δs."""
        return self.length / (self.n_points - 1)

    @property
    def slice_length(self) -> float:
        """ΔT = T / N_c."""
        return self.t_end / self.n_slices

    def rod(self) -> RodSystem:
        """The swimmer (Table 2 values) with M nodes, length L and epsilon^0 sigma_f."""
        return models.rod_swimmer(
            n_points=self.n_points, epsilon=self.epsilon0 * self.sigma_f, length=self.length
        )


#: The shortened run reported in docs/validation.md (about 4 minutes on two shared cores).
FULL = Setup()
#: A half-minute version (31 nodes, T = 2e-3 on 2 slices) for the tests and smoke runs. Its slices
#: hold fewer coarse steps, so it needs a wider margin below the stability edge (see the report).
QUICK = Setup(n_points=31, length=6.0, t_end=2e-3, n_slices=2, fig5_n_nodes=(1, 4), margin=0.9)


def epsilon_nodes(setup: Setup, epsilon1: float, count: int) -> list[float]:
    """epsilon^j = epsilon^1 + (j - 1) 0.05 sigma_f for j = 1..count, absolute (μm)."""
    return [(epsilon1 + j * setup.node_spacing) * setup.sigma_f for j in range(count)]


def _largest_stable_step(setup: Setup, epsilon: float) -> float:
    """Largest forward-Euler step keeping the 1% length limit over [0, T] with this ε."""
    lo, hi = (factor * setup.tau_f for factor in setup.search)
    return integrate.largest_stable_step(
        setup.rod().with_params(epsilon=epsilon),
        "euler",
        setup.t_end,
        lo,
        hi,
        rtol=setup.search_rtol,
    )


def within_limit(setup: Setup, coarse: parareal.Extrapolated) -> bool:
    """Whether the serial sweep of ``coarse`` (Parareal's initial sweep X^0) keeps the 1% limit.

    Checked after every step of every auxiliary solver on every slice, and on the combined state
    X^0_n at every T_n; a blow-up counts as a failure.
    """
    rod = setup.rod()
    auxiliary = [p for row in coarse.auxiliary for p in row]
    times = parareal.time_points(0.0, setup.t_end, setup.n_slices)
    x = rod.initial_state()
    try:
        for t_start, t_end in itertools.pairwise(times):
            worst = max(
                integrate.run(p.system, x, t_start, t_end, p.scheme, p.dt).max_monitor
                for p in auxiliary
            )
            x = coarse(t_start, t_end, x)
            if max(worst, rod.monitor(x)) > rod.monitor_limit:
                return False
    except integrate.BlowUpError:
        return False
    return True


def _largest_coarse_step(setup: Setup, build, dt_max: float) -> float:
    """Largest step tau <= ``dt_max`` dividing a slice with ``within_limit(build(tau))``.

    Tries ΔT / n for n = ceil(ΔT / dt_max), n + 1, ... (at most twice the first n).
    """
    first = math.ceil(setup.slice_length / dt_max * (1 - 1e-12))
    for n in range(first, 2 * first + 1):
        if within_limit(setup, build(setup.slice_length / n)):
            return setup.slice_length / n
    raise RuntimeError(f"no coarse step in [{dt_max / 2:g}, {dt_max:g}] keeps the length limit")


def reference_solution(setup: Setup) -> np.ndarray:
    """The serial fine solution (RK2, tau_f, epsilon^0) at T_0..T_N: the x^F of eq. 34."""
    rod = setup.rod()
    fine = integrate.Propagator(rod, "rk2", setup.tau_f)
    return parareal.serial_solution(fine, rod.initial_state(), 0.0, setup.t_end, setup.n_slices)


def first_iteration(setup: Setup, coarse, reference: np.ndarray) -> dict:
    """One Parareal iteration with ``coarse``: eta^1, eta~^1 and the largest relative length
    change of the first iterate X^1 at T_1..T_N (it must stay within the 1% limit)."""
    rod = setup.rod()
    fine = integrate.Propagator(rod, "rk2", setup.tau_f)
    res = parareal.run(
        fine,
        coarse,
        rod.initial_state(),
        0.0,
        setup.t_end,
        setup.n_slices,
        tol=0.0,
        max_iterations=1,
        reference=reference,
        positions=rod.positions,
        project=rod.project,
    )
    monitor = max(rod.monitor(x) for x in res.states[1:])
    assert res.errors is not None  # (run with a reference)
    return {"eta1": res.errors[0], "increment1": res.increments[0], "max_monitor": monitor}


def _euler(rod: RodSystem, tau: float, **options) -> parareal.Extrapolated:
    """``parareal.extrapolated`` with Euler on the fine grid (no ``grid``: never OnCoarseGrid)."""
    solver = parareal.extrapolated(rod, "euler", tau, **options)
    assert isinstance(solver, parareal.Extrapolated)
    return solver


def _assess(setup: Setup, coarse: parareal.Extrapolated, reference: np.ndarray) -> dict:
    """:func:`within_limit` and :func:`first_iteration` of one coarse solver."""
    return {
        "within_limit": within_limit(setup, coarse),
        **first_iteration(setup, coarse, reference),
    }


def _steps_and_errors(setup: Setup, build, dt_max: float, reference: np.ndarray) -> dict:
    """tau_c at the edge (largest dividing step <= ``dt_max`` within the limit) and with the margin
    (the same below ``margin * dt_max``), with eta^1 of ``build(tau_c)`` at both."""
    edge = _largest_coarse_step(setup, build, dt_max)
    tau_c = _largest_coarse_step(setup, build, setup.margin * dt_max)
    return {
        "tau_max_over_tau_f": dt_max / setup.tau_f,
        "edge": {
            "tau_c_over_tau_f": edge / setup.tau_f,
            **first_iteration(setup, build(edge), reference),
        },
        "tau_c_over_tau_f": tau_c / setup.tau_f,
        **first_iteration(setup, build(tau_c), reference),
    }


def fig3(setup: Setup, reference: np.ndarray, log=print) -> dict:
    """Largest stable tau_c and eta^1 against epsilon^1 (Fig. 3), plus the plain G_{eps^0, tau}.

    tau_max is the limit of the auxiliary solver with epsilon^1 alone (from the initial state,
    ``integrate.largest_stable_step``). tau_c is the largest step dividing a slice, at most
    ``margin * tau_max``, at which the extrapolated solver keeps the limit (:func:`within_limit`);
    the ``edge`` entries are the same without the margin.
    """
    rod = setup.rod()

    def plain(tau: float) -> parareal.Extrapolated:
        return _euler(rod, tau)

    plain_row = _steps_and_errors(setup, plain, _largest_stable_step(setup, rod.epsilon), reference)
    log(f"fig3 plain eps0: {_summary(plain_row)}")
    rows = []
    for factor in setup.fig3_epsilon1:
        nodes = epsilon_nodes(setup, factor, setup.fig3_n_nodes)

        def lagrange(tau: float, nodes=nodes) -> parareal.Extrapolated:
            return _euler(rod, tau, lagrange={"epsilon": nodes})

        row = {
            "epsilon1_over_sigma_f": factor,
            "nodes_over_sigma_f": [eps / setup.sigma_f for eps in nodes],
            "sum_abs_weights": float(np.abs(parareal.lagrange_weights(rod.epsilon, nodes)).sum()),
            **_steps_and_errors(setup, lagrange, _largest_stable_step(setup, nodes[0]), reference),
        }
        row["plain_within_limit_at_tau_c"] = within_limit(
            setup, plain(row["tau_c_over_tau_f"] * setup.tau_f)
        )
        log(f"fig3 eps1={factor}: {_summary(row)}")
        rows.append(row)
    return {"plain": plain_row, "rows": rows}


def _summary(row: dict) -> str:
    """One log line for a Fig. 3 entry."""
    return (
        f"tau_max/tau_f={row['tau_max_over_tau_f']:.2f} "
        f"tau_c/tau_f={row['tau_c_over_tau_f']:.2f} eta1={row['eta1']:.3e} "
        f"(edge {row['edge']['tau_c_over_tau_f']:.2f}: {row['edge']['eta1']:.3e})"
    )


def fig5(setup: Setup, reference: np.ndarray, log=print) -> dict:
    """eta^1 against N_epsilon with (G^4) and without (G^3) Richardson m = 1 (Fig. 5)."""
    rod = setup.rod()
    tau_c = setup.fig5_tau_ratio * setup.tau_f
    r = setup.richardson_r
    plain = _assess(setup, _euler(rod, tau_c), reference)
    log(f"fig5 plain eps0: eta1={plain['eta1']:.3e}")
    rows = []
    for count in setup.fig5_n_nodes:
        nodes = epsilon_nodes(setup, setup.fig5_epsilon1, count)
        lagrange = {"epsilon": nodes}
        g3 = _euler(rod, tau_c, lagrange=lagrange)
        g4 = _euler(
            rod, tau_c / r, lagrange=lagrange, richardson={"m": 1, "r": r}
        )
        steps, weights = g4.plan(0.0, setup.slice_length)
        row = {
            "n_nodes": count,
            "nodes_over_sigma_f": [eps / setup.sigma_f for eps in nodes],
            "lagrange": _assess(setup, g3, reference),
            "richardson": _assess(setup, g4, reference),
            "richardson_steps_over_tau_f": (steps / setup.tau_f).tolist(),
            "richardson_weights": weights.tolist(),
        }
        log(
            f"fig5 N_eps={count}: eta1 G3={row['lagrange']['eta1']:.3e} "
            f"G4={row['richardson']['eta1']:.3e}"
        )
        rows.append(row)
    return {"tau_c_over_tau_f": setup.fig5_tau_ratio, "plain": plain, "rows": rows}


def claims(results: dict) -> dict[str, bool]:
    """The qualitative statements of docs/validation.md, evaluated on ``results``.

    - every coarse solver used keeps the 1% length limit (Fig. 3's by construction of tau_c,
      Fig. 5's checked), and so does every first iterate X^1;
    - Fig. 3: tau_c grows strictly with epsilon^1, starting above the plain G_{eps^0}'s; the plain
      solver breaks the limit at the tau_c of the largest epsilon^1; eta^1 is larger at the
      largest epsilon^1 than at the smallest; at the edge (no margin) eta^1 is at least 100 times
      larger than with the margin, for the plain and every extrapolated solver;
    - Fig. 5: with the largest N_eps, the Lagrange-extrapolated solver's eta^1 is at least 100 times
      below the plain perturbed solver's G_{eps^1} (N_eps = 1) and within a factor 2 of
      G_{eps^0, tau_c}'s, and Richardson m = 1 lowers it at least tenfold.
    """
    f3, f5 = results["fig3"], results["fig5"]
    rows3, rows5 = f3["rows"], f5["rows"]
    assessed = [f5["plain"]] + [row[kind] for row in rows5 for kind in ("lagrange", "richardson")]
    fig3_entries = [f3["plain"], *rows3]
    monitors = [row["max_monitor"] for row in fig3_entries + assessed]
    monitors += [row["edge"]["max_monitor"] for row in fig3_entries]
    steps = [row["tau_c_over_tau_f"] for row in rows3]
    single = next(row for row in rows5 if row["n_nodes"] == 1)["lagrange"]["eta1"]
    last = rows5[-1]
    return {
        "coarse_solvers_keep_length_limit": all(row["within_limit"] for row in assessed)
        and max(monitors) <= 0.01,
        "fig3_tau_c_grows_with_epsilon1": bool(np.all(np.diff(steps) > 0))
        and steps[0] > f3["plain"]["tau_c_over_tau_f"],
        "fig3_plain_breaks_limit_at_largest_tau_c": not rows3[-1]["plain_within_limit_at_tau_c"],
        "fig3_eta1_grows_with_epsilon1": rows3[-1]["eta1"] > rows3[0]["eta1"],
        "fig3_edge_spoils_eta1": all(
            row["edge"]["eta1"] > 100 * row["eta1"] for row in fig3_entries
        ),
        "fig5_lagrange_far_below_perturbed": last["lagrange"]["eta1"] < single / 100,
        "fig5_lagrange_reaches_plain_eps0": last["lagrange"]["eta1"] < 2 * f5["plain"]["eta1"],
        "fig5_richardson_lowers_eta1": last["richardson"]["eta1"] < last["lagrange"]["eta1"] / 10,
    }


def documented_numbers(results: dict) -> dict[str, dict[str, Any]]:
    """The numbers docs/validation.md prints from ``results``, as the groups ``rod_fig3`` and
    ``rod_fig5`` of docs/numbers.toml (rows: the plain G_{eps^0, tau}, then each epsilon^1; each
    N_epsilon)."""
    f3, f5 = results["fig3"], results["fig5"]
    rows3, rows5 = f3["rows"], f5["rows"]
    entries = [f3["plain"], *rows3]
    g3 = [row["lagrange"]["eta1"] for row in rows5]
    g4 = [row["richardson"]["eta1"] for row in rows5]
    return {
        "rod_fig3": {
            "sum_abs_weights": [1.0] + [row["sum_abs_weights"] for row in rows3],
            "tau_max": [e["tau_max_over_tau_f"] for e in entries],
            "tau_c": [e["tau_c_over_tau_f"] for e in entries],
            "eta1": [e["eta1"] for e in entries],
            # the plain solver keeps the limit at its own tau_c by construction
            "plain_within_limit": [True] + [row["plain_within_limit_at_tau_c"] for row in rows3],
            "edge_tau_c": [e["edge"]["tau_c_over_tau_f"] for e in entries],
            "edge_eta1": [e["edge"]["eta1"] for e in entries],
            "tau_c_growth": rows3[-1]["tau_c_over_tau_f"] / rows3[0]["tau_c_over_tau_f"],
            # the fine solution's largest relative length change, in percent
            "reference_monitor_percent": 100 * results["setup"]["reference_max_monitor"],
        },
        "rod_fig5": {
            "plain_eta1": f5["plain"]["eta1"],
            "g3_eta1": g3,
            "g4_eta1": g4,
            "g3_over_g4": [a / b for a, b in zip(g3, g4, strict=True)],
            "richardson_steps": rows5[0]["richardson_steps_over_tau_f"],
            "richardson_weights": rows5[0]["richardson_weights"],
        },
    }


def run_all(setup: Setup, log=print) -> dict:
    """The reference solution, Fig. 3 and Fig. 5 data, and the claims, as one JSON-ready dict."""
    start = time.perf_counter()
    reference = reference_solution(setup)
    log(f"reference solution: {time.perf_counter() - start:.1f}s")
    results: dict[str, Any] = {
        "setup": {
            **dataclasses.asdict(setup),
            "sigma_f": setup.sigma_f,
            "reference_max_monitor": max(setup.rod().monitor(x) for x in reference),
        },
        "fig3": fig3(setup, reference, log),
        "fig5": fig5(setup, reference, log),
    }
    results["claims"] = claims(results)
    results["runtime_s"] = time.perf_counter() - start
    return results


def plot_fig3(results: dict, path: Path) -> None:
    """eta^1 (log scale, left) and the coarse steps (right) against epsilon^1 / sigma_f.

    Filled markers: tau_c with the margin and its eta^1; hollow: the edge. The plain solver
    G_{eps^0, tau} sits at epsilon^0 / sigma_f (squares).
    """
    import matplotlib.pyplot as plt

    f3 = results["fig3"]
    rows, plain = f3["rows"], f3["plain"]
    x = [row["epsilon1_over_sigma_f"] for row in rows]
    x0 = results["setup"]["epsilon0"]
    margin = results["setup"]["margin"]
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    right = ax.twinx()
    ax.semilogy(
        x,
        [row["eta1"] for row in rows],
        "o-",
        color="C0",
        label=rf"$\eta^1$, $\tau_c \leq {margin:g}\,\tau_{{max}}$",
    )
    ax.semilogy(
        x,
        [row["edge"]["eta1"] for row in rows],
        "o:",
        color="C0",
        mfc="none",
        label=r"$\eta^1$ at the edge",
    )
    ax.semilogy([x0], [plain["eta1"]], "s", color="C0")
    ax.semilogy([x0], [plain["edge"]["eta1"]], "s", color="C0", mfc="none")
    right.plot(
        x, [row["tau_c_over_tau_f"] for row in rows], "^-", color="C1", label=r"$\tau_c/\tau_f$"
    )
    right.plot(
        x,
        [row["tau_max_over_tau_f"] for row in rows],
        "^--",
        color="C1",
        mfc="none",
        label=r"$\tau_{max}/\tau_f$ ($\epsilon^1$ alone)",
    )
    right.plot([x0], [plain["tau_c_over_tau_f"]], "s", color="C1")
    right.plot([x0], [plain["tau_max_over_tau_f"]], "s", color="C1", mfc="none")
    ax.set_xlabel(r"$\epsilon^1/\sigma_f$  (squares: plain $\mathcal{G}_{\epsilon^0,\tau}$)")
    ax.set_ylabel(r"$\eta^1$", color="C0")
    right.set_ylabel(r"coarse step / $\tau_f$", color="C1")
    handles = ax.get_legend_handles_labels()[0] + right.get_legend_handles_labels()[0]
    ax.legend(handles=handles, loc="center left", fontsize=8)
    ax.set_title(r"Lagrange in $\epsilon$, $N_\epsilon = 4$ (Fig. 3), shortened rod", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_fig5(results: dict, path: Path) -> None:
    """eta^1 against N_epsilon for G_{eps^0, tau_c}, G^3 (Lagrange) and G^4 (+ Richardson)."""
    import matplotlib.pyplot as plt

    f5 = results["fig5"]
    n = [row["n_nodes"] for row in f5["rows"]]
    fig, ax = plt.subplots(figsize=(5.5, 4))
    ax.axhline(f5["plain"]["eta1"], color="k", ls="--", label=r"$\mathcal{G}_{\epsilon^0,\tau_c}$")
    ax.semilogy(
        n,
        [row["lagrange"]["eta1"] for row in f5["rows"]],
        "o-",
        label=r"$\mathcal{G}^3$: Lagrange in $\epsilon$",
    )
    ax.semilogy(
        n,
        [row["richardson"]["eta1"] for row in f5["rows"]],
        "s-",
        label=r"$\mathcal{G}^4$: + Richardson $m=1$, $r=0.83$",
    )
    ax.set_xlabel(r"$N_\epsilon$")
    ax.set_ylabel(r"$\eta^1$")
    ax.set_xticks(n)
    ax.legend(fontsize=8)
    ax.set_title(rf"$\tau_c = {f5['tau_c_over_tau_f']:g}\,\tau_f$, shortened rod", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def markdown_tables(results: dict) -> str:
    """The numbers of both figures as the Markdown tables of docs/validation.md."""
    f3, f5 = results["fig3"], results["fig5"]
    lines = [
        "| coarse solver | ε¹/σ_f | Σ\\|w_j\\| | τ_max/τ_f | τ_c/τ_f | η¹ "
        "| G_{ε⁰} within 1% at τ_c | edge τ_c/τ_f | η¹ at edge |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for row in [f3["plain"], *f3["rows"]]:
        extrapolated = "epsilon1_over_sigma_f" in row
        lines.append(
            "| "
            + " | ".join(
                [
                    "Lagrange, N_ε = 4" if extrapolated else "plain G_{ε⁰,τ}",
                    f"{row.get('epsilon1_over_sigma_f', results['setup']['epsilon0']):g}",
                    f"{row.get('sum_abs_weights', 1.0):g}",
                    f"{row['tau_max_over_tau_f']:.2f}",
                    f"{row['tau_c_over_tau_f']:.2f}",
                    f"{row['eta1']:.2e}",
                    ("yes" if row["plain_within_limit_at_tau_c"] else "no")
                    if extrapolated
                    else "yes",
                    f"{row['edge']['tau_c_over_tau_f']:.2f}",
                    f"{row['edge']['eta1']:.2e}",
                ]
            )
            + " |"
        )
    first = f5["rows"][0]
    lines += [
        "",
        f"τ_c = {f5['tau_c_over_tau_f']:g} τ_f; η¹ of G_{{ε⁰,τ_c}} = {f5['plain']['eta1']:.2e}; "
        "G⁴ steps h_q/τ_f = "
        + ", ".join(f"{h:.3f}" for h in first["richardson_steps_over_tau_f"])
        + ", weights v_q = "
        + ", ".join(f"{v:.3f}" for v in first["richardson_weights"]),
        "",
        "| N_ε | ε^j/σ_f | η¹ G³ (Lagrange) | η¹ G⁴ (+ Richardson m = 1) | G³ / G⁴ |",
        "|---|---|---|---|---|",
    ]
    for row in f5["rows"]:
        g3, g4 = row["lagrange"]["eta1"], row["richardson"]["eta1"]
        nodes = ", ".join(f"{e:.2f}" for e in row["nodes_over_sigma_f"])
        lines.append(f"| {row['n_nodes']} | {nodes} | {g3:.2e} | {g4:.2e} | {g3 / g4:.3g} |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> dict:
    """Command line: compute, write the JSON and both figures, print the claims."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--quick", action="store_true", help="a half-minute version (31 nodes, T = 2e-3)"
    )
    parser.add_argument("--out", type=Path, default=Path("docs/figures"), help="output folder")
    args = parser.parse_args(argv)
    setup, suffix = (QUICK, "_quick") if args.quick else (FULL, "")
    results = run_all(setup)
    write_results(results, args.out / f"rod_extrapolation{suffix}.json")
    plot_fig3(results, args.out / f"rod_fig3{suffix}.png")
    plot_fig5(results, args.out / f"rod_fig5{suffix}.png")
    print(markdown_tables(results))
    print_claims(results)
    for group, numbers in documented_numbers(results).items():  # docs/numbers.toml
        print(f"[{group}] values:\n{toml_values(numbers)}")
    print(f"total {results['runtime_s']:.1f}s; written to {args.out}")
    return results


if __name__ == "__main__":
    main()
