"""Calibrates the collision-free speed model's law (``flows.headway``, law csm) jointly against
Weidmann's speed-density relation and the bottleneck flows of Seyfried et al. (2009), measuring
each target exactly as ``sweep verify`` does:

- RiMEA test 4 (sweep_core.verify.diagrams.ring_case, ring_measure): the ring corridor's run
  of 70 s with the law, PedPy's Voronoi speed in the 2 m x 1.5 m area after 10 s, at 0.5, 1,
  2, 3 /m^2, against Weidmann's speed at the nominal density;
- the bottleneck validation (bottleneck_scene, steady_flow: 150 people, widths 0.8, 1.0,
  1.2 m): the flow where the bottleneck ends (PedPy's crossings, 10 %-90 %), against
  Seyfried et al.'s at that width.

For each point (T, k, a, k2, f) of the grid (time gaps x lateral fractions x strengths x
fades x length fractions; range D fixed) and each seed (the run's seed, which also draws the
spawned crowd, as in the test) the runs are spread over ``--jobs`` processes. Prints one row
per run and, per point, the largest relative error of each target over seeds and
measurements; writes every row as CSV.

    python scripts/calibrate_speed_law.py OUT.csv --time-gap 1.0,1.1 --lateral 0.65,1 \\
        --repulsion 2 --seeds 2 --jobs 2

``--fade`` takes k2 values (a fade below k is the sharp corridor, written as k), ``--length``
f values, ``--follow`` beta values; ``--first-seed`` starts the seeds elsewhere than 0.
``--append`` adds the rows to an existing OUT.csv of the same columns.
"""
from __future__ import annotations

import argparse
import csv
import time
from concurrent.futures import ProcessPoolExecutor

from sweep_core.model.ring import weidmann
from sweep_core.verify.base import Case, simulate
from sweep_core.verify.diagrams import (
    TARGET_DENSITIES,
    WIDTHS,
    bottleneck_scene,
    ring_case,
    ring_measure,
    seyfried,
    steady_flow,
)

HEADER = ["time_gap_s", "lateral", "repulsion", "repulsion_range_m", "fade", "length", "follow",
          "seed", "measure", "density_per_m2_or_width_m", "value", "reference",
          "relative_error"]


def one(job: tuple[dict, int, str, float]) -> tuple:
    """One run: (law, seed, "ring" or "bottleneck", density or width) -> a CSV row."""
    law, seed, what, x = job
    t0 = time.perf_counter()
    if what == "ring":
        tr = simulate(ring_case(x, law), seed)
        value, ref = (ring_measure(tr)[1] if not tr.error else float("nan")), float(weidmann(x))
    else:
        tr = simulate(Case("calibration", "bottleneck", 400.0,
                           inline=bottleneck_scene(x, law), record_every=2,
                           stop_when_empty=True), seed)
        value, ref = (steady_flow(tr, x) if not tr.error else float("nan")), seyfried(x)
    if tr.error:
        print(f"  {what} {x:g} seed {seed}: {tr.error}", flush=True)
    row = (law["time_gap"], law["lateral"], law["repulsion"], law["repulsion_range"],
           law["fade"], law["length"], law["follow"], seed, what, x, value, ref,
           value / ref - 1.0)
    print(f"{label(law)} seed={seed} {what} {x:g}: {value:.3f} "
          f"against {ref:.3f} ({row[-1]:+.1%}, {time.perf_counter() - t0:.0f} s)", flush=True)
    return row


def label(law: dict) -> str:
    return (f"T={law['time_gap']:g} k={law['lateral']:g} a={law['repulsion']:g} "
            f"k2={law['fade']:g} f={law['length']:g} beta={law['follow']:g}")


def numbers(text: str) -> list[float]:
    return [float(v) for v in text.split(",")]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out", nargs="?", default="speed_law_calibration.csv")
    ap.add_argument("--time-gap", type=numbers, default=[1.0, 1.1], help="T values (s)")
    ap.add_argument("--lateral", type=numbers, default=[0.65, 1.0], help="k values, (0, 1]")
    ap.add_argument("--repulsion", type=numbers, default=[2.0], help="a values")
    ap.add_argument("--range", type=float, default=0.1, help="D (m)")
    ap.add_argument("--fade", type=numbers, default=[0.0], help="k2 values, [k, 1]")
    ap.add_argument("--length", type=numbers, default=[1.0], help="f values, (0, 1]")
    ap.add_argument("--follow", type=numbers, default=[0.0], help="beta values, [0, 1)")
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--append", action="store_true")
    ap.add_argument("--jobs", type=int, default=2)
    args = ap.parse_args()
    laws = [{"law": "csm", "time_gap": T, "lateral": k, "repulsion": a,
             "repulsion_range": args.range, "fade": max(k2, k), "length": f, "follow": b}
            for T in args.time_gap for k in args.lateral for a in args.repulsion
            for k2 in args.fade for f in args.length for b in args.follow]
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    jobs = [(law, seed, what, x) for law in laws for seed in seeds
            for what, x in [("ring", d) for d in TARGET_DENSITIES] + [("bottleneck", w)
                                                              for w in WIDTHS]]
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        rows = list(pool.map(one, jobs))
    with open(args.out, "a" if args.append else "w", newline="") as fh:
        wr = csv.writer(fh)
        if not args.append:
            wr.writerow(HEADER)
        wr.writerows(rows)
    for law in laws:
        key = (law["time_gap"], law["lateral"], law["repulsion"], law["repulsion_range"],
               law["fade"], law["length"], law["follow"])
        mine = [r for r in rows if r[:7] == key]
        ring = max(abs(r[-1]) for r in mine if r[8] == "ring")
        neck = max(abs(r[-1]) for r in mine if r[8] == "bottleneck")
        print(f"{label(law)}: largest |error| Weidmann {ring:.1%}, bottleneck {neck:.1%}")


if __name__ == "__main__":
    main()
