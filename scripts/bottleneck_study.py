"""The bottleneck validation's runs over many seeds, for docs/validation.md ("The bottleneck:
its scene, its measurement, the walls"): the scene as ``sweep verify`` builds it
(sweep_core.verify.diagrams.bottleneck_scene, 150 people in x = 0-8 m) or as JuPedSim's
validation of the same experiments placed them (``--room``: 200 people over the whole
10 m x 8 m room), with the speed law ``--headway`` (a JSON ``flows.headway``; {} the
defaults), one run after the other in this process. Per run it measures the flow at each
width four ways, each against Seyfried et al.'s (relative error), and the first of them
against the experiments' line as ``sweep verify`` judges it (``10-90 line``:
sweep_core.verify.diagrams.line_flow_at):

- ``10-90``: as ``sweep verify`` (PedPy's crossings where the bottleneck ends, 10 %-90 %);
- ``all end`` and ``all entrance``: (N - 1) / (t_N - t_1) over every crossing of the
  bottleneck's end (x = 12 m) or entrance (x = 10 m);
- ``rolling middle``: JuPedSim's test_13 evaluation, the mean of the rolling flows over
  windows of N / 10 crossings of the bottleneck's middle (x = 11 m), averaged over windows
  of the same length.

``--ring`` runs test 4's ring instead (sweep_core.verify.diagrams.ring_case) at 0.5, 1, 2,
3 /m^2 against Weidmann. Writes one JSON line per run to OUT and prints, per width, the
mean and standard deviation of the errors over seeds, the worst width per seed and the
ratio J(1.2 m) / J(0.8 m).

    nice -n 10 python scripts/bottleneck_study.py out.jsonl --seeds 10
    nice -n 10 python scripts/bottleneck_study.py out.jsonl --seeds 10 --room
    nice -n 10 python scripts/bottleneck_study.py out.jsonl --seeds 3 \\
        --headway '{"wall_repulsion": 5, "time_gap": 1.2}'
    nice -n 10 python scripts/bottleneck_study.py out.jsonl --seeds 3 --ring \\
        --headway '{"wall_repulsion": 5, "time_gap": 1.2}'
"""
from __future__ import annotations

import argparse
import json

import numpy as np

from sweep_core.model.ring import weidmann
from sweep_core.verify.base import Case, Trace, simulate
from sweep_core.verify.diagrams import (
    TARGET_DENSITIES,
    WIDTHS,
    bottleneck_scene,
    line_flow_at,
    ring_case,
    ring_measure,
    seyfried,
    steady_flow,
)


def first_crossings(tr: Trace, x0: float) -> np.ndarray:
    """Sorted times (s) at which each agent's recorded centre is first at x >= x0 (m)."""
    traj = tr.traj
    past = traj.xy[:, 0] >= x0
    ids, frames = traj.ids[past], traj.frames[past]
    order = np.lexsort((frames, ids))
    _, first = np.unique(ids[order], return_index=True)
    return np.sort(frames[order][first] / traj.frame_rate)


def whole_run(t: np.ndarray) -> float:
    return (len(t) - 1) / (t[-1] - t[0])


def rolling(t: np.ndarray) -> float:
    """JuPedSim test_13's rolling flow: windows of n = N / 10 crossings, (n - 1) over each
    window's duration, averaged over windows of n of them, then over those."""
    n = len(t) // 10
    f = (n - 1) / (t[n - 1:] - t[:len(t) - n + 1])
    return float(np.mean(np.convolve(f, np.ones(n) / n, mode="valid")))


def bottleneck(width: float, law: dict, seed: int, room: bool) -> dict:
    spec = bottleneck_scene(width, law, 200 if room else 150)
    if room:
        spec["agents"]["spawn"]["region"]["max"] = [10.0, 8.0]
    tr = simulate(Case(f"headway/{width:g}", "bottleneck", 400.0, inline=spec,
                       record_every=2, stop_when_empty=True), seed)
    ref = seyfried(width)
    flows = {"10-90": steady_flow(tr, width), "all end": whole_run(first_crossings(tr, 12.0)),
             "all entrance": whole_run(first_crossings(tr, 10.0)),
             "rolling middle": rolling(first_crossings(tr, 11.0))}
    return {"width": width, "seed": seed, "error": tr.error,
            **{k: v / ref - 1.0 for k, v in flows.items()},
            "10-90 line": flows["10-90"] / line_flow_at(width) - 1.0, "flow": flows["10-90"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out")
    ap.add_argument("--headway", default="{}", help="flows.headway as JSON ({}: defaults)")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--room", action="store_true", help="200 people over the whole room")
    ap.add_argument("--ring", action="store_true", help="test 4's ring instead")
    args = ap.parse_args()
    law = json.loads(args.headway)
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    rows = []
    for seed in seeds:
        for x in TARGET_DENSITIES if args.ring else WIDTHS:
            if args.ring:
                v = ring_measure(simulate(ring_case(x, law), seed))[1]
                row = {"density": x, "seed": seed, "10-90": v / float(weidmann(x)) - 1.0}
            else:
                row = bottleneck(x, law, seed, args.room)
            row.update(headway=law, room=args.room, ring=args.ring)
            rows.append(row)
            with open(args.out, "a") as fh:
                fh.write(json.dumps(row) + "\n")
            print(json.dumps(row), flush=True)
    key = "density" if args.ring else "width"
    xs = TARGET_DENSITIES if args.ring else WIDTHS
    for how in ["10-90"] if args.ring else ["10-90", "all end", "all entrance",
                                             "rolling middle", "10-90 line"]:
        err = np.array([[next(r[how] for r in rows if r["seed"] == s and r[key] == x)
                         for x in xs] for s in seeds])
        worst = np.max(np.abs(err), axis=1)
        print(f"{how}: " + ", ".join(f"{x:g}: {m:+.1%} (sd {sd:.1%})" for x, m, sd in
                                     zip(xs, err.mean(0), err.std(0, ddof=1)
                                         if len(seeds) > 1 else [0.0] * len(xs)))
              + "; worst per seed " + " ".join(f"{w:.1%}" for w in worst)
              + f"; within 15 % on {int(np.sum(worst <= 0.15))} of {len(seeds)}")
    if not args.ring:
        j = {(r["seed"], r["width"]): r["flow"] for r in rows}
        ratio = [j[(s, 1.2)] / j[(s, 0.8)] for s in seeds]
        print("J(1.2) / J(0.8): " + " ".join(f"{v:.2f}" for v in ratio))


if __name__ == "__main__":
    main()
