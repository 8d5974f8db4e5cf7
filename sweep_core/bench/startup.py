"""``sweep bench startup``: how long the command takes to answer before any work.

Each line runs in a fresh interpreter (``python -m sweep_core.cli ...``, as the ``sweep``
script does) ``--repeat`` times, interleaved with a bare interpreter (``python -c pass``);
times are wall seconds, median and max over the repeats, and the ratio of the medians to the
bare interpreter's. ``sweep --help`` and ``--version`` import none of the engine; a command's
own help imports its module (the engine's imports, about a second).
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from sweep_core.bench import options
from sweep_core.bench.tables import write_csv

COLUMNS = ("command", "median_s", "max_s", "over_python")

#: what is timed: label -> the arguments after the interpreter
LINES: dict[str, list[str]] = {
    "python -c pass": ["-c", "pass"],
    "sweep --help": ["-m", "sweep_core.cli", "--help"],
    "sweep --version": ["-m", "sweep_core.cli", "--version"],
    "sweep run --help": ["-m", "sweep_core.cli", "run", "--help"],
}


def measure(repeat: int) -> list[dict]:
    """Median and max wall time of each of :data:`LINES` over ``repeat`` interleaved runs."""
    times: dict[str, list[float]] = {label: [] for label in LINES}
    for _ in range(repeat):
        for label, argv in LINES.items():
            start = time.perf_counter()
            subprocess.run([sys.executable, *argv], check=True, stdout=subprocess.DEVNULL)
            times[label].append(time.perf_counter() - start)
    base = float(np.median(times["python -c pass"]))
    return [{"command": label, "median_s": float(np.median(t)), "max_s": max(t),
             "over_python": float(np.median(t)) / base} for label, t in times.items()]


def run(args: argparse.Namespace) -> int:
    options.count(args.repeat, "--repeat", example="7")
    options.csv_path(args.csv)
    rows = measure(args.repeat)
    print(f"wall time of a fresh interpreter, s (median and max over {args.repeat} runs); "
          "over_python: median / python -c pass's")
    print(f"{'command':<18} {'median_s':>9} {'max_s':>9} {'over_python':>12}")
    for r in rows:
        print(f"{r['command']:<18} {r['median_s']:>9.3f} {r['max_s']:>9.3f} "
              f"{r['over_python']:>12.2f}")
    write_csv(Path(args.csv), rows, COLUMNS)
    print(f"csv: {args.csv}")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``startup`` to the ``bench`` subcommands."""
    p = sub.add_parser("startup", help="wall time of sweep --help, --version and a command's "
                       "help beside a bare interpreter's")
    p.add_argument("--repeat", type=int, default=7, help="runs of each line (default 7)")
    p.add_argument("--csv", default="bench_startup.csv", help="CSV file to write")
    p.set_defaults(func=run)
