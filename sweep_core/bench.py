"""``sweep bench ...``: measured studies of the engine (headless; they write CSV and PNG).

    sweep bench accuracy [--quick] [--out bench_out] [--seed 0] [--problems rbm_wall crowd ...]
    sweep bench speed ...   (sweep_core.speed, registered here too)
    sweep bench recording ...   (sweep_core.recording_bench)

See :mod:`sweep_core.accuracy` for what is measured and how.
"""
from __future__ import annotations

import argparse
import csv
from pathlib import Path
from typing import Sequence


def write_csv(path: Path, rows: list[dict], columns: Sequence[str] | None = None) -> None:
    """The rows as a CSV with a header: ``columns``, or the keys of the first row. Nothing is
    written for no rows without columns."""
    if columns is None and not rows:
        return
    with Path(path).open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(columns or rows[0]))
        w.writeheader()
        w.writerows(rows)


def _accuracy(args: argparse.Namespace) -> int:
    from .accuracy import StudyConfig, run_study

    cfg = StudyConfig.make(args.quick, args.seed)
    print(f"sweep bench accuracy: {'quick' if cfg.quick else 'full'} study, {cfg.levels} dt "
          f"levels, problems {' '.join(args.problems)}", flush=True)
    run_study(cfg, Path(args.out), tuple(args.problems), log=lambda s: print(s, flush=True))
    return 0


def register(subparsers) -> None:
    """Add ``bench`` (``bench accuracy``, ``bench speed`` from :mod:`sweep_core.speed` and
    ``bench recording`` from :mod:`sweep_core.recording_bench`) to the ``sweep`` command's
    subparsers."""
    from . import recording_bench, speed
    from .accuracy import PROBLEMS

    bench = subparsers.add_parser("bench", help="measured studies of the engine")
    sub = bench.add_subparsers(dest="bench", required=True)
    speed.register(sub)
    recording_bench.register(sub)
    acc = sub.add_parser(
        "accuracy", help="error against dt, scheme and solver tolerance; Pareto plot",
        description="Error (95 % CI) against dt, scheme and solver tolerance on exact "
                    "problems and a crowd, fitted log-log slopes, error-vs-dt and Pareto plots, "
                    "and the per-step cost of walls, noise and radius laws.")
    acc.add_argument("--quick", action="store_true",
                     help="fewer paths and a shorter crowd run (under a minute)")
    acc.add_argument("--out", default="bench_out",
                     help="directory for CSV and PNG files (default bench_out)")
    acc.add_argument("--seed", type=int, default=0, help="seed of the Brownian paths")
    acc.add_argument("--problems", nargs="+", default=list(PROBLEMS), choices=PROBLEMS,
                     metavar="NAME", help=f"subset of: {' '.join(PROBLEMS)} (default all)")
    acc.set_defaults(func=_accuracy)
