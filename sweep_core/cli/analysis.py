"""``sweep analyze``, ``sweep replay`` and ``sweep compare``: recordings after the run.

Wired into ``sweep`` by one call, ``register(sub)``, in :func:`sweep_core.cli.build_parser`.
"""
from __future__ import annotations

import argparse
import json
import sys

from sweep_core.analysis import compare, metrics, replay, report
from sweep_core.analysis.speed import DEFAULT_WINDOW_S
from sweep_core.cli.commands import summary
from sweep_core.cli.run import start_live
from sweep_core.io.recording.format import open_for_reading
from sweep_core.io.recording.recover import hint
from sweep_core.numerics import kernels

__all__ = ["register"]


def _kernels() -> None:
    """Compiles (first run on this machine, said on stderr) or loads the engine's kernels
    before the progress bar starts."""
    kernels.warm_up(lambda line: print(f"sweep: {line}", file=sys.stderr))


def _openable(path: str) -> None:
    """RecordingError (one line) when ``path`` cannot be opened as a recording: said before
    the kernels are compiled, not minutes after."""
    open_for_reading(path)[1].close()


def _analyze(args: argparse.Namespace) -> int:
    _openable(args.recording)
    _kernels()
    line = metrics.parse_line(args.line) if args.line else None
    an = metrics.analyze(args.recording, line=line, arrive_radius=args.arrive_radius,
                          cell=args.cell, progress=not args.quiet,
                          goal_radius=args.goal_radius, time_limit=args.time_limit,
                          speed_window=args.speed_window)
    for line in an.problems:  # skipped chunks and messages, gaps: one line each
        print(line, file=sys.stderr)
    an.summary["outputs"] = report.write_outputs(an, plots=not args.no_plots)
    if args.json:
        print(json.dumps(report.jsonable(an.summary), indent=2))
    else:
        if an.summary["truncated"]:
            print(f"truncated recording: read up to its last complete chunk "
                  f"({an.summary['read_until']})")
        # "contacts" repeats "touching" under its old name, for JSON readers only
        print(report.format_summary(an.summary, skip=("precision", "contacts")))
    if an.summary["truncated"]:
        print(hint(args.recording), file=sys.stderr)
    return 0


def _replay(args: argparse.Namespace) -> int:
    _openable(args.recording)
    live = start_live(args)  # a port in use is said before any work
    if live is not None:
        from sweep_core.io.live import serve_recording

        try:
            served = serve_recording(args.recording, live)
        finally:
            live.stop()
        print(f"sweep: live view: {served} recorded messages served; now the replay's check",
              file=sys.stderr)
    _kernels()
    res = replay.replay(args.recording, progress=not args.quiet)
    for line in res.problems:
        print(line, file=sys.stderr)
    print(report.dumps(res.to_dict()) if args.json else replay.format_replay(res))
    if res.truncated:
        print(hint(args.recording), file=sys.stderr)
    if res.stopped is not None:
        print(f"sweep: error: {res.path}: {res.stopped} (fix: replay an undamaged copy of the "
              "recording)", file=sys.stderr)
        return 2
    return 0 if res.identical else 1


def _compare(args: argparse.Namespace) -> int:
    cmp = compare.compare(args.a, args.b, progress=not args.quiet)
    for line in cmp.problems:
        print(line, file=sys.stderr)
    files = compare.write_comparison(cmp, plots=not args.no_plots)
    if args.json:
        d = cmp.to_dict()
        d["outputs"] = files
        print(report.dumps(d))
    else:
        print(compare.format_comparison(cmp))
        print(f"{'outputs':<18} {', '.join(files.values())}")
    for path in cmp.truncated:
        print(hint(path), file=sys.stderr)
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Adds the ``analyze``, ``replay`` and ``compare`` subcommands to ``sweep``."""
    p = sub.add_parser("analyze", help=summary("analyze"),
                       description="Writes RUN.analysis.csv (one row per recorded step), "
                       "RUN.density.csv and RUN.analysis.png next to RUN.mcap and prints a "
                       "summary, starting with how the run ended (its status record: completed, "
                       "interrupted, failed). 'touching' counts the true constraints (agent "
                       "pairs, agent-wall, agent-obstacle) with a gap <= 1e-6 m in each recorded "
                       "frame; sweep run's 'active_rows' counts the rows of the linearised set "
                       "that hold with equality after each step's projection, a different "
                       "number. A recording cut short is read up to its last complete chunk "
                       "(sweep recover makes a complete copy of it).")
    p.add_argument("recording", help="MCAP file from sweep run or sweep_node")
    p.add_argument("--line", metavar="x0,y0,x1,y1",
                   help="counting line (m): flow through it, positive from left to right "
                        "looking from (x0, y0) to (x1, y1), and evacuation times")
    p.add_argument("--arrive-radius", type=float, default=None, metavar="R",
                   help="arrived = within R m of the goal in effect (default: its slow_radius); "
                   "refused when the scene has sinks or sources (an arrival is leaving at a "
                   "sink), journeys or exit choices (no arrivals)")
    p.add_argument("--cell", type=float, default=0.5,
                   help=f"density map cell, m (default 0.5; the map has at most "
                        f"{metrics.MAX_CELLS:g} cells)")
    p.add_argument("--goal-radius", type=float, default=None, metavar="R",
                   help="a robot has reached its goal within R m of it (default: the "
                        "scene's goal_radius; docs/social_metrics.md)")
    p.add_argument("--time-limit", type=float, default=None, metavar="S",
                   help="a robot's episode ends S s after the first frame (default: the "
                        "scene's time_limit, else the whole recording; refused, as "
                        "--goal-radius is, when the scene has no robot)")
    p.add_argument("--speed-window", type=float, default=None, metavar="S",
                   help="every speed is an agent's displacement over S s centred on the frame "
                        f"(default {DEFAULT_WINDOW_S:g}: JPSreport's 10 frames at the Jülich "
                        "experiments' 16 per second; at least two recorded frame intervals)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.add_argument("--no-plots", action="store_true", help="no PNG (no matplotlib needed)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_analyze)

    p = sub.add_parser("replay", help=summary("replay"),
                       description="Exit status 0: identical; 1: diverged (the first step and "
                       "agent are reported); 2: the recording cannot be replayed.")
    p.add_argument("recording", help="MCAP file from sweep run or sweep_node")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--live", type=int, nargs="?", const=8765, default=None, metavar="PORT",
                   help="first serve the recording as it was recorded to Foxglove over its "
                        "WebSocket protocol on 127.0.0.1:PORT (default 8765; 0: any free "
                        "port), then check it")
    p.add_argument("--live-rate", type=float, default=1.0, metavar="FACTOR",
                   help="with --live: the recording's time runs at FACTOR x real time "
                        "(default 1; 0: as fast as it is read; else >= 0.001)")
    p.set_defaults(func=_replay)

    p = sub.add_parser("compare", help=summary("compare"),
                       description="Writes A_vs_B.compare.csv, A_vs_B.agents.csv and "
                       "A_vs_B.compare.png next to A.")
    p.add_argument("a", help="first recording")
    p.add_argument("b", help="second recording")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument("--no-plots", action="store_true", help="no PNG")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_compare)
