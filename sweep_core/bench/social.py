"""``sweep bench social``: the bundled controllers over seeds on the bundled robot scenes (or
scene files), and the social-navigation table (docs/social_bench.md defines every column).

Each run (:mod:`sweep_core.bench.social_runs`) is one seeded simulation of a scene with
its robot's controller replaced, stopped at the goal or the time limit; runs go to a pool of
``--workers`` processes. Per (scene, controller) the table gives: success (goal reached with no
robot-on-person contact) and success without any contact, shares of runs; contact events per
run split by cause (robot-on-person, person-on-robot: :mod:`sweep_core.analysis.causes`); time
to goal (s, runs that reached it) and its ratio to the straight-line time at max_speed; the
path-length ratio (path over geodesic distance); the minimum and mean clearance (m); the time
shares in Hall's zones (intimate < 0.45 m, personal < 1.2 m, social < 3.6 m, public) and the
discomfort frequency (share of time with clearance < 0.2 m). Written: ``runs.csv`` (one row per
run), ``summary.csv`` (the table) and ``social.png`` in ``--out``.
"""
from __future__ import annotations

import argparse
import math
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any

import numpy as np

from sweep_core.analysis.drawing import pyplot, save_figure
from sweep_core.bench import options
from sweep_core.bench.social_runs import RUN_COLUMNS, Run, simulate
from sweep_core.bench.tables import write_csv
from sweep_core.ensemble.cluster import WORKER_BYTES, WORKERS_PER_CORE, default_workers
from sweep_core.errors import SceneError, show
from sweep_core.io import limits
from sweep_core.io.outputs import check_folder
from sweep_core.model.controller_spec import CONTROLLERS
from sweep_core.model.gallery import bundled_scenes
from sweep_core.model.scene import load_scene
from sweep_core.numerics.robots.fleet import check_step_length
from sweep_core.text import text_table

SCENES = ("robot_crowd", "crowdnav")
BENCH_CONTROLLERS = tuple(c for c in CONTROLLERS if c != "none")
#: the controllers run unless --controllers names others (within the table's time budget)
DEFAULT_CONTROLLERS = ("pursuit", "orca", "social_force")
#: most seeds per (scene, controller)
MAX_SEEDS = 1000
SUMMARY = ("scene", "controller", "runs", "success", "success_no_contact", "robot_contacts",
           "person_contacts", "time_to_goal_s", "time_ratio", "path_length_ratio",
           "clearance_min_m", "clearance_mean_m", "intimate", "personal", "social", "public",
           "discomfort")


def _mean(rows: list[dict], key: str) -> float:
    vals = [r[key] for r in rows if r[key] is not None and math.isfinite(float(r[key]))]
    return float(np.mean(vals)) if vals else math.nan


def summarise(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per (scene, controller) of the runs: shares and means (SUMMARY columns)."""
    out = []
    keys = sorted({(r["scene"], r["controller"]) for r in rows},
                  key=lambda k: (k[0], BENCH_CONTROLLERS.index(k[1])
                                 if k[1] in BENCH_CONTROLLERS else 99))
    for scene, ctrl in keys:
        group = [r for r in rows if r["scene"] == scene and r["controller"] == ctrl]
        row: dict[str, Any] = {"scene": scene, "controller": ctrl, "runs": len(group)}
        for key in ("success", "success_no_contact"):
            row[key] = float(np.mean([bool(r[key]) for r in group]))
        for key in SUMMARY[5:]:
            row[key] = _mean(group, key)
        out.append(row)
    return out


def figure(summary: list[dict[str, Any]], path: Path) -> None:
    """Bars per scene and controller: success, contacts by cause, time ratio, clearance."""
    plt = pyplot()
    panels = (("success", "success (share of runs)"),
              ("robot_contacts", "robot-on-person contacts per run"),
              ("person_contacts", "person-on-robot contacts per run"),
              ("time_ratio", "time to goal / straight-line time"),
              ("clearance_min_m", "minimum clearance (m)"),
              ("intimate", "time share in intimate zone (< 0.45 m)"))
    scenes = sorted({r["scene"] for r in summary})
    ctrls = [c for c in BENCH_CONTROLLERS if any(r["controller"] == c for r in summary)]
    fig, axes = plt.subplots(2, 3, figsize=(13, 7))
    width = 0.8 / max(len(ctrls), 1)
    for ax, (key, title) in zip(axes.ravel(), panels, strict=True):
        for k, c in enumerate(ctrls):
            vals = [next((r[key] for r in summary if r["scene"] == s and r["controller"] == c),
                         math.nan) for s in scenes]
            ax.bar(np.arange(len(scenes)) + (k - (len(ctrls) - 1) / 2) * width, vals, width,
                   label=c)
        ax.set_xticks(np.arange(len(scenes)), scenes)
        ax.set_title(title, fontsize=9)
    axes[0, 0].legend(fontsize=8)
    fig.suptitle("sweep bench social: means over seeds")
    fig.tight_layout()
    save_figure(fig, path, [])


def _check(args: argparse.Namespace) -> list[Run]:
    seeds = options.count(args.seeds, "--seeds", example="10")
    if seeds > MAX_SEEDS:
        raise SceneError("--seeds", f"{seeds} is more than the limit {MAX_SEEDS}",
                         f"--seeds {MAX_SEEDS} or fewer")
    workers = options.count(args.workers, "--workers", example="2")
    most = max(8, WORKERS_PER_CORE * default_workers())
    if workers > most:  # the pool forks all its processes at once
        raise SceneError("--workers", f"{workers} is more than {most} processes, "
                         f"{WORKERS_PER_CORE} per core of the {default_workers()} this process "
                         f"may use (each about {WORKER_BYTES / 1e6:.0f} MB)",
                         f"--workers {default_workers()}")
    options.count(args.seed, "--seed", low=0, example="0")
    dt = limits.check_dt(args.dt, "--dt")
    t_end = None
    if args.t_end is not None:
        t_end = options.seconds(args.t_end, "--t-end", "30")
        limits.check_run_size(1, dt, t_end, 1)
        limits.check_some_step(t_end, dt, "every run would measure its start only")
    for option, names in (("--scenes", args.scenes), ("--controllers", args.controllers)):
        twice = next((n for k, n in enumerate(names) if n in names[:k]), None)
        if twice is not None:
            raise SceneError(option, f"names {show(twice)} twice: its runs would be made and "
                             "counted twice", f"name each {option[2:-1]} once")
    bundled = {s.name for s in bundled_scenes()}
    for name in args.scenes:
        if name not in bundled and not _is_file(name):
            raise SceneError("--scenes", f"{show(name)} is neither a bundled scene nor a "
                             "scene file", f"use bundled robot scenes (e.g. --scenes "
                             f"{' '.join(SCENES)}) or the paths of scene YAML files")
        scene = load_scene(name)  # a file's own errors name its fields
        if not scene.robots:
            raise SceneError("--scenes", f"{show(name)} has no robot",
                             f"use scenes with a robot, e.g. --scenes {' '.join(SCENES)}")
        try:
            check_step_length(scene, dt)
        except SceneError as err:
            raise SceneError("--dt", f"{dt:g} s is too long for {show(name)}: its "
                             f"{err.field}: {err.problem}", f"--dt below "
                             f"{min(r.radius / r.max_speed for r in scene.robots):g}") from None
        # every robot gets the benchmarked controller, which drives it to its goal
        aimless = next((k for k, r in enumerate(scene.spec.get("robots") or [])
                        if r.get("goal") is None), None)
        if aimless is not None:
            raise SceneError("--scenes", f"robots[{aimless}] of {show(name)} has no goal, and "
                             "the benchmarked controllers drive every robot to its goal",
                             f"give robots[{aimless}] of {show(name)} a goal, or use scenes "
                             f"whose robots have goals, e.g. --scenes {' '.join(SCENES)}")
    for c in args.controllers:
        if c not in BENCH_CONTROLLERS:
            raise SceneError("--controllers", f"unknown controller {show(c)}",
                             f"use some of {' '.join(BENCH_CONTROLLERS)}")
    return [Run(s, c, seed, dt, t_end) for s in args.scenes for c in args.controllers
            for seed in range(args.seed, args.seed + seeds)]


def _is_file(name: str) -> bool:
    """``name`` is the path of a file (a name the file system refuses is not)."""
    try:
        return Path(name).is_file()
    except OSError:  # ENAMETOOLONG
        return False


def run(args: argparse.Namespace) -> int:
    runs = _check(args)
    out = check_folder(args.out, "--out OTHERDIR")
    start = time.perf_counter()
    workers = min(args.workers, len(runs))  # no process without a run
    print(f"{len(runs)} runs on {workers} processes", flush=True)
    rows: list[dict[str, Any]] = []

    def said(row: dict[str, Any]) -> None:
        rows.append(row)
        t = row["time_to_goal_s"]
        print(f"[{len(rows)}/{len(runs)}] {row['scene']} {row['controller']} seed "
              f"{row['seed']}: {'goal not reached' if t is None else f'goal at {t:.2f} s'}"
              f", contacts {row['robot_contacts']} robot-on-person, {row['person_contacts']} "
              f"person-on-robot ({row['wall_s']:.0f} s)", flush=True)

    if workers == 1:
        for r in runs:
            said(simulate(r))
    else:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            for fut in as_completed([pool.submit(simulate, r) for r in runs]):
                said(fut.result())
    order = {(r.scene, r.controller, r.seed): k for k, r in enumerate(runs)}
    rows.sort(key=lambda row: order[(row["scene"], row["controller"], row["seed"])])
    wall = time.perf_counter() - start
    summary = summarise(rows)
    write_csv(out / "runs.csv", rows, RUN_COLUMNS)
    write_csv(out / "summary.csv", summary, SUMMARY)
    figure(summary, out / "social.png")
    cells = [[f"{r[c]:.3g}" if isinstance(r[c], float) else str(r[c]) for c in SUMMARY]
             for r in summary]
    print(text_table(SUMMARY, cells, "<<" + ">" * (len(SUMMARY) - 2)))
    print(f"wall time {wall:.1f} s for {len(runs)} runs ({workers} processes); "
          f"written: {out / 'runs.csv'}, {out / 'summary.csv'}, {out / 'social.png'}")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``social`` to the ``bench`` subcommands."""
    p = sub.add_parser("social", help="the bundled robot controllers on the robot scenes: "
                       "the social-navigation table")
    p.add_argument("--seeds", type=int, default=10, help="seeds per scene and controller "
                   "(default 10)")
    p.add_argument("--seed", type=int, default=0, help="first seed (default 0)")
    p.add_argument("--scenes", nargs="+", default=list(SCENES),
                   help=f"bundled robot scenes or scene files (default {' '.join(SCENES)})")
    p.add_argument("--controllers", nargs="+", default=list(DEFAULT_CONTROLLERS),
                   help=f"controllers, some of {' '.join(BENCH_CONTROLLERS)} (default "
                        f"{' '.join(DEFAULT_CONTROLLERS)})")
    p.add_argument("--dt", type=float, default=0.01, help="time step, s (default 0.01)")
    p.add_argument("--t-end", type=float, default=None,
                   help="time limit of a run, s (default: the scene's horizon, else 30)")
    p.add_argument("--workers", type=int, default=2, help="processes (default 2; at most 4 per core, and no "
                   "more than the runs)")
    p.add_argument("--out", default="bench_social", help="folder of the CSVs and the figure")
    p.set_defaults(func=run)
