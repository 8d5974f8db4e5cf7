"""``sweep render RUN.mcap``: an animation of a recording (MP4, or GIF).

Wired into ``sweep`` by one call, ``register(sub)``, in :func:`sweep_core.cli.build_parser`.
"""
from __future__ import annotations

import argparse
import sys

from sweep_core.analysis import render
from sweep_core.cli.commands import summary
from sweep_core.errors import SweepError

__all__ = ["register"]


def parse_size(text: str) -> tuple[int, int | None]:
    """``WIDTHxHEIGHT`` or ``WIDTH`` (pixels) as (width, height or None)."""
    parts = text.lower().split("x")
    try:
        if len(parts) in (1, 2) and all(p.strip().isdigit() for p in parts):
            return int(parts[0]), (int(parts[1]) if len(parts) == 2 else None)
    except ValueError:
        pass
    raise SweepError(f"--size {text!r} is not WIDTHxHEIGHT or WIDTH in pixels (fix: give e.g. "
                     "--size 960x540)")


def _render(args: argparse.Namespace) -> int:
    width, height = parse_size(args.size)
    opts = render.RenderOptions(fps=args.fps, start=args.start, end=args.end, speed=args.speed,
                                width=width, height=height, colour=args.colour,
                                speed_window=args.speed_window)
    problems: list[str] = []
    path, frames = render.render(args.recording, args.out, opts, progress=not args.quiet,
                                 problems=problems)
    for line in problems:  # skipped chunks and messages: one line each
        print(line, file=sys.stderr)
    print(f"{path}: {frames} frames at {args.fps:g} fps ({frames / args.fps:.3g} s)")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Adds the ``render`` subcommand to ``sweep``."""
    p = sub.add_parser("render", help=summary("render"),
                       description="Writes RUN.mp4 next to RUN.mcap (H.264 through "
                       "imageio-ffmpeg; RUN.gif through Pillow when no encoder is available, "
                       "or when --out ends in .gif). Times are seconds since the first recorded "
                       "state (for sweep run, the simulation time); video frame k shows the "
                       "last state at or before FROM + k x SPEED / FPS, so a window gives "
                       "floor((TO - FROM) x FPS / SPEED) + 1 frames.")
    p.add_argument("recording", help="MCAP file from sweep run or sweep_node")
    p.add_argument("--out", default=None, help="output file, .mp4 or .gif (default: RUN.mp4)")
    p.add_argument("--fps", type=float, default=10.0, help="video frames per second "
                   "(default 10; a GIF holds each frame a whole number of 10 ms)")
    p.add_argument("--from", dest="start", type=float, default=0.0, metavar="S",
                   help="start of the window, s (default 0)")
    p.add_argument("--to", dest="end", type=float, default=None, metavar="S",
                   help="end of the window, s (default: the last recorded state)")
    p.add_argument("--speed", type=float, default=1.0,
                   help="recorded seconds per video second (default 1)")
    p.add_argument("--size", default="960", metavar="WxH",
                   help="frame size in pixels, WIDTHxHEIGHT or WIDTH (height from the scene's "
                        "aspect); rounded down to even numbers (default 960)")
    p.add_argument("--colour", choices=render.COLOURINGS, default="group",
                   help="disk colours: by group (default), by speed, or none")
    p.add_argument("--speed-window", type=float, default=None, metavar="S",
                   help="with --colour speed: each agent's displacement over S s centred on "
                        "the frame (default 0.625, as sweep analyze)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_render)
