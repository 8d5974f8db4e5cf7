"""``sweep bench walking``: the mean speed ``sweep analyze`` reports against the truth.

A crowd drifts freely (agents 4.5 m apart, no walls) at u = 1.2 m/s with noise sigma = 0.3
m/sqrt(s); its displacement over a window w is N(u w, sigma^2 w I) per agent, so its true mean
speed over the window is the Rice mean E|X| / w. One run is recorded and read three ways, side
by side: the one-step increment |q(t + dt) - q(t)| / dt (what the field never reports: noise
of order sigma / sqrt(dt)), ``sweep analyze``'s windowed speed, and PedPy's
``compute_individual_speed`` on the exported trajectories (``frame_step`` the same number of
frames). Targets: ``sweep analyze`` within 10 % of the truth, and within 2 % of PedPy.
"""
from __future__ import annotations

import argparse
import math
import tempfile
from pathlib import Path

import numpy as np

from sweep_core import checks
from sweep_core.analysis import metrics
from sweep_core.analysis.pedpy_export import check_pedpy, read_trajectories
from sweep_core.analysis.speed import DEFAULT_WINDOW_S
from sweep_core.bench.tables import write_csv
from sweep_core.errors import SweepError
from sweep_core.io.metadata import run_metadata
from sweep_core.io.recording import runs
from sweep_core.model.scene import Scene
from sweep_core.numerics.simulator import Simulator
from sweep_core.text import text_table

#: the crowd: drift (m/s), noise (m/sqrt(s)), spacing (m)
DRIFT, SIGMA, SPACING = 1.2, 0.3, 4.5
#: targets: relative departure from the truth, and from PedPy
TARGET_TRUTH, TARGET_PEDPY = 0.10, 0.02


def rice_mean_speed(u: float, sigma: float, w: float) -> float:
    """E|X| / w (m/s) for X ~ N((u w, 0), sigma^2 w I): the true mean speed over a window w."""
    from scipy import stats
    s = sigma * math.sqrt(w)
    return float(stats.rice(b=u * w / s, scale=s).mean()) / w


def crowd(agents: int) -> Scene:
    """``agents`` disks of 0.2 m on a grid SPACING apart, drifting freely."""
    side = max(1, int(math.ceil(math.sqrt(agents))))
    pts = [[SPACING * (k % side), SPACING * (k // side)] for k in range(agents)]
    return Scene.from_dict({"name": "drifting_crowd",
                            "agents": {"positions": pts, "radius": 0.2},
                            "drift": {"kind": "uniform", "velocity": [DRIFT, 0.0]},
                            "noise": {"sigma": SIGMA}}, name="drifting_crowd")


def measure(agents: int, t_end: float, dt: float, seed: int, folder: Path) -> list[dict]:
    """One recorded run read the three ways (module docstring): a row per way."""
    scene = crowd(agents)
    sim = Simulator(scene, dt=dt, seed=seed)
    out = folder / "drifting.mcap"
    meta = run_metadata(scene, sim, t_end, 1)
    meta["path_dt"] = ""
    run = runs.record_run(sim, t_end, out, meta)
    if run.failure is not None:
        raise run.failure
    an = metrics.analyze(out)
    window = an.speed_window
    n = int(round(window / (2 * dt)))
    traj = read_trajectories(out)
    import pedpy
    ped = pedpy.compute_individual_speed(
        traj_data=traj.to_pedpy(), frame_step=n,
        speed_calculation=pedpy.SpeedCalculation.BORDER_SINGLE_SIDED)
    # the one-step increment, from the same recorded positions
    order = np.lexsort((traj.frames, traj.ids))
    ids, xy = traj.ids[order], traj.xy[order]
    same = ids[1:] == ids[:-1]
    one_step = float(np.mean(np.hypot(*(xy[1:] - xy[:-1])[same].T) / dt))
    windowed = float(an.summary["speed"]["mean_m_per_s"])
    # the truth: two-sided windows of 2 n dt inside the run, one-sided (n dt) at its ends
    frames = int(round(t_end / dt)) + 1
    inner = max(frames - 2 * n, 0)
    truth = ((inner * rice_mean_speed(DRIFT, SIGMA, 2 * n * dt)
              + (frames - inner) * rice_mean_speed(DRIFT, SIGMA, n * dt)) / frames)
    rows = []
    for way, v in (("one-step increment", one_step), ("sweep analyze", windowed),
                   ("PedPy", float(ped["speed"].mean()))):
        rows.append({"way": way, "window_s": dt if way.startswith("one") else 2 * n * dt,
                     "mean_speed_m_per_s": v, "truth_m_per_s": truth,
                     "vs_truth": v / truth - 1.0})
    rows[1]["vs_pedpy"] = windowed / rows[2]["mean_speed_m_per_s"] - 1.0
    rows[1]["ok"] = (abs(rows[1]["vs_truth"]) <= TARGET_TRUTH
                     and abs(rows[1]["vs_pedpy"]) <= TARGET_PEDPY)
    return rows


def run(args: argparse.Namespace) -> int:
    for name, value, lo, hi in (("--agents", args.agents, 1, 10000),
                                ("--t-end", args.t_end, 2 * DEFAULT_WINDOW_S, 600.0)):
        if not lo <= value <= hi or not math.isfinite(value):
            raise SweepError(f"{name}: {value!r} is outside {lo:g}-{hi:g} (fix: give a value "
                             "in that range)")
    checks.integer(args.seed, "--seed", fix="e.g. --seed 0")
    check_pedpy()
    with tempfile.TemporaryDirectory() as tmp:
        rows = measure(args.agents, args.t_end, 0.01, args.seed, Path(tmp))
    print(f"drifting crowd: {args.agents} agents, u {DRIFT:g} m/s, sigma {SIGMA:g} m/sqrt(s), "
          f"dt 0.01 s, {args.t_end:g} s, seed {args.seed}; truth: the Rice mean over the "
          "window (one-sided at the run's ends)")
    print(text_table(("way", "window (s)", "mean speed (m/s)", "truth (m/s)", "vs truth",
                      "vs PedPy"),
                     [(r["way"], f"{r['window_s']:g}", f"{r['mean_speed_m_per_s']:.4f}",
                       f"{r['truth_m_per_s']:.4f}", f"{100 * r['vs_truth']:+.1f} %",
                       f"{100 * r['vs_pedpy']:+.2f} %" if "vs_pedpy" in r else "")
                      for r in rows], "<>>>>>"))
    ok = rows[1]["ok"]
    print(f"target (sweep analyze within {TARGET_TRUTH:.0%} of the truth and "
          f"{TARGET_PEDPY:.0%} of PedPy): {'met' if ok else 'NOT met'}")
    write_csv(Path(args.csv), rows, ("way", "window_s", "mean_speed_m_per_s", "truth_m_per_s",
                                     "vs_truth", "vs_pedpy", "ok"))
    return 0 if ok else 1


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``walking`` to the ``bench`` subcommands."""
    p = sub.add_parser("walking", help="the mean speed sweep analyze reports against the "
                       "truth and PedPy (a freely drifting crowd)")
    p.add_argument("--agents", type=int, default=60, help="agents (default 60)")
    p.add_argument("--t-end", type=float, default=10.0, help="simulated seconds (default 10)")
    p.add_argument("--seed", type=int, default=0, help="seed of the Brownian path (default 0)")
    p.add_argument("--csv", default="bench_walking.csv", help="CSV file to write")
    p.set_defaults(func=run)
