"""``sweep bench ...``: measured studies of the engine (headless; they write CSV and PNG).

    sweep bench accuracy [--quick] [--out bench_out] [--seed 0] [--problems rbm_wall crowd ...]
    sweep bench speed [--sizes 100 1000 ...]
    sweep bench recording [--sizes 1000 10000]
    sweep bench robots [--sizes 100 1000] [--beams 360 1440]
    sweep bench startup [--repeat 7]
    sweep bench live [--sizes 1000]
    sweep bench walking [--agents 60] [--t-end 10]
    sweep bench social [--seeds 10] [--scenes robot_crowd crowdnav] [--controllers ...]

``STUDIES`` is the registry: each name maps to the module whose ``register(subparsers)`` adds
that study's subcommand (the command line in :mod:`sweep_core.cli.bench` walks it). See
:mod:`sweep_core.bench.accuracy` for what the accuracy study measures and how.
"""
from __future__ import annotations

from types import ModuleType

from sweep_core.bench import accuracy_report, live, recording, robots, social, speed, startup, walking

#: name of a study -> module with ``register(subparsers)``
STUDIES: dict[str, ModuleType] = {"accuracy": accuracy_report, "speed": speed,
                                  "recording": recording, "robots": robots, "live": live,
                                  "startup": startup, "walking": walking, "social": social}
