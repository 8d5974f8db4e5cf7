"""The ``sweep`` command: ``run`` a scene headless and record it, ``analyze``, ``replay`` and
``compare`` recordings, ``bench accuracy`` and ``bench speed``."""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import asdict
from importlib import resources
from pathlib import Path

from . import analysis_cli, bench, paths, topics
from .errors import RecordingError, SweepError
from .projection import SolverOptions
from .recording import BackgroundRecorder
from .scene import Scene
from .schemes import SCHEMES
from .simulator import Simulator
from .versions import versions

DEFAULT_SCENE = "room_door.yaml"


def default_scene_path() -> Path:
    """Path of the bundled default scene (a room with a door, 200 agents)."""
    return Path(str(resources.files("sweep_core") / "scenes" / DEFAULT_SCENE))


def load_scene(path: str | None) -> Scene:
    """A scene file, or the bundled default when path is None or empty."""
    return Scene.from_yaml(path or default_scene_path())


def run_metadata(scene: Scene, sim: Simulator, t_end: float | None,
                 record_every: int | None = None) -> dict[str, str]:
    """What a recording needs to be re-simulated: scene, seed, dt, scheme, solver, versions."""
    return {"scene": scene.to_yaml(), "seed": str(sim.seed), "dt": repr(sim.dt),
            "t_end": "" if t_end is None else repr(t_end),
            "record_every": "" if record_every is None else str(record_every),
            "scheme": sim.scheme.name,
            "solver": json.dumps(asdict(sim.scheme.solver)), "versions": json.dumps(versions())}


def _run(args: argparse.Namespace) -> int:
    scene = load_scene(args.scene)
    solver = SolverOptions.from_values(args.eps_abs, args.max_iter, exact_vars=args.exact_vars)
    sim = Simulator(scene, dt=args.dt, seed=args.seed, scheme=args.scheme, solver=solver)
    scene.check_horizon(args.t_end)
    out = Path(args.out)
    stats = {"min_gap": math.inf, "contacts_max": 0, "contacts_sum": 0, "steps": 0,
             "backend_agents_max": 0}

    meta = run_metadata(scene, sim, args.t_end, args.record_every)
    meta["path_dt"] = repr(args.path_dt) if args.path_dt else ""
    # compression and disk writes happen on the recorder's own thread; a backlog of 64 messages
    # (32 recorded steps) at most, so a writer that falls behind slows the run instead of
    # filling the memory
    with BackgroundRecorder(out, metadata=meta, max_backlog=64) as rec:
        for name, msgtype in topics.TYPES.items():
            rec.add_channel("/" + name, msgtype)

        def record(s: Simulator) -> None:
            state = s.state
            if state.step % args.record_every == 0:
                topics.record_state(rec.write, state, args.frame_id)
                if rec.error:
                    raise RecordingError(rec.error)
            if state.step:
                stats["steps"] += 1
                stats["min_gap"] = min(stats["min_gap"], state.min_gap)
                stats["contacts_max"] = max(stats["contacts_max"], state.contacts)
                stats["contacts_sum"] += state.contacts
                stats["backend_agents_max"] = max(stats["backend_agents_max"], s.backend_agents)

        record(sim)
        start = time.perf_counter()
        if args.path_dt:
            paths.run(sim, args.t_end, args.path_dt, progress=not args.quiet, callback=record)
        else:
            sim.run(args.t_end, progress=not args.quiet, callback=record)
        wall = time.perf_counter() - start
    if rec.error:
        raise RecordingError(rec.error)
    steps = stats["steps"]
    summary = {
        "scene": scene.name, "agents": scene.n_agents, "t_end_s": sim.t, "dt_s": sim.dt,
        "seed": sim.seed, "scheme": sim.scheme.name, "steps": steps, "wall_time_s": wall,
        "steps_per_s": steps / wall if wall > 0 else math.inf,
        "ms_per_step": 1e3 * wall / steps if steps else 0.0,
        "min_gap_m": stats["min_gap"] if steps else sim.min_gap,
        "max_overlap_m": max(0.0, -stats["min_gap"]) if steps else 0.0,
        "contacts_mean": stats["contacts_sum"] / steps if steps else 0.0,
        "contacts_max": stats["contacts_max"],
        "backend_agents_max": stats["backend_agents_max"], "recording": str(out),
        "recording_bytes": out.stat().st_size,
    }
    summary_path = out.with_suffix(".summary.json")
    summary_path.write_text(json.dumps(summary, indent=2) + "\n")
    width = max(len(k) for k in summary)
    for key, value in summary.items():
        shown = f"{value:.6g}" if isinstance(value, float) else str(value)
        print(f"{key:<{width}}  {shown}")
    print(f"{'summary':<{width}}  {summary_path}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="sweep", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="run a scene headless and record it to MCAP")
    run.add_argument("scene", nargs="?", default=None,
                     help="scene YAML (default: the bundled room with a door, 200 agents)")
    run.add_argument("--t-end", type=float, default=10.0, help="simulated time, s (default 10)")
    run.add_argument("--dt", type=float, default=0.01, help="time step, s (default 0.01)")
    run.add_argument("--seed", type=int, default=0, help="seed of the Brownian path (default 0)")
    run.add_argument("--scheme", default="projected_euler", choices=sorted(SCHEMES))
    run.add_argument("--out", default="run.mcap", help="MCAP file to write (default run.mcap)")
    run.add_argument("--frame-id", default="map", help="frame of the recorded poses")
    run.add_argument("--record-every", type=int, default=1, metavar="K",
                     help="record every K-th step (default 1: every step)")
    run.add_argument("--eps-abs", type=float, default=SolverOptions.eps_abs,
                     help="QP tolerance, m (default %(default)g)")
    run.add_argument("--max-iter", type=int, default=SolverOptions.max_iter,
                     help="iteration cap of the proxsuite backend")
    run.add_argument("--exact-vars", type=int, default=SolverOptions.exact_vars, metavar="V",
                     help="contact clusters of up to V variables (2 per agent) are solved exactly "
                          "by the active-set solver, larger ones by the interior-point backend "
                          "(default %(default)d)")
    run.add_argument("--path-dt", type=float, default=None, metavar="FINE",
                     help="draw the Brownian path at FINE s and sum dt/FINE increments per step, "
                          "so runs at different dt share one path (sweep compare)")
    run.add_argument("--quiet", action="store_true", help="no progress bar")
    run.set_defaults(func=_run)
    analysis_cli.register(sub)
    bench.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "record_every", 1) < 1:
        parser.error("--record-every: must be >= 1")
    try:
        return args.func(args)
    except SweepError as err:
        print(f"sweep: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("sweep: interrupted; the recording was closed", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
