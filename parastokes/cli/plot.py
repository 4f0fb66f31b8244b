"""``parastokes plot``: the figures of one run, a comparison of runs, or a benchmark file,
written through the output claim (never over a run's own files)."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from .console import Console
from .exits import ExitCode


def cmd_plot(args: argparse.Namespace, console: Console) -> ExitCode:
    from ..output import plots, rundir

    formats = args.formats
    if args.benchmark is not None:
        if args.dirs:
            raise ValueError("plot: give run directories or --benchmark FILE.json, not both")
        out = Path(args.out if args.out is not None else Path(args.benchmark).parent)
        with rundir.claim_files(_figures(out, plots.BENCHMARK_FIGURES, formats)):
            written = plots.draw_benchmark(args.benchmark, out, formats)
    elif not args.dirs:
        raise ValueError("plot: give run directories or --benchmark FILE.json")
    elif len(args.dirs) == 1 and args.out is None:
        with rundir.locked(args.dirs[0]) as directory:  # not while a run writes there
            written = plots.draw_run(args.dirs[0], formats)
            directory.add_results([path.name for path in written])
    else:
        out = Path(args.out or "comparison")
        with rundir.claim_files(_figures(out, plots.COMPARISON_FIGURES, formats),
                                reads=args.dirs):
            written = plots.draw_comparison(args.dirs, out, formats)
    for path in written:
        console.print(str(path))
    return ExitCode.OK


def _figures(out: Path, stems: Sequence[str], formats: Sequence[str]) -> list[Path]:
    """The files of the figures ``stems`` in ``formats`` in the directory ``out``."""
    return [out / f"{stem}.{fmt}" for stem in stems for fmt in formats]
