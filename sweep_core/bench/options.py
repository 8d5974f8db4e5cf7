"""Checks of the bench studies' options, run before anything is measured: sizes and counts,
tolerances and time limits, and the CSV the study writes. Each raises a SweepError naming the
option, the value and the fix (``sweep`` prints it on one line and exits with status 2)."""
from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from sweep_core import checks
from sweep_core.errors import SceneError
from sweep_core.io.outputs import check_output
from sweep_core.numerics.projection.options import SolverOptions

#: most agents of a measured crowd: a step of 10 000 agents in a jam takes about 20 ms and one
#: of 5000 agents at the evacuation's door about 1.2 s (docs/performance.md), so a crowd of 1e6
#: already takes minutes per step; at 1e9 the crowd's arrays alone asked for tens of GB and
#: the study ended in a MemoryError before its first row
MAX_AGENTS = 1_000_000


def counts(values: Sequence[int], field: str, *, low: int = 1, high: int | None = None,
           example: str = "") -> list[int]:
    """Whole numbers in [low, high] (every one of ``values``), else SceneError naming
    ``field`` (``--sizes``, ``--beams``)."""
    out = []
    for v in values:
        n = checks.integer(v, field, low=low, fix=f"e.g. {field} {example or max(low, 1)}")
        if high is not None and n > high:
            raise SceneError(field, f"{n} is more than the limit {high:g}",
                             f"{field} {high} or fewer")
        out.append(n)
    return out


def count(value: int, field: str, *, low: int = 1, example: str = "") -> int:
    """A whole number >= low (``--steps``, ``--warmup``, ``--repeat``)."""
    return counts([value], field, low=low, example=example)[0]


def seconds(value: float, field: str, example: str) -> float:
    """A finite time limit > 0 s (``--timeout``): 0 would stop every solve before it starts."""
    return checks.number(value, field, positive=True, fix=f"e.g. {field} {example}")


def tolerances(values: Sequence[float], field: str = "--tols") -> list[float]:
    """Certified tolerances (m) the projection accepts (``SolverOptions``: [1e-12, 1] m)."""
    out = []
    for v in values:
        try:
            SolverOptions.from_values(tol=v)
        except SceneError as err:
            raise SceneError(field, err.problem, f"e.g. {field} 1e-4 1e-8") from None
        out.append(float(v))
    return out


def csv_path(path: str) -> Path:
    """The study's CSV, checked before the study runs (absent or a regular file, not inside
    the package)."""
    return check_output(path, other="--csv OTHER.csv")


def speed(args: argparse.Namespace) -> None:
    """``sweep bench speed``'s options, before anything is measured."""
    counts(args.sizes, "--sizes", high=MAX_AGENTS, example="1000")
    counts(args.evacuation_sizes, "--evacuation-sizes", high=MAX_AGENTS, example="1000")
    count(args.steps, "--steps", example="30")
    count(args.warmup, "--warmup", low=0, example="40")
    count(args.evacuation_steps, "--evacuation-steps", example="100")
    count(args.evacuation_warmup, "--evacuation-warmup", low=0, example="400")
    count(args.backend_qps, "--backend-qps", low=0, example="3")
    args.tols = tolerances(args.tols)
    seconds(args.timeout, "--timeout", "30")
    seconds(args.backend_timeout, "--backend-timeout", "20")
    csv_path(args.csv)
    refuse_without_steps(args)


#: the ``steps`` options' defaults (None on the command line: not given)
STEPS_DEFAULTS = {"run_steps": 200, "env_steps": 2000, "num_envs": 32}


def refuse_without_steps(args: argparse.Namespace) -> None:
    """Refuses a ``steps`` option given when ``steps`` is not among ``--scenes``: it would
    be ignored, silently."""
    given = next((name for name in (*STEPS_DEFAULTS, "env_workers")
                  if getattr(args, name, None) is not None), None)
    if given is not None and "steps" not in args.scenes:
        option = "--" + given.replace("_", "-")
        raise SceneError(option, f"is an option of --scenes steps, which is not among "
                         f"--scenes {' '.join(args.scenes)}",
                         f"add steps to --scenes, or leave {option} out")
