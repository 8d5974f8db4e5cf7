"""``sweep bench``: one subcommand per study of :data:`sweep_core.bench.STUDIES`."""
from __future__ import annotations

import argparse

from sweep_core.bench import STUDIES
from sweep_core.cli.commands import summary


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``bench`` and its studies to the ``sweep`` command's subparsers."""
    bench = subparsers.add_parser("bench", help=summary("bench"))
    sub = bench.add_subparsers(dest="bench", required=True)
    for module in STUDIES.values():
        module.register(sub)
