"""The output directory of an ensemble: one small parquet file per finished run, the table
``runs.parquet``, ``summary.csv`` and what makes a re-run resume.

Layout of DIR:

    ensemble.json            the configuration (scene, t_end, dt, scheme, line, arrive_radius);
                             a re-run with another configuration is refused
    runs/<point>_s<seed>.parquet   one row per finished run, written as it completes (atomic
                             rename), so a killed ensemble keeps every run that finished
    runs.parquet             the rows of this invocation's runs x grid points
    summary.csv              per grid point and metric: runs, completed, failed, n, mean, std,
                             95 % interval (normal approximation: mean +- 1.96 std / sqrt(n))
    summaries/<point>_s<seed>.json   ``sweep analyze``'s summary per run (record summary, full)
    mcap/<point>_s<seed>.mcap        the recording per run (record full)

A run is done (skipped on resume) when its file holds status ``ok`` or ``failed``; a run whose
worker was lost (status ``lost``) is run again.
"""
from __future__ import annotations

import json
import math
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import pandas as pd

from sweep_core.errors import SweepError
from sweep_core.io.outputs import check_folder, open_locked, replacing, write_text

CONFIG = "ensemble.json"
#: statuses that count as done on resume
DONE = ("ok", "failed")
#: 95 % two-sided quantile of the normal distribution
Z95 = 1.959963984540054
#: columns of a row that are not metrics (the grid keys come on top)
BOOKKEEPING = ("point", "run", "seed", "dt", "scheme", "status", "error", "worker",
               "t_reached_s", "final_sha256", "recording", "summary_json", "agents", "frames")


def run_name(pid: str, seed: int) -> str:
    """File stem of a run: grid point id and seed."""
    return f"{pid}_s{seed}"


def lock(out: Path) -> int:
    """Makes DIR (absent, or a folder) and locks it for this ensemble: a descriptor of
    DIR/.lock, locked until closed; a second ensemble writing DIR at the same time is refused.

    Raises:
        OutputError: DIR exists and is not a folder, lies inside the installed package, cannot
            be written into, or another ensemble is writing it.
    """
    check_folder(out, other="--out NEWDIR")
    return open_locked(out / ".lock", other="--out OTHERDIR")


def check_config(out: Path, config: dict[str, Any]) -> None:
    """Writes DIR/ensemble.json, or checks that the one there is the same configuration."""
    path = out / CONFIG
    text = json.dumps(config, sort_keys=True, indent=1)
    if path.exists():
        try:
            old = json.loads(path.read_text())
        except (OSError, ValueError):
            old = None
        if old != json.loads(text):
            diff = sorted(k for k in set(config) | set(old or {})
                          if (old or {}).get(k) != config.get(k))
            raise SweepError(
                f"--out: {str(out)!r} holds an ensemble of another configuration ("
                f"{', '.join(diff) or 'unreadable ' + CONFIG} differ) (fix: use a new --out "
                "directory, or the same scene and options to resume)")
        return
    out.mkdir(parents=True, exist_ok=True)
    write_text(path, text + "\n", other="--out OTHERDIR")


def write_row(out: Path, name: str, row: dict[str, Any]) -> None:
    """One run's row to DIR/runs/NAME.parquet (written to a temporary name, then renamed)."""
    runs = out / "runs"
    runs.mkdir(parents=True, exist_ok=True)
    with replacing(runs / f"{name}.parquet", other="--out OTHERDIR") as tmp:
        pd.DataFrame([row]).to_parquet(tmp, index=False)


def read_rows(out: Path, names: Iterable[str]) -> dict[str, dict[str, Any]]:
    """Rows already in DIR/runs among ``names`` whose status is done (unreadable files are
    ignored: that run is simply run again)."""
    rows: dict[str, dict[str, Any]] = {}
    runs = out / "runs"
    if not runs.is_dir():
        return rows
    for name in names:
        path = runs / f"{name}.parquet"
        if not path.exists():
            continue
        try:
            frame = pd.read_parquet(path)
        except (OSError, ValueError):
            continue
        if len(frame) == 1 and frame["status"].iloc[0] in DONE:
            rows[name] = {k: _plain(v) for k, v in frame.iloc[0].items()}
    return rows


def _plain(value: Any) -> Any:
    """A parquet cell back to a Python value (numpy scalars -> Python, NA -> None/NaN)."""
    if hasattr(value, "item"):
        value = value.item()
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return value
    try:
        if pd.isna(value):
            return None
    except (TypeError, ValueError):
        pass
    return value


def metric_columns(table: pd.DataFrame, grid_keys: Iterable[str]) -> list[str]:
    """The numeric metric columns of the table (wall time included), in table order."""
    skip = set(BOOKKEEPING) | set(grid_keys)
    return [c for c in table.columns
            if c not in skip and pd.api.types.is_numeric_dtype(table[c])
            and not pd.api.types.is_bool_dtype(table[c])]


def summarize(table: pd.DataFrame, grid_keys: list[str]) -> pd.DataFrame:
    """Per grid point and metric: runs, completed, failed, n (finite values among completed
    runs), mean, std (ddof 1), ci95_low, ci95_high (mean -+ 1.96 std / sqrt(n), the normal
    approximation; NaN below 2 values)."""
    out = []
    metrics = metric_columns(table, grid_keys)
    for point, group in table.groupby("point", sort=True):
        ok = group[group["status"] == "ok"]
        base: dict[str, Any] = {"point": point}
        base.update({k: group[k].iloc[0] for k in grid_keys})
        base.update({"runs": len(group), "completed": len(ok), "failed": len(group) - len(ok)})
        for metric in metrics:
            vals = pd.to_numeric(ok[metric], errors="coerce").astype(float)
            vals = vals[vals.map(math.isfinite)]
            n = len(vals)
            mean = float(vals.mean()) if n else math.nan
            std = float(vals.std(ddof=1)) if n > 1 else math.nan
            half = Z95 * std / math.sqrt(n) if n > 1 else math.nan
            out.append({**base, "metric": metric, "n": n, "mean": mean, "std": std,
                        "ci95_low": mean - half, "ci95_high": mean + half})
    return pd.DataFrame(out)


def write_tables(out: Path, table: pd.DataFrame, grid_keys: list[str]) -> dict[str, str]:
    """DIR/runs.parquet and DIR/summary.csv; returns their paths."""
    runs = out / "runs.parquet"
    with replacing(runs, other="--out OTHERDIR") as tmp:
        table.to_parquet(tmp, index=False)
    summary = out / "summary.csv"
    write_text(summary, summarize(table, grid_keys).to_csv(index=False, float_format="%.9g"),
               other="--out OTHERDIR")
    return {"runs": str(runs), "summary": str(summary)}
