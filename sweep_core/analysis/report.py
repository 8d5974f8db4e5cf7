"""Output of the analysis tools: file names beside the recording, CSV tables, JSON-safe values and
the printed summary."""
from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from sweep_core.analysis.metrics import Analysis
from sweep_core.analysis.plots import plot_analysis
from sweep_core.analysis.robots import SocialMetrics
from sweep_core.io.outputs import check_output, replacing


def output_paths(recording: str | Path, suffix: str) -> dict[str, Path]:
    p = Path(recording)
    return {ext: p.with_name(f"{p.stem}{suffix}.{ext}") for ext in ("csv", "png")}


def _fmt(x: float) -> str:
    if isinstance(x, float) and not math.isfinite(x):
        return "" if math.isnan(x) else ("inf" if x > 0 else "-inf")
    if isinstance(x, float) and x == int(x) and abs(x) < 2**53:
        return str(int(x))
    return repr(float(x))


#: the fix an analysis output error names (its outputs are named after the recording)
OTHER = "copy the recording to a writable folder and analyse the copy"


def write_table(path: Path, header: tuple[str, ...] | list[str], rows: np.ndarray | list,
                inputs: list[str] | None = None) -> None:
    """A CSV table, written to a temporary file renamed over ``path`` (never one of
    ``inputs``; an error leaves no partial file); numbers as :func:`_fmt`, text as it is."""
    with replacing(path, inputs or [], other=OTHER) as tmp, open(tmp, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        for row in rows:
            w.writerow([v if isinstance(v, str) else _fmt(float(v)) for v in row])


def write_outputs(an: Analysis, plots: bool = True) -> dict[str, str]:
    """``RUN.analysis.csv`` (per frame), ``RUN.density.csv`` (x, y of each cell centre,
    agents/m^2), ``RUN.robots.csv`` (the robots' frames, when there are robots),
    ``RUN.analysis.png``; returns their paths."""
    out = output_paths(an.meta.path, ".analysis")
    dens_path = output_paths(an.meta.path, ".density")["csv"]
    inputs = [an.meta.path]
    robots = (output_paths(an.meta.path, ".robots")["csv"],) if an.robots is not None else ()
    for p in (out["csv"], dens_path) + robots + ((out["png"],) if plots else ()):
        check_output(p, inputs, other=OTHER)  # all checked before any is written
    write_table(out["csv"], Analysis.COLUMNS, an.table, inputs)
    iy, ix = np.nonzero(an.density)
    cells = np.column_stack([an.density_origin[0] + (ix + 0.5) * an.cell,
                             an.density_origin[1] + (iy + 0.5) * an.cell, an.density[iy, ix]])
    write_table(dens_path, ("x_m", "y_m", "agents_per_m2"), cells, inputs)
    files = {"csv": str(out["csv"]), "density_csv": str(dens_path)}
    if an.robots is not None:  # the robots' frames: docs/social_metrics.md
        robots_path = output_paths(an.meta.path, ".robots")["csv"]
        write_table(robots_path, SocialMetrics.COLUMNS, an.robots, inputs)
        files["robots_csv"] = str(robots_path)
    if plots:
        plot_analysis(an, out["png"])
        files["png"] = str(out["png"])
    return files


def jsonable(obj: Any) -> Any:
    """inf / NaN -> None, numpy scalars -> Python, recursively."""
    if isinstance(obj, dict):
        return {k: jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, (np.floating, float)):
        return float(obj) if math.isfinite(obj) else None
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


#: how the printed summary shows a missing value of these keys (else "-")
NONE_TEXT = {"evacuation_s": "not all arrived"}


def format_summary(summary: dict, skip: tuple[str, ...] = ("precision",)) -> str:
    """The summary as aligned ``key  value`` lines (nested keys joined with '.')."""
    flat: list[tuple[str, str]] = []

    def walk(prefix: str, obj: Any) -> None:
        if isinstance(obj, dict):
            for k, v in obj.items():
                if k not in skip:
                    walk(f"{prefix}.{k}" if prefix else k, v)
        elif obj is None:
            flat.append((prefix, NONE_TEXT.get(prefix.rsplit(".", 1)[-1], "-")))
        elif isinstance(obj, float):
            flat.append((prefix, f"{obj:.6g}"))
        elif isinstance(obj, list):
            flat.append((prefix, ", ".join(f"{v:g}" if isinstance(v, float) else str(v)
                                           for v in obj)))
        else:
            flat.append((prefix, str(obj)))

    walk("", summary)
    width = max(len(k) for k, _ in flat)
    return "\n".join(f"{k:<{width}}  {v}" for k, v in flat)


def dumps(obj: Any) -> str:
    """``obj`` as indented JSON (numpy values made JSON-safe by :func:`jsonable`)."""
    return json.dumps(jsonable(obj), indent=2)
