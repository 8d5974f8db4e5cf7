"""The ``sweep`` command: ``run`` a scene headless and record it (``scenes`` lists the bundled
ones), ``analyze``, ``render``, ``replay`` and ``compare`` recordings, ``recover`` one cut short,
``bench accuracy`` and ``bench speed``, ``verify`` (the RiMEA tests) and ``export`` (PedPy
trajectories)."""
from __future__ import annotations

import argparse
import os
import sys

from sweep_core.cli import analysis, bench, ensemble, maps, recover, render, run, scenes, verify
from sweep_core.errors import SweepError


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="sweep", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    run.register(sub)
    scenes.register(sub)
    analysis.register(sub)
    render.register(sub)
    recover.register(sub)
    maps.register(sub)
    bench.register(sub)
    ensemble.register(sub)
    verify.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "record_every", 1) < 1:
        parser.error("--record-every: must be >= 1")
    try:
        code = args.func(args)
        sys.stdout.flush()  # a reader that left (``| head``) is met here, not at exit
        return code
    except BrokenPipeError:
        return reader_gone()
    except SweepError as err:
        print(f"sweep: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("sweep: interrupted; the recording was closed", file=sys.stderr)
        return 130




#: the exit status of a command whose reader closed the pipe: 128 + SIGPIPE, as the shell
#: reports a command killed by it
PIPE_CLOSED = 141


def reader_gone() -> int:
    """The output's reader closed the pipe (``sweep compare A B | head``): end quietly. The
    standard streams are pointed at /dev/null, so the interpreter's last flush finds no closed
    pipe either (no traceback, no "Exception ignored" line). Returns :data:`PIPE_CLOSED`."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    for stream in (sys.stdout, sys.stderr):
        try:
            os.dup2(devnull, stream.fileno())
        except (OSError, ValueError, AttributeError):  # not a real file (captured): left as is
            pass
    os.close(devnull)
    return PIPE_CLOSED
