"""Running the accuracy study: tables, CSV files and plots (``sweep bench accuracy``)."""
from __future__ import annotations

import argparse
import dataclasses
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from sweep_core import checks
from sweep_core.bench.accuracy import (
    PROBLEMS,
    Measurement,
    Slope,
    StudyConfig,
    Variant,
    group_slopes,
)
from sweep_core.bench.accuracy_problems import STUDIES, study_crowd, study_features
from sweep_core.bench.tables import write_csv
from sweep_core.errors import SweepError
from sweep_core.io.outputs import check_folder
from sweep_core.numerics.schemes import SCHEMES
from sweep_core.text import text_table


def format_table(ms: list[Measurement]) -> str:
    """The measurements, one line each: problem, metric, scheme, solver tolerance, dt (s),
    error and its 95 % half-width (m), wall seconds per simulated second, substeps."""
    return text_table(
        ("problem", "metric", "scheme", "tol", "dt", "error", "+-95%", "wall s/s", "sub"),
        [(m.problem, m.metric, m.scheme, m.tol, f"{m.dt:.3g}", f"{m.error:.3e}", f"{m.ci:.2e}",
          f"{m.wall_per_s:.3g}", f"{m.substeps:.2f}") for m in ms],
        "<<<<>>>>>", widths=(11, 6, 16, 16, 10, 10, 9, 9, 5), gaps=" ", rule=True)


def format_slopes(slopes: list[Slope]) -> str:
    """The fitted slopes with their 95 % intervals ("-" when none could be fitted)."""
    rows = [(s.problem, s.metric, s.scheme, s.tol,
             *((f"{s.slope:.2f}", f"[{s.lo:.2f}, {s.hi:.2f}]") if np.isfinite(s.slope)
               else ("-", "")), s.note) for s in slopes]
    return text_table(("problem", "metric", "scheme", "tol", "slope", "95% interval", "note"),
                      rows, "<<<<><<", widths=(11, 6, 16, 16, 7, 16),
                      gaps=(" ", " ", " ", " ", "  ", " "), rule=True)


def format_features(rows: list[dict]) -> str:
    """The cost of the model's features on a free-flow crowd: ms per step, its ratio to the
    bare scene's, contacts."""
    return text_table(("free-flow crowd, 120 agents", "ms/step", "x none", "contacts"),
                      [(r["scene"], f"{r['ms_per_step']:.3f}", f"{r['ratio_to_none']:.2f}",
                        str(r["contacts"])) for r in rows],
                      "<>>>", widths=(29, 9, 7, 9), gaps=" ", rule=True)


def _mrow(m: Measurement) -> dict:
    return {"problem": m.problem, "metric": m.metric, "scheme": m.scheme, "tol": m.tol,
            "dt": m.dt, "error": m.error, "ci95": m.ci, "wall_s_per_sim_s": m.wall_per_s,
            "substeps_per_step": m.substeps, "samples": m.samples}


def plot(ms: list[Measurement], out: Path) -> list[Path]:
    """error_vs_dt.png and pareto.png (error against wall time per simulated second)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter

    default_tol = Variant("", SCHEMES["projected_euler"]).tol
    panels: dict[tuple[str, str], list[Measurement]] = {}
    for m in ms:
        panels.setdefault((m.problem, m.metric), []).append(m)
    keys = list(panels)
    cols = min(3, math.ceil(math.sqrt(len(keys))))
    rows = max(1, math.ceil(len(keys) / cols))
    written = []
    for name, xkey, xlabel in (("error_vs_dt.png", "dt", "dt (s)"),
                               ("pareto.png", "wall_per_s", "wall time per simulated second (s)")):
        fig, axes = plt.subplots(rows, cols, figsize=(4.0 * cols, 3.1 * rows), squeeze=False)
        for ax, key in zip(axes.flat, keys):
            lines: dict[tuple[str, str], list[Measurement]] = {}
            for m in panels[key]:
                lines.setdefault((m.scheme, m.tol), []).append(m)
            drawn = 0
            for (scheme, tol), g in lines.items():
                g = [m for m in sorted(g, key=lambda m: -m.dt) if m.error > 1e-13]
                if not g:
                    continue
                drawn += 1
                x = np.array([getattr(m, xkey) for m in g])
                y = np.array([m.error for m in g])
                ci = np.array([m.ci for m in g])
                label = scheme if tol == default_tol else f"{scheme} {tol}"
                ax.errorbar(x, y, yerr=[np.minimum(ci, 0.9 * y), ci], marker="o", ms=3, lw=1,
                            capsize=2, label=label)
            if xkey == "dt":
                dts = np.array(sorted({m.dt for m in panels[key]}))
                ref = [m.error for m in panels[key] if m.error > 1e-13]
                if ref and len(dts) > 1:
                    y0 = float(np.median(ref))
                    for p, style in ((0.5, ":"), (1.0, "--")):
                        ax.plot(dts, y0 * (dts / dts[len(dts) // 2]) ** p, "k" + style, lw=0.7,
                                label=f"slope {p:g}")
            ax.set_title(f"{key[0]} ({key[1]})", fontsize=9)
            if not drawn:
                ax.text(0.5, 0.5, "exact to rounding\n(every error < 1e-13 m)",
                        ha="center", va="center", transform=ax.transAxes, fontsize=8)
                ax.set_xticks([])
                ax.set_yticks([])
                continue
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.xaxis.set_minor_formatter(NullFormatter())
            ax.set_xlabel(xlabel, fontsize=8)
            ax.set_ylabel("error (m)", fontsize=8)
            ax.tick_params(labelsize=7)
            ax.legend(fontsize=6)
        for ax in list(axes.flat)[len(keys):]:
            ax.axis("off")
        fig.tight_layout()
        path = out / name
        fig.savefig(path, dpi=72)
        plt.close(fig)
        written.append(path)
    return written


def run_study(cfg: StudyConfig, out: Path, problems: tuple[str, ...] = PROBLEMS,
              log=print, client: Any = None) -> tuple[list[Measurement], list[Slope], list[dict]]:
    """Run the chosen problems, print the tables, write CSVs and plots into ``out``; with a
    ``distributed.Client`` the crowd's paths run on its workers."""
    out.mkdir(parents=True, exist_ok=True)
    ms: list[Measurement] = []
    start = time.perf_counter()
    for name in problems:
        if name in STUDIES:
            t0 = time.perf_counter()
            ms.extend(study_crowd(cfg, log, client) if name == "crowd"
                      else STUDIES[name](cfg, log))
            log(f"  {name}: {time.perf_counter() - t0:.1f} s")
    features = study_features(cfg, log) if "features" in problems else []
    slopes = group_slopes(ms, cfg.seed)
    if ms:
        log(format_table(ms))
        log("")
        log(format_slopes(slopes))
        write_csv(out / "accuracy.csv", [_mrow(m) for m in ms])
        write_csv(out / "slopes.csv", [dataclasses.asdict(s) for s in slopes])
        for p in plot(ms, out):
            log(f"wrote {p}")
    if features:
        log("")
        log(format_features(features))
        write_csv(out / "features.csv", features)
    log(f"study took {time.perf_counter() - start:.1f} s; CSV and PNG in {out}")
    return ms, slopes, features


def _accuracy(args: argparse.Namespace) -> int:
    # numpy's generators take seeds >= 0 only: refused here, before any problem runs
    checks.integer(args.seed, "--seed", fix="e.g. --seed 0")
    out = check_folder(args.out, "--out OTHERDIR")  # before the study, not after it
    cfg = StudyConfig.make(args.quick, args.seed)
    if args.crowd_paths is not None:
        if args.crowd_paths < 2:
            raise SweepError(f"--crowd-paths: {args.crowd_paths} gives no interval (fix: 2 or "
                             "more)")
        cfg = dataclasses.replace(cfg, crowd_paths=args.crowd_paths)
    print(f"sweep bench accuracy: {'quick' if cfg.quick else 'full'} study, {cfg.levels} dt "
          f"levels, problems {' '.join(args.problems)}, {cfg.crowd_paths} crowd paths",
          flush=True)

    def log(text: str) -> None:
        print(text, flush=True)

    if args.workers is None and args.scheduler is None:
        run_study(cfg, out, tuple(args.problems), log=log)
        return 0
    from sweep_core.ensemble.cluster import check_workers, connect

    workers = check_workers(args.workers) if args.scheduler is None else None
    with connect(scheduler=args.scheduler, workers=workers, log=log) as client:
        run_study(cfg, out, tuple(args.problems), log=log, client=client)
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``accuracy`` to the subparsers of ``sweep bench``."""
    acc = sub.add_parser(
        "accuracy", help="error against dt, scheme and solver tolerance; Pareto plot",
        description="Error (95 % CI) against dt, scheme and solver tolerance on exact "
                    "problems and a crowd, fitted log-log slopes, error-vs-dt and Pareto plots, "
                    "and the per-step cost of walls, noise and radius laws.")
    acc.add_argument("--quick", action="store_true",
                     help="fewer paths and a shorter crowd run (under a minute)")
    acc.add_argument("--out", default="bench_out",
                     help="directory for CSV and PNG files (default bench_out)")
    acc.add_argument("--seed", type=int, default=0, help="seed of the Brownian paths")
    acc.add_argument("--problems", nargs="+", default=list(PROBLEMS), choices=PROBLEMS,
                     metavar="NAME", help=f"subset of: {' '.join(PROBLEMS)} (default all)")
    acc.add_argument("--crowd-paths", type=int, default=None, metavar="N",
                     help="independent paths of the crowd problem (default 4, --quick 3)")
    where = acc.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, default=None, metavar="K",
                       help="run the crowd's paths on a local Dask cluster of K workers")
    where.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                       help="run the crowd's paths on an existing Dask cluster")
    acc.set_defaults(func=_accuracy)
