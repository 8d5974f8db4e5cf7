"""Calibrates the collision-free speed model's law (``flows.headway``, law csm) jointly against
Weidmann's speed-density relation and the bottleneck flows of Seyfried et al. (2009).

For each (T, a) of the grid (repulsion range D fixed) and each seed:
- ring corridor (sweep_core.model.ring: inner radius 3 m, outer 5 m, disks of 0.2 m, free
  speed 1.34 m/s, noise sigma 0.05 m/sqrt(s), dt 0.05 s) at each density: the mean speed
  along the ring over agents and steps from 10 s to 20 s, against Weidmann's;
- the bottleneck of ``sweep verify`` (sweep_core.verify.diagrams.bottleneck_scene: 150 people,
  widths 0.8, 1.0, 1.2 m): the steady flow where the bottleneck ends (PedPy's crossings,
  10 %-90 %), against Seyfried et al.'s at that width.
Prints one row per measurement and, per (T, a), the largest relative error of each target
over seeds; writes every row as CSV (argument 1, default speed_law_calibration.csv).

    python scripts/calibrate_speed_law.py [out.csv] [T1,T2,...] [a1,a2,...] [seeds] [D]
"""
from __future__ import annotations

import csv
import sys
import time

from sweep_core import Scene, Simulator
from sweep_core.model.ring import ring_corridor, tangential_speed, weidmann
from sweep_core.verify.base import Case, simulate
from sweep_core.verify.diagrams import WIDTHS, bottleneck_scene, seyfried, steady_flow

DT, WARM, MEASURE = 0.05, 10.0, 10.0
DENSITIES = (0.5, 1.0, 2.0, 3.0)


def ring_speed(density: float, law: dict, seed: int) -> float:
    """Mean speed (m/s) along the ring after the warm-up."""
    spec = ring_corridor(density, seed=seed)
    spec["noise"] = {"sigma": 0.05}
    spec["flows"] = {"headway": law}
    sim = Simulator(Scene.from_dict(spec), dt=DT, seed=seed)
    sim.run(WARM)
    total, count = 0.0, 0
    for _ in range(int(round(MEASURE / DT))):
        sim.step()
        s = tangential_speed(sim.positions, sim.velocities)
        total += float(s.sum())
        count += len(s)
    return total / count


def bottleneck_flow(width: float, law: dict, seed: int) -> float:
    """Steady flow (1/s) out of the bottleneck of ``sweep verify``."""
    case = Case("calibration", "bottleneck", 400.0, inline=bottleneck_scene(width, law),
                record_every=2, stop_when_empty=True)
    tr = simulate(case, seed)
    if tr.error:
        raise RuntimeError(tr.error)
    return steady_flow(tr, width)


def main() -> None:
    out = sys.argv[1] if len(sys.argv) > 1 else "speed_law_calibration.csv"
    gaps = [float(x) for x in sys.argv[2].split(",")] if len(sys.argv) > 2 else [0.6, 0.8, 1.0]
    strengths = ([float(x) for x in sys.argv[3].split(",")] if len(sys.argv) > 3
                 else [2.0, 5.0])
    seeds = range(int(sys.argv[4]) if len(sys.argv) > 4 else 2)
    reach = float(sys.argv[5]) if len(sys.argv) > 5 else 0.1
    rows = []
    for T in gaps:
        for a in strengths:
            law = {"law": "csm", "time_gap": T, "repulsion": a, "repulsion_range": reach}
            for seed in seeds:
                for what, x in [("ring", d) for d in DENSITIES] + [("bottleneck", w)
                                                                  for w in WIDTHS]:
                    t0 = time.perf_counter()
                    if what == "ring":
                        value, ref = ring_speed(x, law, seed), float(weidmann(x))
                    else:
                        value, ref = bottleneck_flow(x, law, seed), seyfried(x)
                    rows.append((T, a, reach, seed, what, x, value, ref, value / ref - 1.0))
                    print(f"T={T:g} a={a:g} D={reach:g} seed={seed} {what} {x:g}: {value:.3f} "
                          f"against {ref:.3f} ({value / ref - 1.0:+.1%}, "
                          f"{time.perf_counter() - t0:.0f} s)", flush=True)
    with open(out, "w", newline="") as f:
        wr = csv.writer(f)
        wr.writerow(["time_gap_s", "repulsion", "repulsion_range_m", "seed", "measure",
                     "density_per_m2_or_width_m", "value", "reference", "relative_error"])
        wr.writerows(rows)
    for T, a in dict.fromkeys((r[0], r[1]) for r in rows):
        mine = [r for r in rows if (r[0], r[1]) == (T, a)]
        ring = max(abs(r[-1]) for r in mine if r[4] == "ring")
        neck = max(abs(r[-1]) for r in mine if r[4] == "bottleneck")
        print(f"T={T:g} a={a:g}: largest |error| Weidmann {ring:.1%}, bottleneck {neck:.1%}")


if __name__ == "__main__":
    main()
