"""``sweep recover``: a recording cut short (killed writer, full disk) rewritten as a complete
MCAP file that rosbags, Foxglove, rosbag2 and mcap's seeking reader open."""
from __future__ import annotations

import argparse

from sweep_core.cli.commands import summary
from sweep_core.io.recording import read_metadata
from sweep_core.io.recording.recover import default_output, format_recovery, recover

__all__ = ["register"]


def _t_end(path: str) -> float | None:
    """The run's planned end (s) from its ``sweep_ros`` metadata, if it says."""
    try:
        return float(read_metadata(path).get("sweep_ros", {}).get("t_end", ""))
    except ValueError:
        return None


def _recover(args: argparse.Namespace) -> int:
    res = recover(args.recording, args.out)
    print(format_recovery(res, _t_end(res.source) if not res.complete else None))
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Adds ``recover`` to the ``sweep`` command's subparsers."""
    p = sub.add_parser("recover", help=summary("recover"),
        description="Reads IN up to its last complete chunk (as sweep analyze does) and writes "
        "everything read (schemas, channels, messages, metadata, attachments) to OUT with "
        "indexes, summary and footer, plus a metadata record sweep_recover; prints the "
        "messages kept per topic and what was lost. IN is never modified.")
    p.add_argument("recording", metavar="IN", help="the MCAP file cut short")
    p.add_argument("out", metavar="OUT", nargs="?", default=None,
                   help="the complete file to write (default: IN with .recovered.mcap, e.g. "
                        f"run.mcap -> {default_output('run.mcap')}); never IN itself")
    p.set_defaults(func=_recover)
