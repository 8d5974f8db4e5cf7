"""``sweep scenes``: the bundled scenes, what each shows, its agents and
the model its people walk with (the speed law or the pure model), and why."""
from __future__ import annotations

import argparse

from sweep_core.cli.commands import summary
from sweep_core.model.gallery import bundled_scenes, scenes_dir
from sweep_core.text import text_table


def _scenes(args: argparse.Namespace) -> int:
    scenes = bundled_scenes()
    print(text_table(("name", "agents", "model", "shows"),
                     [(s.name, str(s.agents), s.model, s.shows) for s in scenes], "<><<"))
    print("\nwhy each model (speed law: flows.headway, the csm law at the parameters sweep "
          "verify validates;\npure: without it; remove or add that key in a copy of the scene "
          "for the other):")
    print(text_table(("name", "model", "why"), [(s.name, s.model, s.why) for s in scenes],
                     "<<<"))
    print("\nrun one with: sweep run NAME (a name is a bundled scene when no such file exists)")
    print(f"files: {scenes_dir()}")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``scenes`` to the ``sweep`` command's subparsers."""
    parser = sub.add_parser("scenes", help=summary("scenes"),
        description="Lists the scenes bundled with sweep: name, agents, the model its people "
        "walk with (the speed law flows.headway, or the pure model without it) and why, and "
        "what each shows. sweep run NAME runs one; a name is resolved to a bundled scene only "
        "when no file of that name exists.")
    parser.set_defaults(func=_scenes)
