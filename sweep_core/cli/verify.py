"""``sweep verify`` (the RiMEA tests and the validation against experiments) and ``sweep
export`` (a recording as PedPy trajectories).

    sweep verify [--quick] [--tests rimea1 rimea6 ...] [--seeds 5] [--seed 0] [--out DIR]
                 [--scenes DIR] [--workers K | --scheduler tcp://HOST:PORT | --in-process]
    sweep export RUN.mcap --pedpy OUT.txt
"""
from __future__ import annotations

import argparse
import sys

from sweep_core.cli.commands import summary
from sweep_core.errors import RecordingError, SweepError
from sweep_core.io.outputs import check_folder

__all__ = ["register"]

#: seeds of the full run and of --quick
SEEDS, QUICK_SEEDS = 5, 2
#: most seeds per test: every (case, seed) task is listed before the first run starts (with a
#: Dask future each); 10 000 seeds of the 30-odd cases of a full verify are some 300 000
#: tasks, and the standard error over 10 000 seeds is already 1 % of the spread
MAX_SEEDS = 10_000


def _verify(args: argparse.Namespace) -> int:
    from sweep_core.numerics import kernels
    from sweep_core.verify import TESTS
    from sweep_core.verify.runner import verify

    # a test named twice runs once, in the order first named
    names = (list(dict.fromkeys(args.tests)) if args.tests else
             [k for k, t in TESTS.items() if not (args.quick and t.slow)])
    unknown = [n for n in names if n not in TESTS]
    if unknown:
        raise SweepError(f"--tests: {unknown[0]!r} is not a test (fix: choose from "
                         f"{', '.join(TESTS)})")
    n = args.seeds if args.seeds is not None else (QUICK_SEEDS if args.quick else SEEDS)
    if not 1 <= n <= MAX_SEEDS:
        raise SweepError(f"--seeds: {n} is not a number of seeds from 1 to {MAX_SEEDS} (fix: "
                         "e.g. --seeds 3)")
    if args.seed < 0:
        raise SweepError(f"--seed: {args.seed} is not a seed (fix: give a whole number >= 0, "
                         "e.g. --seed 0)")
    seeds = list(range(args.seed, args.seed + n))
    tests = [TESTS[k] for k in names]
    out = None if args.no_report else check_folder(args.out)
    kernels.warm_up(lambda text: print(f"sweep: {text}", file=sys.stderr))

    def progress(text: str) -> None:
        print(f"sweep: {text}", file=sys.stderr, flush=True)

    if args.in_process or (args.quick and args.workers is None and args.scheduler is None):
        results = verify(tests, seeds, args.quick, out, args.scenes, progress=progress)
    else:
        from sweep_core.ensemble.cluster import connect

        with connect(scheduler=args.scheduler, workers=args.workers,
                     log=lambda text: print(f"sweep: {text}", file=sys.stderr)) as client:
            results = verify(tests, seeds, args.quick, out, args.scenes, client,
                             progress=progress)
    if out is not None:
        print(f"report: {out / 'report.md'}")
    return 1 if any(v.status == "FAIL" for _, v in results) else 0


def _export(args: argparse.Namespace) -> int:
    from sweep_core.analysis.pedpy_export import check_pedpy, read_trajectories, write_pedpy_txt

    check_pedpy()
    traj = read_trajectories(args.recording)
    if traj.cut:
        raise RecordingError(f"{args.recording}: {traj.cut}; its export would end there as if "
                             f"the run had (fix: sweep recover {args.recording}, then export "
                             "the complete copy it writes)")
    if traj.damaged:
        raise RecordingError(f"{args.recording}: the recording is damaged: {traj.damaged}; "
                             "its export would pass over those states as if the run had "
                             "them (fix: re-record it)")
    if not len(traj.ids):
        raise RecordingError(f"{args.recording}: no agent is present at any frame time, so "
                             "there is no trajectory to export (fix: export a recording with "
                             "agents in it)")
    path = write_pedpy_txt(traj, args.pedpy, inputs=[args.recording])
    print(f"{path}: {len(set(traj.ids.tolist()))} agents, {len(traj.ids)} rows, "
          f"{traj.frame_rate:g} frames/s (pedpy.load_trajectory_from_txt reads it)")
    if traj.resampling:
        print(f"frames: {traj.resampling}")
    if traj.recovered:
        print(f"note: {traj.recovered}")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``verify`` and ``export`` to the ``sweep`` command's subparsers."""
    p = subparsers.add_parser("verify", help=summary("verify"),
        description="Runs the RiMEA tests (and the validation studies) over several seeds, "
        "prints one line per test (measured, criterion, value over seeds, PASS/FAIL; DOC: "
        "documented, no threshold) and writes a report folder. Exit status 1 when any fails.")
    p.add_argument("--quick", action="store_true",
                   help=f"{QUICK_SEEDS} seeds, smaller crowds, the fast tests only, in this "
                   "process (no Dask) unless --workers or --scheduler is given")
    p.add_argument("--tests", nargs="+", metavar="NAME", help="tests to run (default: all)")
    p.add_argument("--seeds", type=int, default=None,
                   help=f"seeds per test, 1 to {MAX_SEEDS} (default {SEEDS}, {QUICK_SEEDS} with "
                   "--quick)")
    p.add_argument("--seed", type=int, default=0, help="first seed, >= 0 (default 0)")
    p.add_argument("--out", default="verify_out", help="report folder, made when absent and "
                   "checked before any run (default verify_out)")
    p.add_argument("--no-report", action="store_true", help="print the lines only")
    p.add_argument("--scenes", metavar="DIR", default=None,
                   help="a folder of scene files that replace the bundled ones of the same "
                   "name (e.g. rimea06_corner.yaml)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, default=None,
                       help="local Dask worker processes (default: the cores)")
    where.add_argument("--scheduler", default=None, help="a running Dask scheduler's address")
    where.add_argument("--in-process", action="store_true", help="no Dask: run here")
    p.set_defaults(func=_verify)

    e = subparsers.add_parser("export", help=summary("export"),
                              description="Writes a recording's trajectories in PedPy's text "
                              "format (id frame x y z), frame k at time k P: P = dt "
                              "record_every, or dt times the most common step gap between "
                              "recorded states (a node's ticks). Recorded states off that grid "
                              "(uneven ticks) are put on it by linear interpolation in time of "
                              "each agent's centre within its presence, and the command says "
                              "how many frames were. A recording cut short, with resets or "
                              "without a recorded state is refused (exit status 2).")
    e.add_argument("recording", help="an MCAP recording of sweep run or the node")
    e.add_argument("--pedpy", required=True, metavar="OUT.txt", help="the file to write")
    e.set_defaults(func=_export)
