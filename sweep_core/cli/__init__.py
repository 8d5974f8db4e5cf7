"""The sweep command: run a scene headless and record it (scenes lists the bundled ones);
analyze, render, replay and compare recordings; recover one cut short; bench (measured
studies of the engine); verify (the RiMEA tests and the validation against experiments); export
(PedPy trajectories). sweep COMMAND --help tells more of each."""
from __future__ import annotations

import argparse
import importlib
import os
import sys

from sweep_core.cli.commands import COMMANDS
from sweep_core.errors import SweepError
from sweep_core.version import __version__


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The ``sweep`` parser. With ``command`` (a key of :data:`COMMANDS`), only that command's
    module is imported and its options registered; the others appear with their one-line help
    alone (so ``sweep --help`` imports none of the engine). Without it, every command is
    registered."""
    parser = argparse.ArgumentParser(prog="sweep", description=__doc__)
    parser.add_argument("--version", action="version", version=f"sweep {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    chosen = {c.module for n, c in COMMANDS.items() if command is None or n == command}
    registered: set[str] = set()
    for name, (module, help_line) in COMMANDS.items():
        if module not in chosen:
            sub.add_parser(name, help=help_line)
        elif module not in registered:
            importlib.import_module(f"sweep_core.cli.{module}").register(sub)
            registered.add(module)
    return parser


def _command(argv: list[str]) -> str:
    """The command ``argv`` names: its first word that is not an option ('' when none)."""
    for word in argv:
        if not word.startswith("-"):
            return word if word in COMMANDS else ""
    return ""


def main(argv: list[str] | None = None) -> int:
    args_list = sys.argv[1:] if argv is None else argv
    parser = build_parser(_command(args_list))
    try:
        args = parser.parse_args(args_list)
    except BrokenPipeError:  # sweep --help | head -1
        return reader_gone()
    if getattr(args, "record_every", 1) < 1:
        parser.error("--record-every: must be >= 1")
    try:
        code = int(args.func(args))
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
