"""``sweep ensemble``: seeded runs x a grid on a Dask cluster (:func:`sweep_core.ensemble.run`).

Wired into ``sweep`` by one call, ``register(sub)``, in :func:`sweep_core.cli.build_parser`.
"""
from __future__ import annotations

import argparse
import sys

from sweep_core.cli.commands import summary
from sweep_core.ensemble import grid, paired
from sweep_core.ensemble.task import RECORD
from sweep_core.numerics.schemes import SCHEMES

__all__ = ["register"]


def _say(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def _ensemble(args: argparse.Namespace) -> int:
    from sweep_core.ensemble.runner import run

    vary = grid.parse_vary(args.vary)
    try:
        table = run(args.scene, runs=args.runs, seed0=args.seed0, t_end=args.t_end, dt=args.dt,
                    scheme=args.scheme, vary=vary, record=args.record, out=args.out,
                    line=args.line, arrive_radius=args.arrive_radius, workers=args.workers,
                    scheduler=args.scheduler, plots=not args.no_plots,
                    progress=not args.quiet, log=_say)
    except KeyboardInterrupt:
        _say(f"sweep ensemble: interrupted; the finished runs are kept in {args.out}/runs/ "
             "(re-run the same command to resume)")
        return 130
    ok = int((table["status"] == "ok").sum())
    lost = int((table["status"] == "lost").sum())
    print(f"runs {len(table)}  completed {ok}  failed {len(table) - ok - lost}  lost {lost}  "
          f"grid points {table['point'].nunique()}  out {args.out}")
    for _, row in table[table["status"] != "ok"].head(3).iterrows():
        print(f"  {row['status']}: point {row['point']} seed {row['seed']}: {row['error']}")
    if paired.KEY in vary and len(table):  # the robots' effect, seed by seed
        keys = list(vary)
        print("with - without the robots (paired by seed):")
        print(paired.summary(paired.differences(table, keys), keys).to_string(
            index=False, float_format=lambda x: f"{x:.6g}"))
    if lost:
        _say(f"sweep ensemble: {lost} runs lost by the cluster (not by the simulation; the "
             "scheduler and every worker need this sweep_core installed); re-run the same "
             "command to run them again")
        return 1
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Adds ``ensemble`` to the ``sweep`` command's subparsers."""
    p = sub.add_parser("ensemble", help=summary("ensemble"),
        description="Run k of every grid point uses seed SEED0+k and gives exactly what `sweep "
        "run --seed SEED0+k` gives. Without --scheduler a LocalCluster of --workers processes "
        "runs on this machine; with it, the runs go to that Dask cluster (`dask scheduler`, "
        "`dask worker tcp://HOST:8786`). DIR gets runs.parquet, summary.csv (mean, std, 95 %% "
        "interval by the normal approximation) and plots; re-running with the same DIR skips "
        "the runs already there.")
    p.add_argument("scene", nargs="?", default=None,
                   help="scene YAML (default: the bundled room with a door, 200 agents)")
    p.add_argument("--runs", type=int, required=True, help="runs per grid point")
    p.add_argument("--seed0", type=int, default=0, help="seed of run 0 (default 0)")
    p.add_argument("--t-end", type=float, default=60.0, help="simulated time, s (default 60)")
    p.add_argument("--dt", type=float, default=0.01, help="time step, s (default 0.01)")
    p.add_argument("--scheme", default="projected_euler", choices=sorted(SCHEMES),
                   help="time-stepping scheme of every run, as sweep run --scheme (default "
                        "projected_euler)")
    p.add_argument("--vary", action="append", default=[], metavar="KEY=V1,V2,...",
                   help="a grid over a run option (dt, scheme) or a dotted scene key "
                        "(noise.sigma, agents.radius, walls.0.velocity); repeatable: the grid is "
                        "the product; robots=with,without pairs each seed's run with and "
                        "without the scene's robots (DIR/paired.csv, paired_summary.csv: "
                        "evacuation time, flow, pressure, with - without)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, default=None, metavar="K",
                       help="worker processes of the local cluster (default: the cores)")
    where.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                       help="a running Dask scheduler to send the runs to")
    p.add_argument("--record", default="none", choices=RECORD,
                   help="none: rows only; summary: rows carry analyze's whole summary (also "
                        "DIR/summaries/); full: also one MCAP per run in DIR/mcap/ (DIR must be "
                        "shared by every worker at the same path)")
    p.add_argument("--line", metavar="x0,y0,x1,y1", default=None,
                   help="counting line (m) as in sweep analyze: flow and evacuation times")
    p.add_argument("--arrive-radius", type=float, default=None, metavar="R",
                   help="arrived = within R m of the goal (default: its slow_radius; refused "
                   "as by sweep analyze)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--no-plots", action="store_true", help="no PNG")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_ensemble)
