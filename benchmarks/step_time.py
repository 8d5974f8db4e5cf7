"""Per-step wall time of the engine on jammed and free-flow crowds (a benchmark, not a test).

    python benchmarks/step_time.py [--sizes 100 1000] [--steps 30]

Prints a table: median / min / max ms per step over the measured steps (after a warm-up),
for a hexagonal jam pushed to its centre (sigma = 0.1) and the same crowd spread out
(free flow, uniform drift), plus the share of steps that needed the exact fallback solver.
"""
from __future__ import annotations

import argparse
import math
import time

import numpy as np

import sweep_core as sc
import sweep_core.projection as projection


def crowd(n: int, jammed: bool) -> sc.Scene:
    cols = int(math.ceil(math.sqrt(n)))
    spacing = 0.5 if jammed else 1.5
    pos = [(c * spacing + (r % 2) * spacing / 2, r * spacing * math.sqrt(3) / 2)
           for r in range(cols) for c in range(cols)][:n]
    pos = np.array(pos)
    drift = ({"kind": "goal", "goal": pos.mean(axis=0).tolist(), "speed": 1.0}
             if jammed else {"kind": "uniform", "velocity": [1.0, 0.2]})
    return sc.Scene.from_dict({"agents": {"positions": pos.tolist(), "radius": 0.24},
                               "drift": drift, "noise": {"sigma": 0.1}})


def measure(scene: sc.Scene, steps: int, warmup: int) -> dict:
    sim = sc.Simulator(scene, dt=0.01, seed=0)
    sim.step(warmup)
    fallbacks = 0
    original = projection._ldp

    def counting(*args):
        nonlocal fallbacks
        fallbacks += 1
        return original(*args)

    projection._ldp = counting
    times = []
    try:
        for _ in range(steps):
            t0 = time.perf_counter()
            sim.step()
            times.append(time.perf_counter() - t0)
    finally:
        projection._ldp = original
    ms = 1e3 * np.array(times)
    return {"median": np.median(ms), "min": ms.min(), "max": ms.max(),
            "contacts": sim.contacts, "fallback_clusters": fallbacks}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[100, 1000])
    parser.add_argument("--steps", type=int, default=30)
    parser.add_argument("--warmup", type=int, default=50)
    args = parser.parse_args()
    print(f"{'N':>6} {'scene':>9} {'median ms':>10} {'min ms':>8} {'max ms':>8} "
          f"{'contacts':>9} {'fallbacks':>9}")
    for n in args.sizes:
        for jammed in (True, False):
            r = measure(crowd(n, jammed), args.steps, args.warmup)
            print(f"{n:>6} {'jammed' if jammed else 'free':>9} {r['median']:>10.2f} "
                  f"{r['min']:>8.2f} {r['max']:>8.2f} {r['contacts']:>9} "
                  f"{r['fallback_clusters']:>9}", flush=True)


if __name__ == "__main__":
    main()
