"""Learned Parareal corrections on the 40-slice problems of ``frontier.py --k40`` (issue 48).

Parareal's correction (eq. 11) X_n^k = F(X_{n-1}^{k-1}) + G(X_{n-1}^k) - G(X_{n-1}^{k-1}) takes
the fine-coarse difference D(x) = F(x) - G(x) at the previous iterate as if it did not depend on
the state. The corrections compared here learn D from every pair (x, D(x)) that both schedules have
when X_n^k is formed: x = X_{j-1}^i for iterations i <= k - 1 and slices j <= n (F(X_{j-1}^i) is
solved in iteration i + 1, G(X_{j-1}^i) in sweep i):

- ``classical``: eq. 11.
- ``gp``: GParareal (Pentland, Tamborrino, Sullivan, Buchanan & Appel, Statistics and Computing
  33:20, 2023): X_n^k = G(X_{n-1}^k) + m(X_{n-1}^k), m the posterior mean of a zero-mean Gaussian
  process fitted to D, one squared-exponential kernel over the state (scaled by the initial
  state's RMS) shared by all outputs, its lengthscale the maximum of the marginal likelihood over
  a log grid (signal variance profiled out), nugget 1e-10.
- ``gp-exact``: eq. 11 + m(X_{n-1}^k) - m(X_{n-1}^{k-1}): eq. 11 wherever the input has
  converged, so the first k slices are exact after k iterations, as in Parareal.
- ``secant``: the engine's (``parareal.run(correction="secant")``, parastokes/parareal/learned.py):
  eq. 11 + J (X_{n-1}^k - X_{n-1}^{k-1}), J the minimum-norm least-squares map with J dX_n^i =
  dD_n^i over the differences of consecutive iterates of slice n itself, dX_n^i = X_{n-1}^i -
  X_{n-1}^{i-1}, dD_n^i = D(X_{n-1}^i) - D(X_{n-1}^{i-1}) (the Krylov-subspace idea of Gander &
  Petcu, ESAIM Proc. 25, 2008: F is applied exactly on the span of the previous iterates for a
  linear problem).
- ``secant-all``: the same map fitted to the differences of every slice j <= n (one J for all).

F and G are those of ``frontier.py`` (its ``k40_problem``, ``build``, ``CANDIDATES``); eta^k is
``k40_errors``'s, against F's serial solution (``k40_reference``). Every F and G solve is kept on
disk keyed by its input's bytes (``out/learned/``), so a rerun, or a variant that feeds F the same
input, takes it from there: killed runs resume by rerunning. The fine solves of an iteration run
on ``--workers`` processes. Results: ``docs/figures/frontier/learned_PROBLEM.json``.

    export PYTHONPATH=. NUMBA_NUM_THREADS=1
    nice -n 10 python benchmarks/learned.py table5 "ros34pw2 1.25e-3" --iterations 6 --workers 2
"""

from __future__ import annotations

import argparse
import hashlib
import multiprocessing
import pathlib
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import numpy as np

from benchmarks import frontier as fr
from parastokes.integrate import BlowUpError
from parastokes.parareal.algorithm import correct
from parastokes.parareal.learned import SecantHistory, secant_step

WORK = pathlib.Path("out/learned")
CORRECTIONS = ("classical", "secant", "gp", "gp-exact", "secant-all")
#: GParareal's log grid of lengthscales, in units of the median distance between training inputs.
LENGTHSCALES = np.logspace(-2, 2, 25)
NUGGET = 1e-10

_SETUP: dict[str, Any] = {}


# ---- the solves, cached by their input's bytes ------------------------------------------------

def _key(kind: str, t0: float, t1: float, x: np.ndarray) -> str:
    digest = hashlib.sha1(f"{kind}|{t0!r}|{t1!r}|{x.dtype}|{x.shape}".encode())
    digest.update(np.ascontiguousarray(x).tobytes())
    return digest.hexdigest()


def _init(name: str, label: str, double_lu: bool = False) -> None:
    """Build the problem's F and G once per process (``double_lu``: the linearly implicit
    schemes' banded LU in float64 instead of float32, parastokes.stiff.solve.BAND_PRECISION)."""
    if double_lu:
        from parastokes.stiff import solve as stiff_solve

        stiff_solve.BAND_PRECISION = np.float64
    _SETUP["setup"] = fr.build(fr.k40_problem(name), fr.CANDIDATES[name][label].coarse)


def solve(kind: str, folder: str, t0: float, t1: float, x: np.ndarray) -> tuple[np.ndarray, float]:
    """F (``kind`` "fine") or G ("coarse") over (t0, t1) from x, from ``folder``'s cache or solved
    and kept there; with the CPU time it took (0 when cached)."""
    path = pathlib.Path(folder) / f"{_key(kind, t0, t1, x)}.npy"
    if path.exists():
        return np.load(path), 0.0
    propagator = getattr(_SETUP["setup"], kind)
    start = time.process_time()
    value = propagator(t0, t1, x)
    cpu = time.process_time() - start
    tmp = path.with_suffix(".tmp.npy")
    np.save(tmp, value)
    tmp.replace(path)
    return value, cpu


# ---- the learned models -----------------------------------------------------------------------

def gp_fit(d2: np.ndarray, outputs: np.ndarray) -> tuple[float, np.ndarray]:
    """GParareal's fit: the lengthscale l and weights (K + nugget I)^-1 Y of a zero-mean GP with
    the squared-exponential kernel exp(-|z - z'|^2 / (2 l^2)) shared by every output column, from
    the squared distances ``d2`` between the inputs; l maximizes the marginal likelihood (signal
    variance profiled: s^2 = tr(Y^T K^-1 Y) / (n d)) over ``LENGTHSCALES`` times the median
    distance between the inputs."""
    n, d = outputs.shape
    positive = d2[d2 > 0]
    median = float(np.sqrt(np.median(positive))) if positive.size else 1.0
    best: tuple[float, float, np.ndarray] | None = None
    for scale in LENGTHSCALES * median:
        kernel = np.exp(-d2 / (2.0 * scale**2)) + NUGGET * np.eye(n)
        try:
            factor = np.linalg.cholesky(kernel)
        except np.linalg.LinAlgError:
            continue
        weights = np.linalg.solve(factor.T, np.linalg.solve(factor, outputs))
        fit = float(np.sum(outputs * weights)) / (n * d)
        likelihood = -0.5 * n * d * np.log(fit) - d * np.sum(np.log(np.diag(factor)))
        if best is None or likelihood > best[0]:
            best = (likelihood, float(scale), weights)
    assert best is not None, "no lengthscale of the grid gives a positive definite kernel"
    return best[1], best[2]


def gp_mean(scale: float, weights: np.ndarray, inputs: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The posterior mean k(x, Z) (K + nugget I)^-1 Y at ``x`` (``gp_fit``'s scale and weights)."""
    d2 = ((inputs - x[None, :]) ** 2).sum(1)
    return np.exp(-d2 / (2.0 * scale**2)) @ weights


# ---- Parareal with a chosen correction ---------------------------------------------------------

class Run:
    """Parareal (Algorithm 1, standard schedule) on ``name``'s 40 slices with G = ``label`` and
    the given ``correction``; iterates and solves as arrays X[k][n], F[i][n], G[i][n]."""

    def __init__(self, name: str, label: str, correction: str, pool: ProcessPoolExecutor,
                 double_lu: bool = False) -> None:
        self.problem = fr.k40_problem(name)
        self.correction = correction
        self.pool = pool
        self.times = np.linspace(0.0, self.problem.t1, self.problem.slices + 1)
        self.fine_folder = WORK / name / "F"
        self.coarse_folder = WORK / name / (fr_slug(label) + ("_f64" if double_lu else ""))
        for folder in (self.fine_folder, self.coarse_folder):
            folder.mkdir(parents=True, exist_ok=True)
        self.x0 = _SETUP["setup"].system.initial_state()
        self.scale = float(np.sqrt(np.mean(self.x0**2)))
        self.states: list[np.ndarray] = []
        self.fine: dict[tuple[int, int], np.ndarray] = {}
        self.coarse: dict[tuple[int, int], np.ndarray] = {}
        self.model_cpu: list[float] = []
        self.coarse_cpu: list[float] = []
        self.fine_cpu = 0.0
        self.index: dict[tuple[int, int], int] = {}
        self.inputs: list[np.ndarray] = []
        self.d2 = np.zeros((0, 0))
        self.history = SecantHistory()

    def _coarse(self, k: int, n: int, x: np.ndarray) -> np.ndarray:
        value, cpu = solve("coarse", str(self.coarse_folder), self.times[n - 1], self.times[n], x)
        if cpu:
            self.coarse_cpu.append(cpu)
        self.coarse[k, n] = value
        return value

    def initial_sweep(self) -> None:
        """Eq. 9."""
        x = np.empty((self.problem.slices + 1, *self.x0.shape))
        x[0] = self.x0
        for n in range(1, len(self.times)):
            x[n] = self._coarse(0, n, x[n - 1])
        self.states.append(x)

    def _data(self, k: int, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The training pairs of X_n^k: inputs X_{j-1}^i (scaled) for i <= k - 1, i < j <= n,
        their squared distances (each computed once, from the differences) and D."""
        wanted = [(i, j) for i in range(k) for j in range(i + 1, n + 1)]
        for point in wanted:
            if point not in self.index:
                i, j = point
                z = self.states[i][j - 1].ravel() / self.scale
                row = np.array([((z - other) ** 2).sum() for other in self.inputs])
                size = len(self.inputs)
                grown = np.zeros((size + 1, size + 1))
                grown[:size, :size] = self.d2
                grown[size, :size] = grown[:size, size] = row
                self.d2 = grown
                self.index[point] = size
                self.inputs.append(z)
        rows = [self.index[p] for p in wanted]
        inputs = np.array([self.inputs[r] for r in rows])
        outputs = np.array([(self.fine[p] - self.coarse[p]).ravel() for p in wanted])
        return inputs, self.d2[np.ix_(rows, rows)], outputs

    def _differences(self, k: int, n: int) -> tuple[np.ndarray, np.ndarray]:
        """Columns dX_j^i, dD_j^i for i = 1..k-1 over the slices j <= n; zero differences
        (converged inputs) left out."""
        dx, dd = [], []
        for j in range(1, n + 1):
            for i in range(1, min(k, j)):
                step = self.states[i][j - 1] - self.states[i - 1][j - 1]
                if not np.any(step):
                    continue
                dx.append(step.ravel())
                dd.append(((self.fine[i, j] - self.coarse[i, j])
                           - (self.fine[i - 1, j] - self.coarse[i - 1, j])).ravel())
        if not dx:
            size = self.x0.size
            return np.zeros((size, 0)), np.zeros((size, 0))
        return np.array(dx).T, np.array(dd).T

    def corrected(self, k: int, n: int, g_new: np.ndarray) -> np.ndarray:
        """X_n^k from G(X_{n-1}^k) = ``g_new`` by the run's correction."""
        new, old = self.states[k][n - 1], self.states[k - 1][n - 1]
        fine, previous = self.fine[k - 1, n], self.coarse[k - 1, n]
        if self.correction == "classical":  # (the engine's own correction, bit for bit)
            return correct(fine, g_new, previous, None)
        classical = fine + g_new - previous
        start = time.process_time()
        if self.correction in ("gp", "gp-exact"):
            inputs, d2, outputs = self._data(k, n)
            scale, weights = gp_fit(d2, outputs)

            def mean(x: np.ndarray) -> np.ndarray:
                return gp_mean(scale, weights, inputs, x.ravel() / self.scale).reshape(x.shape)

            if self.correction == "gp":
                value = g_new + mean(new)
            else:
                value = classical + mean(new) - mean(old)
        elif self.correction == "secant":
            value = correct(fine, g_new, previous, None, (n, k, self.times[n]), None,
                            (self.history, new, old))
        else:
            dx, dd = self._differences(k, n)
            value = classical + secant_step(dx, dd, (new - old).ravel()).reshape(new.shape)
        self.model_cpu.append(time.process_time() - start)
        return value

    def iterate(self, k: int) -> None:
        """Eqs. 10-11 with the run's correction: F(X_{n-1}^{k-1}) for n = k..N on the pool, then
        the serial sweep."""
        previous = self.states[k - 1]
        slices = range(k, len(self.times))
        jobs = [self.pool.submit(solve, "fine", str(self.fine_folder), self.times[n - 1],
                                 self.times[n], previous[n - 1]) for n in slices]
        for n, job in zip(slices, jobs, strict=True):
            self.fine[k - 1, n], cpu = job.result()
            self.fine_cpu += cpu
        x = previous.copy()
        x[k] = self.fine[k - 1, k]
        self.states.append(x)
        for n in range(k + 1, len(self.times)):
            x[n] = self.corrected(k, n, self._coarse(k, n, x[n - 1]))


def fr_slug(label: str) -> str:
    """A folder name for a coarse solver's label."""
    return "".join(c if c.isalnum() or c in ".-" else "_" for c in label)


def measure(name: str, label: str, corrections: Sequence[str], iterations: int,
            workers: int, double_lu: bool = False) -> dict[str, Any]:
    """eta^1..eta^``iterations`` of each correction against F's serial solution, with K and the
    pipelined speedups at the analogue's alpha (none with ``double_lu``: not measured); saved
    after every iteration."""
    problem = fr.k40_problem(name)
    out = fr.OUT / f"learned_{name}.json"
    data = fr._load(out)
    _init(name, label, double_lu)
    work = WORK / name
    work.mkdir(parents=True, exist_ok=True)
    reference = fr.k40_reference(_SETUP["setup"], problem, work)
    analogue = fr.load_problem(name)
    own = fr.summary(analogue)["fine"]["error"]
    # (the analogue's alpha where it was measured there; none for a variant it never ran)
    alpha = None if double_lu else analogue["candidates"].get(label, {}).get("alpha")
    rows = data.setdefault(label + (fr.DOUBLE_LU if double_lu else ""), {
        "alpha": alpha, "fine_own_error": own, "slices": problem.slices, "t1": problem.t1,
        "corrections": {}})
    with ProcessPoolExecutor(workers, multiprocessing.get_context("spawn"), initializer=_init,
                             initargs=(name, label, double_lu)) as pool:
        for correction in corrections:
            run = Run(name, label, correction, pool, double_lu)
            run.initial_sweep()
            errors: list[float] = []
            for k in range(1, iterations + 1):
                try:
                    run.iterate(k)
                except BlowUpError as error:  # the corrected state sent G (or F) astray
                    failed = rows["corrections"].setdefault(correction, {})
                    failed["blowup"] = f"iteration {k}: {error}"[:300]
                    fr._save(out, data)
                    print(f"{label} | {correction} | k = {k}: blew up", flush=True)
                    break
                errors.append(fr.k40_errors(reference, [run.states[k][-1]])[0])
                K = fr.iterations_to_reach(errors, problem.target, own)
                rows["corrections"][correction] = {
                    "errors": errors,
                    "K": K,
                    "speedups": (None if K is None or alpha is None
                                 else fr.predicted_speedups(alpha, K)),
                    "model_cpu_per_correction": (float(np.mean(run.model_cpu))
                                                 if run.model_cpu else 0.0),
                    "model_cpu_max": max(run.model_cpu, default=0.0),
                    "coarse_cpu_per_solve": (float(np.median(run.coarse_cpu))
                                             if run.coarse_cpu else None),
                    "load_average": fr.load_average(),
                }
                fr._save(out, data)
                print(f"{label} | {correction} | k = {k}: eta = {errors[-1]:.3e}, model "
                      f"{rows['corrections'][correction]['model_cpu_per_correction']:.3g} s per "
                      f"correction", flush=True)
    return data


def smoothness(name: str, label: str, slice_index: int = 10, scale: float = 1e-15
               ) -> dict[str, Any]:
    """How much G (banded LU in float32, then float64) and F move when their input, F's serial
    solution at T_``slice_index``, moves by ``scale`` (relative, random): eq. 34 of the changes.
    A smooth solver moves by about its Lipschitz constant times the input's change; the learned
    corrections fit differences of F - G, so a non-smooth G sets their floor. Saved in
    ``OUT/learned_NAME_smoothness.json``."""
    from parastokes.parareal import relative_change
    from parastokes.stiff import solve as stiff_solve

    _init(name, label)
    setup, problem = _SETUP["setup"], fr.k40_problem(name)
    x = fr.k40_reference(setup, problem, WORK / name)[slice_index]
    moved = x * (1.0 + scale * np.random.default_rng(0).standard_normal(x.shape))
    t0, t1 = slice_index * problem.slice_length, (slice_index + 1) * problem.slice_length
    result: dict[str, Any] = {"label": label, "slice": slice_index + 1,
                              "input_change": relative_change(moved, x)}
    for precision in (np.float32, np.float64):
        stiff_solve.BAND_PRECISION = precision
        result[f"coarse_change_{precision.__name__}_lu"] = relative_change(
            setup.coarse(t0, t1, moved), setup.coarse(t0, t1, x))
    result["fine_change"] = relative_change(setup.fine(t0, t1, moved), setup.fine(t0, t1, x))
    fr._save(fr.OUT / f"learned_{name}_smoothness.json", result)
    return result


def table(name: str) -> str:
    """The markdown table of docs/benchmarks.md ("Learned corrections") from the results."""
    ratio = fr.summary(fr.load_problem(name))["cost_ratio"]
    lines = ["| G | α | correction | η¹ .. η^k at 40 slices | K | pipelined / standard against "
             f"F (against the fastest serial run, {ratio:.3g} of F's CPU) | "
             "model CPU per correction (s) | G CPU per solve (s) |", "|---" * 8 + "|"]
    for label, entry in fr._load(fr.OUT / f"learned_{name}.json").items():
        for correction, row in entry["corrections"].items():
            errors = ", ".join(f"{e:.1e}" for e in row.get("errors", []))
            if "blowup" in row:
                errors += f" (blew up in {row['blowup'].split(':')[0]})"
            speedups = row.get("speedups")
            shown = "-" if not speedups else (
                f"{speedups['pipelined']:.2f} / {speedups['standard']:.2f} "
                f"({ratio * speedups['pipelined']:.2f} / {ratio * speedups['standard']:.2f})")
            alpha = "-" if entry["alpha"] is None else f"{entry['alpha']:.3g}"
            lines.append(f"| {label} | {alpha} | {correction} | {errors} | "
                         f"{row.get('K') or '-'} | {shown} | "
                         f"{fr._g(row.get('model_cpu_per_correction'))} | "
                         f"{fr._g(row.get('coarse_cpu_per_solve'))} |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("problem", choices=sorted(fr.CANDIDATES))
    parser.add_argument("label", nargs="?",
                        help="a coarse solver of frontier.py's CANDIDATES[problem]")
    parser.add_argument("--table", action="store_true",
                        help="print the table of the results so far and stop")
    parser.add_argument("--smoothness", action="store_true",
                        help="measure how G and F move under a change of 1e-15 of their input")
    parser.add_argument("--corrections", nargs="+", choices=CORRECTIONS, default=CORRECTIONS)
    parser.add_argument("--iterations", type=int, default=6)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--double-lu", action="store_true",
                        help="the implicit G's banded LU in float64 (a smooth G; alpha not "
                        "measured)")
    args = parser.parse_args(argv)
    if args.table:
        print(table(args.problem))
        return
    if args.smoothness:
        print(smoothness(args.problem, args.label))
        return
    if args.label not in fr.CANDIDATES[args.problem]:
        parser.error(f"no coarse solver {args.label!r} for {args.problem}; choose one of "
                     f"{sorted(fr.CANDIDATES[args.problem])}")
    measure(args.problem, args.label, args.corrections, args.iterations, args.workers,
            args.double_lu)


if __name__ == "__main__":
    main()
