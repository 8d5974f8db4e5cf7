"""The ``sweep`` commands: each one's module and one-line help.

Kept apart from the modules so that ``sweep --help`` and ``sweep --version`` import none of
them (the engine's imports take about a second), and ``sweep COMMAND`` imports only its own.
"""
from __future__ import annotations

from typing import NamedTuple


class Command(NamedTuple):
    """A ``sweep`` command: the module of ``sweep_core.cli`` that registers it, its help."""

    module: str
    help: str


COMMANDS: dict[str, Command] = {
    "run": Command("run", "run a scene headless and record it to MCAP"),
    "scenes": Command("scenes", "list the bundled scenes (sweep run NAME runs one)"),
    "analyze": Command("analysis", "metrics of a recording: gaps, touching constraints, "
                       "pressure, speeds, flow, arrivals, density (CSV, PNG, summary)"),
    "replay": Command("analysis", "re-simulate a recording from its metadata and check every "
                      "recorded pose bit for bit"),
    "compare": Command("analysis", "pathwise distance between two runs of one scene on their "
                       "common times (e.g. dt = 0.01 vs 0.001 on one Brownian path)"),
    "render": Command("render", "an animation of a recording: disks, walls, obstacles, groups, "
                      "the navigation field, time and status (MP4 or GIF)"),
    "recover": Command("recover", "rewrite a recording cut short (kill -9, full disk) into a "
                       "complete MCAP file that rosbags, Foxglove and rosbag2 open"),
    "map": Command("maps", "show what a map_server map becomes (walls), draw it, and write a "
                   "scene that uses it"),
    "bench": Command("bench", "measured studies of the engine"),
    "ensemble": Command("ensemble", "seeded runs x a grid of scene keys on a Dask cluster: one "
                        "row of analyze metrics per run, summary statistics and plots"),
    "verify": Command("verify", "the RiMEA tests and the validation against experiments"),
    "export": Command("verify", "a recording as PedPy trajectories"),
}


def summary(name: str) -> str:
    """The one-line help of the command ``name`` (a key of :data:`COMMANDS`)."""
    return COMMANDS[name].help
