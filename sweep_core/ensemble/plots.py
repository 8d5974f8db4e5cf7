"""Plots of an ensemble (matplotlib, Agg): histograms of evacuation time and minimum gap per
grid point, and those metrics (mean and 95 % interval) against each varied key."""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pandas as pd

from sweep_core.analysis.plots import pyplot
from sweep_core.ensemble.store import summarize
from sweep_core.io.outputs import replacing

#: candidates for "evacuation time", the first with a finite value wins: every agent through
#: the counting line (--line), then 90 % or 50 % of them, then the same for arrivals at the goal
EVACUATION = ("flow.t_all_s", "flow.t_90_s", "flow.t_50_s", "arrivals.t_all_s",
              "arrivals.t_90_s", "arrivals.t_50_s")
MIN_GAP = "min_gap.min_m"
#: at most this many grid points drawn in one histogram
MAX_SERIES = 8


def evacuation_column(table: pd.DataFrame) -> str | None:
    """The evacuation-time column with a finite value in some completed run, or None."""
    ok = table[table["status"] == "ok"]
    for col in EVACUATION:
        if col in ok and pd.to_numeric(ok[col], errors="coerce").notna().any():
            return col
    return None


def _label(row: Any, keys: list[str]) -> str:
    return ", ".join(f"{k}={_fmt(row[k])}" for k in keys) or "all runs"


def _fmt(v: Any) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


def _histogram(plt: Any, table: pd.DataFrame, col: str, keys: list[str], title: str,
               xlabel: str, png: Path) -> None:
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    ok = table[table["status"] == "ok"]
    drawn = 0
    for _, group in ok.groupby("point", sort=True):
        vals = pd.to_numeric(group[col], errors="coerce").dropna()
        vals = vals[vals.map(math.isfinite)]
        if not len(vals) or drawn >= MAX_SERIES:
            continue
        ax.hist(vals, bins=min(30, max(5, len(vals) // 3)), alpha=0.5,
                label=f"{_label(group.iloc[0], keys)} (n={len(vals)})")
        drawn += 1
    ax.set_xlabel(xlabel)
    ax.set_ylabel("runs")
    ax.set_title(title)
    if drawn:
        ax.legend(fontsize="small")
    fig.tight_layout()
    with replacing(png, other="--out OTHERDIR") as tmp:
        fig.savefig(tmp, format="png", dpi=100)
    plt.close(fig)


def _against(plt: Any, table: pd.DataFrame, key: str, keys: list[str], cols: list[str],
             png: Path) -> None:
    """Mean and 95 % interval of each column against ``key``, one line per combination of the
    other keys."""
    summary = summarize(table, keys)
    others = [k for k in keys if k != key]
    fig, axes = plt.subplots(1, len(cols), figsize=(5.0 * len(cols), 3.8), squeeze=False)
    values = list(dict.fromkeys(table[key]))
    numeric = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)
    for ax, col in zip(axes[0], cols):
        part = summary[summary["metric"] == col]
        groups = part.groupby(others, sort=False) if others else [((), part)]
        for i, (_, g) in enumerate(groups):
            if i >= MAX_SERIES:
                break
            x = g[key].tolist() if numeric else [values.index(v) for v in g[key]]
            label = _label(g.iloc[0], others) if others else None
            ax.errorbar(x, g["mean"], yerr=[g["mean"] - g["ci95_low"], g["ci95_high"] - g["mean"]],
                        marker="o", capsize=3, label=label)
        if not numeric:
            ax.set_xticks(range(len(values)), [str(v) for v in values])
        ax.set_xlabel(key)
        ax.set_ylabel(col)
        if others:
            ax.legend(fontsize="small")
    fig.suptitle(f"mean and 95 % interval (normal approximation) against {key}")
    fig.tight_layout()
    with replacing(png, other="--out OTHERDIR") as tmp:
        fig.savefig(tmp, format="png", dpi=100)
    plt.close(fig)


def write_plots(out: Path, table: pd.DataFrame, keys: list[str]) -> dict[str, str]:
    """DIR/hist_evacuation.png, DIR/hist_min_gap.png and DIR/vs_<key>.png per varied key
    (those with data); returns name -> path."""
    plt = pyplot()
    files: dict[str, str] = {}
    evac = evacuation_column(table)
    if evac is not None:
        png = out / "hist_evacuation.png"
        _histogram(plt, table, evac, keys, f"evacuation time ({evac})", "time, s", png)
        files["hist_evacuation"] = str(png)
    if MIN_GAP in table:
        png = out / "hist_min_gap.png"
        _histogram(plt, table, MIN_GAP, keys, "minimum gap over the run", "gap, m", png)
        files["hist_min_gap"] = str(png)
    cols = [c for c in (evac, MIN_GAP) if c is not None and c in table]
    if cols and (table["status"] == "ok").any():
        for key in keys:
            png = out / f"vs_{key.replace('/', '_')}.png"
            _against(plt, table, key, keys, cols, png)
            files[f"vs_{key}"] = str(png)
    return files
