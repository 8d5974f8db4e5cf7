"""Calibrates the headway law's time gap T against Weidmann's speed-density relation.

For each T and density rho, a ring corridor (sweep_core.model.ring: inner radius 3 m, outer
5 m, agents of radius 0.2 m, free speed 1.34 m/s, no noise) is run for WARM s and then for
MEASURE s; the measured speed is the mean over agents and steps of the speed along the ring.
Prints one row per (T, w, rho) and, per (T, w), the largest relative error against Weidmann
over rho in [0.5, 3]; writes the table as CSV (argument 1, default headway_calibration.csv).
T = 0 is the pure model.

    python scripts/calibrate_headway.py [out.csv] [T1,T2,...] [w1,w2,...] [rho1,...] [seeds]
"""
from __future__ import annotations

import csv
import sys
import time

import numpy as np

from sweep_core import Scene, Simulator
from sweep_core.model.ring import ring_corridor, tangential_speed, weidmann

DT, WARM, MEASURE = 0.05, 10.0, 10.0


def measure(density: float, time_gap: float | None, margin: float, seed: int) -> float:
    """Mean speed (m/s) along the ring after the warm-up."""
    sim = Simulator(Scene.from_dict(ring_corridor(density, seed=seed, time_gap=time_gap,
                                                  margin=margin)), dt=DT, seed=seed)
    sim.run(WARM)
    total, count = 0.0, 0
    for _ in range(int(round(MEASURE / DT))):
        sim.step()
        s = tangential_speed(sim.positions, sim.velocities)
        total += float(s.sum())
        count += len(s)
    return total / count


def main() -> None:
    out = sys.argv[1] if len(sys.argv) > 1 else "headway_calibration.csv"
    gaps = ([float(x) for x in sys.argv[2].split(",")] if len(sys.argv) > 2
            else [0.3, 0.4, 0.5])
    margins = ([float(x) for x in sys.argv[3].split(",")] if len(sys.argv) > 3
               else [0.0, 0.1, 0.2, 0.3])
    rhos = ([float(x) for x in sys.argv[4].split(",")] if len(sys.argv) > 4
            else [0.5, 1.0, 1.5, 2.0, 2.5, 3.0])
    seeds = range(int(sys.argv[5]) if len(sys.argv) > 5 else 1)
    rows = []
    for T in gaps:
        for w in margins if T else [0.0]:
            for rho in rhos:
                t0 = time.perf_counter()
                v = [measure(rho, None if T == 0 else T, w, s) for s in seeds]
                ref = float(weidmann(rho))
                rows.append((T, w, rho, float(np.mean(v)), float(np.std(v)), ref,
                             (float(np.mean(v)) - ref) / ref))
                print(f"T={T:g} w={w:g} rho={rho:g} v={np.mean(v):.3f} +- {np.std(v):.3f} "
                      f"weidmann={ref:.3f} err={rows[-1][-1]:+.1%} "
                      f"({time.perf_counter() - t0:.0f} s)", flush=True)
    with open(out, "w", newline="") as f:
        wr = csv.writer(f)
        wr.writerow(["time_gap_s", "margin_m", "density_per_m2", "speed_m_per_s",
                     "speed_std_over_seeds_m_per_s", "weidmann_m_per_s", "relative_error"])
        wr.writerows(rows)
    for T, w in dict.fromkeys((r[0], r[1]) for r in rows):
        err = [abs(r[-1]) for r in rows if (r[0], r[1]) == (T, w) and 0.5 <= r[2] <= 3.0]
        print(f"T={T:g} w={w:g}: largest |error| over rho in [0.5, 3] = {max(err):.1%}")


if __name__ == "__main__":
    main()
