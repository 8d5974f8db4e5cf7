"""``sweep run``: run a scene headless, record it to MCAP, print and write the summary."""
from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

from sweep_core.errors import RecordingError
from sweep_core.io import topics
from sweep_core.io.metadata import run_metadata
from sweep_core.io.recording import BackgroundRecorder
from sweep_core.model.scene import load_scene
from sweep_core.numerics import paths
from sweep_core.numerics.projection import SolverOptions
from sweep_core.numerics.projection.options import METHODS
from sweep_core.numerics.schemes import SCHEMES
from sweep_core.numerics.simulator import Simulator


def _run(args: argparse.Namespace) -> int:
    scene = load_scene(args.scene)
    solver = SolverOptions.from_values(args.eps_abs, args.max_iter, exact_vars=args.exact_vars,
                                       tol=args.tol, max_rounds=args.max_rounds,
                                       method=args.method)
    sim = Simulator(scene, dt=args.dt, seed=args.seed, scheme=args.scheme, solver=solver)
    scene.check_horizon(args.t_end)
    out = Path(args.out)
    stats = {"min_gap": math.inf, "contacts_max": 0, "contacts_sum": 0, "steps": 0,
             "backend_agents_max": 0, "bound_max_m": 0.0}

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
                stats["bound_max_m"] = max(stats["bound_max_m"], s.bound)

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
        "backend_agents_max": stats["backend_agents_max"],
        "bound_max_m": stats["bound_max_m"], "tol_m": solver.tol, "recording": str(out),
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


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``run`` to the ``sweep`` command's subparsers."""
    parser = sub.add_parser("run", help="run a scene headless and record it to MCAP")
    parser.add_argument("scene", nargs="?", default=None,
                        help="scene YAML (default: the bundled room with a door, 200 agents)")
    parser.add_argument("--t-end", type=float, default=10.0, help="simulated time, s (default 10)")
    parser.add_argument("--dt", type=float, default=0.01, help="time step, s (default 0.01)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the Brownian path (default 0)")
    parser.add_argument("--scheme", default="projected_euler", choices=sorted(SCHEMES))
    parser.add_argument("--out", default="run.mcap", help="MCAP file to write (default run.mcap)")
    parser.add_argument("--frame-id", default="map", help="frame of the recorded poses")
    parser.add_argument("--record-every", type=int, default=1, metavar="K",
                        help="record every K-th step (default 1: every step)")
    parser.add_argument("--eps-abs", type=float, default=SolverOptions.eps_abs,
                        help="QP tolerance, m (default %(default)g)")
    parser.add_argument("--max-iter", type=int, default=SolverOptions.max_iter,
                        help="iteration cap of the proxsuite backend")
    parser.add_argument("--exact-vars", type=int, default=SolverOptions.exact_vars, metavar="V",
                        help="contact clusters of up to V variables (2 per agent) are solved exactly "
                             "by the active-set solver, larger ones by the interior-point backend "
                             "(default %(default)d)")
    parser.add_argument("--tol", type=float, default=SolverOptions.tol, metavar="M",
                        help="certified accuracy of each projection, m: the step's distance to the "
                             "exact projection is proved below it (default %(default)g)")
    parser.add_argument("--max-rounds", type=int, default=SolverOptions.max_rounds, metavar="R",
                        help="rounds of the certified solver per step before the clusters it has "
                             "not certified go to the exact or interior-point solvers "
                             "(default %(default)d)")
    parser.add_argument("--method", default=SolverOptions.method, choices=METHODS,
                        help="projection: the certified solver (default), or the cluster solvers "
                             "alone (closed form, active set, interior point)")
    parser.add_argument("--path-dt", type=float, default=None, metavar="FINE",
                        help="draw the Brownian path at FINE s and sum dt/FINE increments per step, "
                             "so runs at different dt share one path (sweep compare)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.set_defaults(func=_run)
