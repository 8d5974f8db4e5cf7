"""The robot's effect on the crowd: paired runs with and without it (``--vary
robots=with,without``).

Run k of both grid points has the same seed, so the people start alike and draw the same noise
until the robot first touches or is avoided: the difference of a metric between the two runs of
a seed is the robot's effect on that seed's crowd, and its mean over the seeds has a smaller
standard error than the difference of two independent means. ``paired.csv`` holds one row per
seed (and other grid point): each metric with, without and their difference;
``paired_summary.csv`` per metric: pairs, mean difference, its standard deviation and 95 %
interval (normal approximation: mean +- 1.96 std / sqrt(n)).
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pandas as pd

from sweep_core.ensemble.store import Z95
from sweep_core.io.outputs import write_text

#: the grid key and its two values
KEY, WITH, WITHOUT = "robots", "with", "without"
#: the compared metrics: name -> the summary columns that give it, the first present used
METRICS = {
    "evacuation_s": ("flow.t_all_s", "arrivals.t_all_s"),
    "evacuation_90_s": ("flow.t_90_s", "arrivals.t_90_s"),
    "evacuation_50_s": ("flow.t_50_s", "arrivals.t_50_s"),
    "evacuated": ("flow.evacuated", "arrivals.arrived"),
    "flow_per_s": ("flow.per_s",),
    "pressure_mean_m_per_s": ("reaction.pressure_mean_m_per_s",),
    "min_gap_m": ("min_gap.min_m",),
}


def apply(spec: dict, value: Any) -> dict:
    """The scene dict of a grid point's ``robots`` value: as it is (``with``), or without its
    robots and the crowd's reaction to them (``without``)."""
    if value == WITH:
        return spec
    out = {k: v for k, v in spec.items() if k != "crowd_reaction"}
    out[KEY] = []
    return out


def is_paired(keys: list[str], points: list[dict]) -> bool:
    """Whether the grid pairs runs with and without the robots."""
    return KEY in keys and {p[KEY] for p in points} == {WITH, WITHOUT}


def differences(table: pd.DataFrame, keys: list[str]) -> pd.DataFrame:
    """One row per seed and other grid point with both runs ``ok``: each metric's value with
    the robots, without, and the difference (with - without)."""
    others = [k for k in keys if k != KEY]
    ok = table[table["status"] == "ok"]
    cols = {name: next((c for c in candidates if c in ok and ok[c].notna().any()), None)
            for name, candidates in METRICS.items()}
    by = [*others, "seed"]
    with_ = ok[ok[KEY] == WITH].set_index(by)
    without = ok[ok[KEY] == WITHOUT].set_index(by)
    common = with_.index.intersection(without.index)
    out = pd.DataFrame(index=common)
    for name, col in cols.items():
        if col is None:
            continue
        a, b = with_.loc[common, col].astype(float), without.loc[common, col].astype(float)
        out[f"{name}.with"], out[f"{name}.without"] = a, b
        out[f"{name}.difference"] = a - b
    return out.reset_index()


def summary(diff: pd.DataFrame, keys: list[str]) -> pd.DataFrame:
    """Per other grid point and metric: pairs, mean difference, std and 95 % interval."""
    others = [k for k in keys if k != KEY]
    rows = []
    groups = diff.groupby(others, sort=False) if others else [((), diff)]
    for point, part in groups:
        point = point if isinstance(point, tuple) else (point,)
        for name in METRICS:
            col = f"{name}.difference"
            if col not in part:
                continue
            d = part[col].dropna()
            n = len(d)
            mean = float(d.mean()) if n else math.nan
            std = float(d.std(ddof=1)) if n > 1 else math.nan
            half = Z95 * std / math.sqrt(n) if n > 1 else math.nan
            rows.append({**dict(zip(others, point)), "metric": name, "pairs": n,
                         "mean_difference": mean, "std": std, "ci95_low": mean - half,
                         "ci95_high": mean + half})
    return pd.DataFrame(rows)


def write(out_dir: Path, table: pd.DataFrame, keys: list[str]) -> dict[str, str]:
    """``paired.csv`` and ``paired_summary.csv`` in DIR; their paths."""
    diff = differences(table, keys)
    files = {}
    for name, frame in (("paired", diff), ("paired_summary", summary(diff, keys))):
        path = out_dir / f"{name}.csv"
        write_text(path, frame.to_csv(index=False, float_format="%.9g"), other="--out OTHERDIR")
        files[name] = str(path)
    return files
