"""The ``sweep`` command: ``run`` a scene headless and record it, ``analyze``, ``replay``,
``compare`` and ``render`` recordings, ``recover`` one cut short, ``bench accuracy`` and
``bench speed``."""
from __future__ import annotations

import argparse
import sys

from sweep_core.cli import analysis, bench, ensemble, maps, recover, render, run
from sweep_core.errors import SweepError


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="sweep", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    run.register(sub)
    analysis.register(sub)
    render.register(sub)
    recover.register(sub)
    maps.register(sub)
    bench.register(sub)
    ensemble.register(sub)
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


