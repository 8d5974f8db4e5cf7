"""``sweep bench robots``: what a robot's laser scan costs among N people.

For each N, N people of radius 0.25 m are spawned in a square room of side sqrt(N / 0.6) m
(0.6 people per m^2) and one robot stands at the middle of its south wall, facing north; the
scan (``robots[0].scan``: range_max 30 m, a full turn) is cast ``--repeat`` times from there
for each beam count (``--beams``). Times in ms per scan, median over the repeats;
core_pct_10hz = 100 * median * 10 / 1000: the share of one core a 10 Hz scan takes.
"""
from __future__ import annotations

import argparse
import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from sweep_core.bench import options
from sweep_core.bench.tables import table_row, write_csv
from sweep_core.model.robots import MAX_BEAMS
from sweep_core.model.scene import Scene
from sweep_core.numerics.robots.scan import scan

COLUMNS = ("N", "beams", "scan_ms", "scan_max_ms", "core_pct_10hz")


def room(n: int) -> Scene:
    """N people at 0.6 per m^2 and a robot at the middle of the south wall."""
    side = max(4.0, math.sqrt(n / 0.6))
    return Scene.from_dict({
        "agents": {"spawn": {"count": n, "radius": 0.25, "seed": 1, "region": {
            "kind": "rectangle", "min": [0.5, 1.5], "max": [side - 0.5, side - 0.5]}}},
        "walls": [{"kind": "polyline", "points": [[0, 0], [side, 0], [side, side], [0, side],
                                                  [0, 0]]}],
        "robots": [{"name": "bench", "radius": 0.3, "pose": [side / 2, 0.8, math.pi / 2],
                    "scan": {"range_max": 30.0}}]})


def measure(n: int, beams: int, repeat: int) -> dict:
    scene = room(n)
    robot = scene.robots[0]
    assert robot.scan is not None
    spec = replace(robot.scan, angle_min=-math.pi, angle_max=math.pi,
                   increment=2 * math.pi / beams)
    q, r = scene.positions, scene.radii(0.0)
    scan(spec, robot.pose, 0.0, 0, scene.geometry, q, r)  # compiled or loaded before timing
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        scan(spec, robot.pose, 0.0, 0, scene.geometry, q, r)
        times.append(time.perf_counter() - start)
    med = float(np.median(times)) * 1e3
    return {"N": n, "beams": spec.beams, "scan_ms": med, "scan_max_ms": max(times) * 1e3,
            "core_pct_10hz": med}


def run(args: argparse.Namespace) -> int:
    options.counts(args.sizes, "--sizes", high=options.MAX_AGENTS, example="1000")
    options.counts(args.beams, "--beams", high=MAX_BEAMS, example="360")
    options.count(args.repeat, "--repeat", example="50")
    options.csv_path(args.csv)
    print("per scan, ms (median and max over the repeats); core_pct_10hz: one core's share")
    print(" ".join(f"{c:>14}" for c in COLUMNS), flush=True)
    results = []
    for n in args.sizes:
        for beams in args.beams:
            row = measure(n, beams, args.repeat)
            results.append(row)
            print(table_row(row, COLUMNS, [14] * len(COLUMNS)), flush=True)
    write_csv(Path(args.csv), results, COLUMNS)
    print(f"csv: {args.csv}")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``robots`` to the ``bench`` subcommands."""
    p = sub.add_parser("robots", help="cost of a robot's laser scan among N people")
    p.add_argument("--sizes", type=int, nargs="+", default=[100, 1000], metavar="N",
                   help="people round the robot (default 100 1000)")
    p.add_argument("--beams", type=int, nargs="+", default=[360, 1440],
                   help="beams of the scan (default 360 1440)")
    p.add_argument("--repeat", type=int, default=50, help="scans timed per row (default 50)")
    p.add_argument("--csv", default="bench_robots.csv", help="CSV file to write")
    p.set_defaults(func=run)
