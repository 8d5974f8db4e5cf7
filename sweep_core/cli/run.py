"""``sweep run``: run a scene headless, record it to MCAP, print and write the summary.

SIGINT and SIGTERM stop the run between two steps; however it ends (completed, interrupted,
failed), the recording gets a last metadata record ``sweep_status`` and its summary and footer,
and ``OUT.summary.json`` is written with that status.
"""
from __future__ import annotations

import argparse
import json
import math
import signal
import sys
import threading
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from sweep_core import checks
from sweep_core.cli.commands import summary
from sweep_core.errors import OutputError, SweepError
from sweep_core.io import limits, markers
from sweep_core.io.metadata import run_metadata
from sweep_core.io.outputs import check_output, write_text
from sweep_core.io.recording.runs import record_run
from sweep_core.model.gallery import resolve_scene_path
from sweep_core.model.room import most_present
from sweep_core.model.scene import Scene, load_scene
from sweep_core.numerics import kernels, paths
from sweep_core.numerics.projection import SolverOptions
from sweep_core.numerics.projection.options import METHODS
from sweep_core.numerics.schemes import SCHEMES
from sweep_core.numerics.simulator import Simulator

if TYPE_CHECKING:
    from sweep_core.io.live import LiveView


class Interrupted(KeyboardInterrupt):
    """SIGINT or SIGTERM stopped the run between two steps; ``signum`` says which."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum

    def __reduce__(self) -> tuple:
        """Pickled with its argument (the signal's number, not its name)."""
        return (type(self), (self.signum,), self.__dict__)


class StopOnSignal:
    """SIGINT and SIGTERM set a flag that the run checks after every step.

    The run then stops between two steps and takes its ordinary exit: the status record, the
    recording's summary and footer, the summary JSON. A step that blocks in native code (a QP
    solve) delays the stop until it returns; a second signal of the same kind gets the default
    action (immediate termination: the recording stays readable up to its last flushed chunk,
    and ``sweep recover`` turns it into a complete file). Handlers can only be installed from
    the main thread; elsewhere this does nothing (SIGINT then stays a KeyboardInterrupt).
    """

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self) -> None:
        self.signum: int | None = None
        self._previous: dict[int, Any] = {}

    def __enter__(self) -> StopOnSignal:
        if threading.current_thread() is threading.main_thread():
            for sig in self.SIGNALS:
                self._previous[sig] = signal.signal(sig, self._handle)
        return self

    def __exit__(self, *exc: object) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)
        self._previous.clear()

    def _handle(self, signum: int, frame: Any) -> None:
        self.signum = signum
        signal.signal(signum, signal.SIG_DFL)

    def check(self) -> None:
        """Raises :class:`Interrupted` once a signal has arrived."""
        if self.signum is not None:
            raise Interrupted(self.signum)


def default_t_end(scene: Scene) -> float:
    """The simulated time (s) of ``sweep run`` without ``--t-end``: 10 s, or the scene's
    horizon when it has one and a robot whose controller drives it to a goal (an episode is
    meant to last until the robot arrives)."""
    if scene.horizon is not None and any(r.goal is not None and r.controller != "none"
                                         for r in scene.robots):
        return scene.horizon
    return 10.0


def _run(args: argparse.Namespace) -> int:
    scene = load_scene(args.scene)
    dt = limits.check_dt(args.dt, "--dt")
    t_end = checks.number(args.t_end if args.t_end is not None else default_t_end(scene),
                          "--t-end", nonnegative=True)
    limits.check_some_step(t_end, dt, "the recording would hold the start only" + (
        "" if args.t_end is not None else f" (the scene's horizon, {t_end:g} s, is --t-end's "
        "default)"))
    solver = SolverOptions.from_values(args.eps_abs, args.max_iter, exact_vars=args.exact_vars,
                                       tol=args.tol, max_rounds=args.max_rounds,
                                       method=args.method, backend=args.backend)
    checks.integer(args.seed, "--seed", fix="e.g. --seed 0")
    sim = Simulator(scene, dt=dt, seed=args.seed, scheme=args.scheme, solver=solver)
    scene.check_horizon(t_end)
    checks.number(args.marker_rate, "--marker-rate", positive=True)
    from sweep_core.io.live import check_rate
    check_rate(args.live_rate)
    if args.path_dt:
        paths.substeps(dt, args.path_dt)  # refused before the recording is created
    sources = scene.flows.sources if scene.flows is not None else ()
    limits.check_run_size(scene.n_agents, dt, t_end, args.record_every,
                          path_dt=args.path_dt or None, frame_id=args.frame_id, force=args.force,
                          entries=np.concatenate([s.times for s in sources]) if sources else None,
                          most=most_present(scene, t_end) if sources else None)
    inputs = scene_files(args.scene, scene)
    out = check_output(args.out, inputs)
    if out.exists() and not args.overwrite:
        raise OutputError(str(out), "exists: sweep run never replaces a recording unasked",
                          "--out OTHER.mcap, or --overwrite to replace it")
    if not out.parent.is_dir():
        if out.parent.exists():
            raise OutputError(str(out), f"its folder {out.parent} is not a folder",
                              "--out in a folder")
        out.parent.mkdir(parents=True)
    summary_out = check_output(out.with_suffix(".summary.json"), inputs)
    live = start_live(args)  # a port in use is said before any work
    stats = {"min_gap": math.inf, "active_rows_max": 0, "active_rows_sum": 0, "steps": 0,
             "backend_agents_max": 0, "bound_max_m": 0.0}

    # compiling (first run on this machine) or loading the kernels, said and timed apart
    warm = kernels.warm_up(lambda line: print(f"sweep: {line}", file=sys.stderr))
    stats["compile_s"] = warm.seconds
    meta = run_metadata(scene, sim, t_end, args.record_every)
    meta["path_dt"] = repr(args.path_dt) if args.path_dt else ""

    def tally(s: Simulator) -> None:
        if s.state.step:
            stats["steps"] += 1
            stats["min_gap"] = min(stats["min_gap"], s.state.min_gap)
            stats["active_rows_max"] = max(stats["active_rows_max"], s.state.contacts)
            stats["active_rows_sum"] += s.state.contacts
            stats["backend_agents_max"] = max(stats["backend_agents_max"], s.backend_agents)
            stats["bound_max_m"] = max(stats["bound_max_m"], s.bound)
        stop.check()

    try:
        # the summary of an earlier run to this --out goes before the recording is opened,
        # which empties it: a run killed at any moment after leaves no summary of another
        # recording
        try:
            summary_out.unlink(missing_ok=True)
        except OSError as err:
            raise OutputError(str(summary_out), "the summary of an earlier run cannot be "
                              f"removed ({err.strerror})", "remove it or give another --out"
                              ) from err
        with StopOnSignal() as stop:
            run = record_run(sim, t_end, out, meta, record_every=args.record_every,
                             frame_id=args.frame_id, path_dt=args.path_dt or None,
                             progress=not args.quiet and live is None, on_state=tally,
                             inputs=inputs, live=live,
                             markers_every=(markers.markers_every(dt, args.record_every,
                                                                  args.marker_rate)))
    finally:
        if live is not None:
            live.stop()
    status, error, failure, wall = run.status, run.error, run.failure, run.wall_s
    summary_path = _write_summary(summary_out, out, scene, sim, solver, stats, wall, status,
                                  error)
    if isinstance(failure, Interrupted):
        print(f"sweep: interrupted by {error} at t = {sim.t:g} s (step {stats['steps']}); "
              f"the recording was closed: {out}; summary: {summary_path}", file=sys.stderr)
        return 128 + failure.signum
    if failure is not None:
        raise failure
    return 0


def start_live(args: argparse.Namespace) -> LiveView | None:
    """The live view of ``--live`` (None without), its address said in one line."""
    if args.live is None:
        return None
    from sweep_core.io.live import LiveError, LiveView, check_rate
    port = checks.integer(args.live, "--live", fix="a port in [0, 65535], 0 for any free one")
    if port > 65535:
        raise LiveError(f"--live: got {port}, a port is at most 65535 (fix: e.g. --live 8765, "
                        "or 0 for any free port)")
    live = LiveView(port, check_rate(args.live_rate))
    rate = live.rate
    print(f"sweep: live view on ws://127.0.0.1:{live.port} (Foxglove: Open connection, "
          f"Foxglove WebSocket), {'as fast as it runs' if rate == 0 else f'{rate:g} x real time'}",
          file=sys.stderr, flush=True)
    return live


def scene_files(path: str | None, scene: Scene) -> list[str]:
    """The files a scene was read from: its YAML (none for the bundled scene) and the map
    YAML it names (outputs may be none of them)."""
    files = [str(resolve_scene_path(path))] if path else []
    source = (scene.spec.get("map") or {}).get("source")
    if source and Path(source).is_file():
        files.append(source)
    return files


def _finite(value: float) -> float | None:
    """``value``, or None (JSON null) when it is infinite or NaN."""
    return value if math.isfinite(value) else None


def _write_summary(summary_path: Path, out: Path, scene: Scene, sim: Simulator,
                   solver: SolverOptions, stats: dict, wall: float, status: str,
                   error: str) -> Path:
    """Writes ``OUT.summary.json`` (strict JSON) and prints it (to stdout); returns its path.

    ``active_rows_*``: rows of a step's linearised constraint set (agent pairs near enough to
    be built, walls, obstacles) that hold with equality after its projection. ``min_gap_m`` is
    null when no constraint exists (one agent and no walls), ``steps_per_s`` when no wall time
    was measured, ``bound_max_m`` when some step's projection was left uncertified (its bound
    infinite: only proven feasible).
    """
    steps = stats["steps"]
    summary = {
        "status": status, "error": error,
        "scene": scene.name, "agents": scene.n_agents, "t_end_s": sim.t, "dt_s": sim.dt,
        "seed": sim.seed, "scheme": sim.scheme.name, "steps": steps,
        "compile_s": stats["compile_s"], "wall_time_s": wall,
        "steps_per_s": steps / wall if wall > 0 else None,
        "ms_per_step": 1e3 * wall / steps if steps else 0.0,
        "min_gap_m": _finite(stats["min_gap"] if steps else sim.min_gap),
        "max_overlap_m": max(0.0, -stats["min_gap"]) if steps else 0.0,
        "active_rows_mean": stats["active_rows_sum"] / steps if steps else 0.0,
        "active_rows_max": stats["active_rows_max"],
        "backend_agents_max": stats["backend_agents_max"],
        "bound_max_m": _finite(stats["bound_max_m"]), "tol_m": solver.tol, "recording": str(out),
        "recording_bytes": out.stat().st_size if out.exists() else 0,
    }
    try:
        write_text(summary_path, json.dumps(summary, indent=2, allow_nan=False) + "\n")
    except SweepError as err:  # e.g. the disk that stopped the recording is full
        print(f"sweep: warning: cannot write the summary: {err}; it is printed below",
              file=sys.stderr)
    width = max(len(k) for k in summary)
    for key, value in summary.items():
        if key == "error" and not value:
            continue
        shown = f"{value:.6g}" if isinstance(value, float) else "-" if value is None \
            else str(value)
        print(f"{key:<{width}}  {shown}")
    print(f"{'summary':<{width}}  {summary_path}")
    return summary_path


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``run`` to the ``sweep`` command's subparsers."""
    parser = sub.add_parser("run", help=summary("run"),
        description="Runs a scene, records every K-th step to OUT (MCAP) and writes "
        "OUT.summary.json. The summary's status is completed, interrupted (SIGINT, SIGTERM: the "
        "run stops between two steps and the recording is closed) or failed (with the error); "
        "the recording ends with a metadata record sweep_status saying the same. "
        "active_rows_mean/max count the rows of a step's linearised constraint set (agent "
        "pairs near enough to be built, walls, obstacles) that hold with equality after its "
        "projection; sweep analyze's 'touching' counts true constraints with a gap <= 1e-6 m, "
        "a different number. A run of more than 1e6 steps, or whose recording would exceed "
        "2 GB, is refused unless --force.")
    parser.add_argument("scene", nargs="?", default=None,
                        help="scene YAML, or the name of a bundled scene when no such file "
                             "exists (sweep scenes lists them; default: room_door, a room "
                             "with a door, 200 agents)")
    parser.add_argument("--t-end", type=float, default=None,
                        help="simulated time, s (default 10; a scene whose robot drives to a "
                             "goal: the scene's horizon when it gives one)")
    parser.add_argument("--dt", type=float, default=0.01,
                        help=f"time step, s, in [{limits.DT_MIN:g}, {limits.DT_MAX:g}] as the "
                             "node's dt parameter (default 0.01)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the Brownian path (default 0)")
    parser.add_argument("--scheme", default="projected_euler", choices=sorted(SCHEMES),
                        help="time-stepping scheme: projected_euler (one projection per step, the "
                             "default), bridge (projected Euler with the Brownian-bridge "
                             "correction of wall and obstacle contacts), adaptive (bridge "
                             "steps bisected where an agent in contact moves far against "
                             "its radius); docs/mathematics.md")
    parser.add_argument("--out", default="run.mcap",
                        help="MCAP file to write, its folder made when absent (default run.mcap); "
                             "an existing file is refused unless --overwrite")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace OUT and OUT.summary.json when they exist")
    parser.add_argument("--frame-id", default="map", help="frame of the recorded poses")
    parser.add_argument("--record-every", type=int, default=1, metavar="K",
                        help="record every K-th step (default 1: every step)")
    parser.add_argument("--eps-abs", type=float, default=SolverOptions.eps_abs,
                        help="QP tolerance, m (default %(default)g)")
    parser.add_argument("--max-iter", type=int, default=SolverOptions.max_iter,
                        help="iteration cap of the proxqp backend")
    parser.add_argument("--backend", default=SolverOptions.backend, metavar="NAME",
                        help="QP solver of the clusters too large for the exact active-set "
                             "solver: any installed one (through qpsolvers), e.g. piqp "
                             "(default), clarabel, osqp, proxqp; an unknown name lists them")
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
    parser.add_argument("--force", action="store_true",
                        help=f"run even beyond {limits.MAX_STEPS:g} steps or a recording of "
                             f"more than {limits.MAX_RECORDING_BYTES / 1e9:g} GB (estimated "
                             "uncompressed: 88 bytes per agent present per recorded step, an "
                             "entering agent counted from its source time on, never more at "
                             "once than a closed room around them holds)")
    parser.add_argument("--marker-rate", type=float, default=markers.MARKER_RATE_HZ,
                        metavar="HZ",
                        help="record /markers (people as disks, robots) at HZ of simulated "
                             "time, at most with every recorded step (default %(default)g)")
    parser.add_argument("--live", type=int, nargs="?", const=8765, default=None, metavar="PORT",
                        help="serve the run to Foxglove over its WebSocket protocol on "
                             "127.0.0.1:PORT (default 8765; 0: any free port) while recording")
    parser.add_argument("--live-rate", type=float, default=1.0, metavar="FACTOR",
                        help="with --live: simulated time runs at FACTOR x real time "
                             "(default 1; 0: as fast as the run goes; else >= 0.001)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.set_defaults(func=_run)
