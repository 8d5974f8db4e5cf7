"""``sweep scenes``: the bundled scenes, what each shows, its agents and its expected run time."""
from __future__ import annotations

import argparse

from sweep_core.model.gallery import bundled_scenes, measured_on, scenes_dir


def _scenes(args: argparse.Namespace) -> int:
    scenes = bundled_scenes()
    width = max(len(s.name) for s in scenes)
    print(f"{'name':<{width}}  agents  run s  shows")
    for s in scenes:
        print(f"{s.name:<{width}}  {s.agents:>6}  {s.run_s:>5.0f}  {s.shows}")
    print("\nrun one with: sweep run NAME (a name is a bundled scene when no such file exists)")
    print(f"run s: wall time of sweep run NAME (10 s simulated, dt 0.01, every step recorded), "
          f"measured on {measured_on()}")
    print(f"files: {scenes_dir()}")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``scenes`` to the ``sweep`` command's subparsers."""
    parser = sub.add_parser(
        "scenes", help="list the bundled scenes (sweep run NAME runs one)",
        description="Lists the scenes bundled with sweep: name, agents, the measured wall time "
        "of sweep run NAME (10 s simulated) and what each shows. sweep run NAME runs one; a "
        "name is resolved to a bundled scene only when no file of that name exists.")
    parser.set_defaults(func=_scenes)
