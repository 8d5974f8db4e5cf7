"""``sweep bench speed``: step time against the floor and a whole-set QP baseline.

For each N and scene (a hexagonal jam pushed to its centre, and free flow), after a warm-up:

* floor: neighbour search + constraint assembly of the step (``constraints.linearise``), the
  work no exact method avoids;
* step: a full ``Simulator.step()`` (prediction, assembly, projection, feasibility check);
* baseline: assembly plus the same linearised QP solved as one problem by Clarabel over
  every built row and every agent in a row (no clusters, no closed forms), on the same states.
Median, min and max over the measured steps; a CSV is written beside the table.
"""
from __future__ import annotations

import argparse
import csv
import math
import time
from pathlib import Path

import numpy as np

from . import projection
from .constraints import linearise
from .scene import Scene
from .simulator import Simulator


def crowd(n: int, jammed: bool, sigma: float = 0.1) -> Scene:
    """n disks of radius 0.24 m on a hexagonal lattice: touching and pushed to the centre
    (jammed), or 1.5 m apart under a uniform drift (free flow)."""
    cols = int(math.ceil(math.sqrt(n)))
    spacing = 0.5 if jammed else 1.5
    pos = np.array([(c * spacing + (r % 2) * spacing / 2, r * spacing * math.sqrt(3) / 2)
                    for r in range(cols) for c in range(cols)][:n])
    drift = ({"kind": "goal", "goal": pos.mean(axis=0).tolist(), "speed": 1.0}
             if jammed else {"kind": "uniform", "velocity": [1.0, 0.2]})
    return Scene.from_dict({"agents": {"positions": pos.tolist(), "radius": 0.24},
                            "drift": drift, "noise": {"sigma": sigma}})


def _baseline(sim: Simulator, pred: np.ndarray, q: np.ndarray, t1: float) -> float:
    """Seconds to assemble the step's linearised QP and solve it as one Clarabel problem."""
    start = time.perf_counter()
    r1 = sim.scene.radii(t1)
    rows = linearise(sim.scene.geometry, t1, q, r1, projection.first_cutoff(q, pred, r1))
    agents = rows.agents()
    loc = np.full(len(q), -1, dtype=np.intp)
    loc[agents] = np.arange(len(agents))
    c, b = projection._row_matrix(rows, loc, len(agents))
    projection._clarabel(pred[agents].ravel(), c.tocsr(), b, sim.scheme.solver)
    return time.perf_counter() - start


def measure(n: int, jammed: bool, steps: int, warmup: int, baseline: bool) -> dict:
    sim = Simulator(crowd(n, jammed), dt=0.01, seed=0)
    sim.step(warmup)
    floor, step, base = [], [], []
    for _ in range(steps):
        q, t1 = sim.positions, sim.t + sim.dt
        start = time.perf_counter()
        sim.step()
        step.append(time.perf_counter() - start)
        # the floor of that step: assembly at the cutoff the step itself started from
        r1 = sim.scene.radii(t1)
        start = time.perf_counter()
        linearise(sim.scene.geometry, t1, q, r1,
                  projection.first_cutoff(q, sim.last.prediction, r1))
        floor.append(time.perf_counter() - start)
        if baseline:
            base.append(_baseline(sim, sim.last.prediction, q, t1))
    ms = {k: 1e3 * np.array(v) for k, v in (("floor", floor), ("step", step), ("base", base))}
    out = {"N": n, "scene": "jammed" if jammed else "free", "contacts": sim.contacts}
    for k, v in ms.items():
        out[f"{k}_median_ms"] = float(np.median(v)) if len(v) else math.nan
    out["step_min_ms"], out["step_max_ms"] = float(ms["step"].min()), float(ms["step"].max())
    out["step_over_floor"] = out["step_median_ms"] / out["floor_median_ms"]
    out["step_over_baseline"] = out["step_median_ms"] / out["base_median_ms"] if base else math.nan
    return out


def run(args: argparse.Namespace) -> int:
    results = []
    cols = ("N", "scene", "contacts", "floor_median_ms", "step_median_ms", "step_min_ms",
            "step_max_ms", "step_over_floor", "base_median_ms", "step_over_baseline")
    print(" ".join(f"{c:>18}" for c in cols))
    for n in args.sizes:
        for jammed in (True, False):
            r = measure(n, jammed, args.steps, args.warmup, not args.no_baseline)
            results.append(r)
            print(" ".join(f"{r[c]:>18.3f}" if isinstance(r[c], float) else f"{r[c]:>18}"
                           for c in cols), flush=True)
    out = Path(args.csv)
    with out.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=cols)
        writer.writeheader()
        for r in results:
            writer.writerow({c: r[c] for c in cols})
    print(f"csv: {out}")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``speed`` to the ``bench`` subcommands."""
    p = sub.add_parser("speed", help="step time vs floor and a whole-set QP baseline")
    p.add_argument("--sizes", type=int, nargs="+", default=[100, 1000, 4000, 10000])
    p.add_argument("--steps", type=int, default=30, help="measured steps (default 30)")
    p.add_argument("--warmup", type=int, default=20, help="steps before measuring")
    p.add_argument("--no-baseline", action="store_true", help="skip the whole-set QP")
    p.add_argument("--csv", default="bench_speed.csv", help="CSV file to write")
    p.set_defaults(func=run)
