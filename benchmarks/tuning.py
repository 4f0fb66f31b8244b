"""Targets of ``parastokes tune`` (docs/tuning.md): tuned vs the paper's hand-chosen coarse solvers
and vs the plain coarse solver, at 40 cores and targets 1e-6 and 1e-8.

Run from the repository root (each run is ``parastokes tune``; its TUNED.json/.toml/.png land in
``--dir``; measurements run at low priority)::

    PYTHONPATH=. nice python benchmarks/tuning.py --problems rod5 rod7 --targets 1e-6 1e-8
    PYTHONPATH=. python benchmarks/tuning.py --tables            # Markdown tables from --dir
    PYTHONPATH=. nice python benchmarks/tuning.py --validate 5 20 --targets 1e-6 1e-8 \\
        --dir docs/figures/tuning/validate                      # pilot vs real runs

Problems: ``rod5`` / ``rod7`` (Tables 4 / 5: ε⁰ = 5σ_f / 7σ_f, M = 301, T = 1; the search runs on a
pilot rod of 61 nodes at the same σ_f and slice length), ``ves7`` / ``ves8`` (Tables 7 / 8, the
642-point vesicle, T = 100; the paper's solvers by ``--pilot-check``), and problems not in the
paper: ``rod4`` (ε⁰ = 4σ_f), ``ves_soft`` (Table 7's vesicle with half the spring stiffness),
``short5`` / ``short7`` (the 61-node rod, ε⁰ = 5σ_f / 7σ_f, on 40 slices of 2e-3 instead of 0.025: T
= 0.08). For the paper's problems the paper's solvers are measured the same way (``--compare``), at
their own steps.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence
from pathlib import Path

from parastokes import cli


def _tables(number: int, solvers: Sequence[int]) -> list[str]:
    return [f"experiments/table{number}_g{i}.toml" for i in solvers]


PROBLEMS = {
    "rod5": ("experiments/table4_g1.toml", [], _tables(4, (1, 2, 3, 4))),
    "rod7": ("experiments/table5_g1.toml", [], _tables(5, (1, 2, 3))),
    # the vesicle: no --compare (each of the paper's solvers would cost 2-3 fine slices, more
    # than 15 % allows); --pilot-check measures them on the same pilot instead
    "ves7": ("experiments/table7_g1.toml", [], []),
    "ves8": ("experiments/table8_g1.toml", [], []),
    # Table 4 G⁴ (plain coarse): G¹'s nodes (5.2σ_f and up) are too far from ε⁰ = 4σ_f
    "rod4": ("experiments/table4_g4.toml", ["model.epsilon=4"], []),
    "ves_soft": ("experiments/table7_g1.toml", ["model.stiffness=0.05"], []),
    # short slices (2e-3 = 2000 τ_f, 40 of them), not in the paper: the quick rod (M = 61)
    "short5": ("experiments/quick/table4_g1.toml", ["time.t1=0.08"], []),
    "short7": ("experiments/quick/table5_g1.toml", ["time.t1=0.08"], []),
}


def run(problem: str, target: float, cores: int, out: Path, extra: Sequence[str],
        search_only: bool = False) -> int:
    """``parastokes tune`` of ``problem``; with ``search_only`` the paper's solvers are not
    given, so the whole budget goes to the search (files ``{problem}_{target}_search.*``)."""
    config, overrides, compare = PROBLEMS[problem]
    name = f"{problem}_{target:g}" + ("_search" if search_only else "")
    argv = ["tune", config, "--cores", str(cores), "--target", f"{target:g}",
            "--out", str(out / f"{name}.toml")]
    for item in overrides:
        argv += ["--set", item]
    if compare and not search_only:
        argv += ["--compare", *compare]
    return cli.main([*argv, *extra])


def _num(value: float | None, spec: str) -> str:
    return "-" if value is None else format(value, spec)


def _growth(stability: dict) -> float | None:
    """ρ(DG) of the combined slice map; files written before it replaced the power iteration
    hold that iteration's ``amplification`` instead (docs/tuning.md, step 7)."""
    return stability.get("spectral_radius", stability.get("amplification"))


def _row(c: dict) -> str:
    p = c["predicted"]
    return (f"| {c['label']} | {_num(c.get('dt_ratio'), '.3g')} | {c['n_auxiliary']} | "
            f"{_num(_growth(c['stability']), '.4g')} | "
            f"{_num(c['pilot']['eta1'], '.2e')} | {p['iterations'] or '-'} | "
            f"{_num(p['gamma_ratio'], '.4f')} | {_num(p['speedup'], '.2f')} | {c['status']} |")


def tables(directory: Path) -> str:
    """Markdown: per run, the chosen, the baseline and the given (paper's) solvers."""
    out = []
    for path in sorted(directory.glob("*.json")):
        report = json.loads(path.read_text())
        if not isinstance(report, dict) or "cost" not in report:  # validate.json, pilot checks
            continue
        cost, problem = report["cost"], report["problem"]
        out += [f"### {path.stem}: η* = {problem['target']:g}, N_c = {problem['n_slices']}", "",
                f"{report['pilot']['note']}; tuning {cost['cpu_seconds']:.0f} s CPU "
                f"({cost['seconds']:.0f} s wall) = {cost['fraction']:.1%} of the estimated "
                f"serial fine solve ({cost['serial_fine_estimate']:.0f} s CPU); search stopped: "
                f"{report['search']['stopped']}; {report['extrapolation']['note']}", "",
                "| solver | τ_c/τ_f | N_G | ρ(DG) (older files: ‖DG‖, power iteration) "
                "| η¹ pilot "
                "| N_it | γ_G/γ_F | speedup | status |",
                "|---|---|---|---|---|---|---|---|---|"]
        rows = [report["chosen"]] if report["chosen"] else []
        rows.append(report["baseline"])
        rows += [c for c in report["candidates"] if c.get("given")]
        seen = set()
        for c in rows:
            key = (c["label"], c["dt"])
            if key not in seen:
                seen.add(key)
                out.append(_row(c))
        out += ["", *_by_target(report), ""]
    return "\n".join(out)


def _by_target(report: dict) -> list[str]:
    """Best measured, plain and best given solver per target, from the same measurements."""
    curves = report["curves"]
    given = {f"{c['label']} @ {c['dt']:.4g}" for c in report["candidates"] if c.get("given")}
    plain = {f"{c['label']} @ {c['dt']:.4g}" for c in report["candidates"]
             if c["label"] == report["baseline"]["label"] and c["dt"]}
    lines = ["| η* | best measured (speedup) | best of the search alone | plain G_{Θ⁰,τ} | "
             "best given | best / plain |", "|---|---|---|---|---|---|"]
    for i, eta in enumerate(curves["targets"]):
        if f"{eta:g}" not in ("1e-06", "1e-08"):
            continue
        def top(keys: set[str], i: int = i) -> tuple[float | None, str]:
            values = [(curves["speedup"][k][i], k) for k in keys
                      if k in curves["speedup"] and curves["speedup"][k][i] is not None]
            return max(values) if values else (None, "-")
        best, label = top(set(curves["speedup"]))
        base, _ = top(plain)
        paper, paper_label = top(given)
        searched, searched_label = top(set(curves["speedup"]) - given)
        ratio = None if best is None or base is None else best / base
        lines.append(f"| {eta:g} | {_num(best, '.2f')} ({label}) | {_num(searched, '.2f')} "
                     f"({searched_label}) | {_num(base, '.2f')} | "
                     f"{_num(paper, '.2f')} ({paper_label}) | {_num(ratio, '.2f')} |")
    return lines


#: Pilot against real runs: the quick rod (M = 61, ε⁰ = 5σ_f) with slices of 2e-3 (2000 τ_f,
#: docs/validation.md's setup) on N_c = 5 and 20 slices, runs with the serial executor.
VALIDATE = "experiments/quick/table4_g1.toml"


def validate(target: float, cores: int, out: Path) -> dict:
    """Tune, then run the tuned config to N_it + 1 iterations (mode both): predicted vs real η^k."""
    from parastokes.tuning.cost import predicted_errors

    stem = out / f"validate_{cores}_{target:g}"
    t1 = 2e-3 * cores
    code = cli.main(["tune", VALIDATE, "--cores", str(cores), "--target", f"{target:g}",
                     "--out", f"{stem}.toml", "--set", f"time.t1={t1:g}", "-q"])
    if code != 0:
        return {"cores": cores, "target": target, "tune_exit": code}
    report = json.loads(Path(f"{stem}.json").read_text())
    chosen = report["chosen"]
    n_it = chosen["predicted"]["iterations"]
    run_dir = Path(f"{stem}_run")
    cli.main(["run", f"{stem}.toml", "--out", str(run_dir), "-q",
              "--set", f"parareal.max_iterations={n_it + 1}",
              "--set", 'execution.executor="serial"', "--set", "execution.workers=1",
              "--set", "output.trajectory=false", "--set", "output.figures=false"])
    summary = json.loads((run_dir / "summary.json").read_text())
    predicted = predicted_errors(chosen["pilot"]["eta"], report["pilot"]["slices"], cores,
                                 n_it + 1)
    return {"cores": cores, "target": target, "chosen": chosen["label"],
            "predicted_iterations": n_it, "predicted_eta": predicted,
            "measured_eta": summary["errors"],
            "reached_at": next((k for k, e in enumerate(summary["errors"], 1) if e <= target),
                               None),
            "tuning_seconds": report["cost"]["seconds"]}


#: The paper's vesicle solvers and, where the reproduction ran one at full scale, its record.
PILOT_CHECK = {"table7": _tables(7, (4, 1, 2, 3)), "table8": _tables(8, (1, 2, 3))}
RECORDS = Path("docs/reproduction")


def _record(solver: str) -> dict | None:
    """The full-scale reproduction record of ``solver`` (``table7_g4``), if that run finished."""
    path = RECORDS / f"{solver}.json"
    if not path.exists():
        return None
    record = json.loads(path.read_text())
    return {"errors": record["errors"], "gamma_ratio": record["gamma_ratio"],
            "speedup_40": record["speedup_40"]["speedup"]}


def pilot_check(table: str, slices: int = 40) -> list[dict]:
    """The pilot against full-scale runs: for each solver of ``table`` (Tables 7-8, the vesicle),
    η^k measured on the pilot window (P = 2, K = 1 and P = 3, K = 2, one reference), the
    prediction for the whole run, and the screened prediction (one coarse call, scaled from the
    table's first solver); the first solver's full-scale record beside it."""
    from dataclasses import replace

    from parastokes import config as configuration
    from parastokes import integrate
    from parastokes.tuning import cost
    from parastokes.tuning.pilot import Pilot
    from parastokes.tuning.space import settings_from_config

    paths = PILOT_CHECK[table]
    cfg, resolved = configuration.load(paths[0])
    system = configuration.build_system(cfg, resolved)
    fine = integrate.Propagator(system, cfg.fine.scheme, cfg.fine.dt)
    length = (cfg.time.t1 - cfg.time.t0) / slices
    three = Pilot.prepare(fine, system.initial_state(), cfg.time.t0, length, 3)
    two = replace(three, n_slices=2, reference=three.reference[:3])
    rows, calibration = [], None
    for path in paths:
        other, other_resolved = configuration.load(path)
        settings = settings_from_config(other, other_resolved, name=Path(path).stem)
        coarse = settings.build(system)
        shot = three.screen(coarse)
        row = {"solver": settings.name, "label": settings.label(), "defect": shot.defect,
               "gamma_f": three.gamma_f, "reference_seconds": three.seconds}
        for pilot, k in ((two, 1), (three, 2)):
            run = pilot.measure(coarse, k, shot)
            rho = cost.contraction(run.errors, run.eta0)
            ratio = cost.gamma_ratio(settings, length, run.coarse_seconds, pilot.gamma_f, slices)
            its = {f"{eta:g}": cost.predicted_iterations(run.errors, pilot.n_slices, slices, eta,
                                                         rho) for eta in (1e-6, 1e-8)}
            row[f"P{pilot.n_slices}"] = {
                "eta": run.errors, "eta0": run.eta0, "contraction": rho,
                "predicted": cost.predicted_errors(run.errors, pilot.n_slices, slices, 4, rho),
                "gamma_ratio": ratio, "iterations": its,
                "speedup": {e: None if n is None else cost.speedup(ratio, n, slices)
                            for e, n in its.items()}}
        if calibration is None:
            calibration = (shot.defect, row["P3"]["eta"])
        else:
            row["screened_eta"] = cost.screened_errors(shot.defect, *calibration)
        rows.append(row)
        print(json.dumps(row), flush=True)
    return rows


def pilot_tables(directory: Path) -> str:
    """Markdown of the --pilot-check files in ``directory``: each solver's pilot η^k, predicted
    N_it and speedup at 1e-6 and 1e-8 (two- and three-slice windows), and the full-scale record
    where the reproduction has one (read now, so finished runs appear without a new check)."""
    out = []
    for path in sorted(directory.glob("pilot_check_*.json")):
        out += [f"{path.stem}:", "",
                "| solver | d (screen) | pilot | η^k at T_P | ρ | predicted η¹, η² of the run | "
                "γ_G/γ_F | N_it 1e-6 / 1e-8 | speedup 1e-6 / 1e-8 |",
                "|---|---|---|---|---|---|---|---|---|"]
        for row in json.loads(path.read_text()):
            for key in ("P2", "P3"):
                m = row[key]
                its = " / ".join(str(m["iterations"][e] or "-") for e in ("1e-06", "1e-08"))
                speed = " / ".join(_num(m["speedup"][e], ".2f") for e in ("1e-06", "1e-08"))
                out.append(f"| {row['label']} | {row['defect']:.2e} | {key} | "
                           f"{', '.join(f'{e:.2e}' for e in m['eta'])} | "
                           f"{m['contraction']:.2e} | "
                           f"{', '.join(f'{e:.2e}' for e in m['predicted'][:2])} | "
                           f"{m['gamma_ratio']:.4f} | {its} | {speed} |")
            rec = _record(row["solver"])
            if rec is not None:
                out.append(f"| {row['label']} | | full scale (record) | "
                           f"{', '.join(f'{e:.2e}' for e in rec['errors'][:2])} | "
                           f"{rec['errors'][1] / rec['errors'][0]:.2e} | | "
                           f"{rec['gamma_ratio']:.4f} | | |")
        out.append("")
    return "\n".join(out)


def _first_below(errors: Sequence[float], target: float) -> int | None:
    return next((k for k, e in enumerate(errors, 1) if e <= target), None)


def pilot_against_records(directory: Path, targets: Sequence[float] = (1e-6, 1e-8)) -> str:
    """Markdown: for every solver of the --pilot-check files with a full-scale record, the η^k the
    pilot predicts for the run (k = 1..4) against the record's, and N_it predicted against the
    run's own (the first k <= 4 with η^k <= η*; "> 4" when four iterations did not reach it)."""
    head = " | ".join(f"N_it {t:g}: predicted / run" for t in targets)
    out = [f"| solver | | η¹ | η² | η³ | η⁴ | {head} |",
           "|---|---|---|---|---|---|" + "---|" * len(targets)]
    for path in sorted(directory.glob("pilot_check_*.json")):
        for row in json.loads(path.read_text()):
            rec = _record(row["solver"])
            if rec is None:
                continue
            out.append(f"| {row['solver']} | full scale | "
                       + " | ".join(f"{e:.1e}" for e in rec["errors"][:4]) + " |"
                       + " |" * len(targets))
            for key in ("P2", "P3"):
                m = row[key]
                cells = []
                for t in targets:
                    predicted = m["iterations"][f"{t:g}"]
                    real = _first_below(rec["errors"], t)
                    mark = ""
                    if predicted and (real or 5) > predicted + 1:
                        mark = " ✗"  # the run needed more than N_it + 1
                    elif predicted and real is None:
                        mark = " ?"  # not decided by four iterations
                    cells.append(f"{predicted or '-'} / {real or '> 4'}{mark}")
                out.append(f"| | pilot {key} | "
                           + " | ".join(f"{e:.1e}" for e in m["predicted"][:4]) + " | "
                           + " | ".join(cells) + " |")
    return "\n".join(out)


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problems", nargs="+", choices=sorted(PROBLEMS), default=[])
    parser.add_argument("--targets", type=float, nargs="+", default=[1e-6, 1e-8])
    parser.add_argument("--cores", type=int, default=40)
    parser.add_argument("--dir", type=Path, default=Path("docs/figures/tuning"))
    parser.add_argument("--tables", action="store_true", help="print the Markdown tables")
    parser.add_argument("--pilot-check", nargs="+", choices=sorted(PILOT_CHECK), default=[],
                        help="the vesicle pilot against the full-scale reproduction records")
    parser.add_argument("--search-only", action="store_true",
                        help="do not give the paper's solvers (--compare): the budget is the "
                             "search's alone")
    parser.add_argument("--validate", type=int, nargs="*", metavar="N_C",
                        help="pilot vs real runs of tuned quick-rod configs on N_C slices")
    args, extra = parser.parse_known_args(argv)
    args.dir.mkdir(parents=True, exist_ok=True)
    for problem in args.problems:
        for target in args.targets:
            print(f"== {problem}, η* = {target:g}", flush=True)
            run(problem, target, args.cores, args.dir, extra, args.search_only)
    if args.validate:
        rows = [validate(target, n, args.dir) for n in args.validate for target in args.targets]
        (args.dir / "validate.json").write_text(json.dumps(rows, indent=1))
        for row in rows:
            print(json.dumps(row))
    for table in args.pilot_check:
        rows = pilot_check(table, args.cores)
        (args.dir / f"pilot_check_{table}.json").write_text(json.dumps(rows, indent=1))
    if args.tables:
        print(tables(args.dir))
        print(pilot_tables(args.dir))
        print(pilot_against_records(args.dir))


if __name__ == "__main__":
    main()
