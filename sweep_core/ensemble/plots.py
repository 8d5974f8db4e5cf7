"""Plots of an ensemble (matplotlib, Agg): histograms of evacuation time and minimum gap per
grid point, and those metrics (mean and 95 % interval) against each varied key.

Every grid point appears in every figure: drawn, or named in a note under the axes that says
why it has no value (no run reached the fraction of agents the time is for, every run failed,
more points than the figure draws). A minimum gap within 1e-9 m of zero
(:data:`~sweep_core.analysis.crowd.ROUNDING_M`) is the rounding of touching disks, not a
distance: such values are drawn at 0 m and counted in a note, and a point whose every value is
at that level is stated "at rounding level", not plotted."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from sweep_core.analysis.crowd import ROUNDING_M
from sweep_core.analysis.drawing import pyplot
from sweep_core.ensemble.store import Z95
from sweep_core.io.outputs import replacing

#: candidates for "evacuation time", the first with a finite value wins: every agent through
#: the counting line (--line), then 90 % or 50 % of them, then the same for arrivals at the goal
EVACUATION = ("flow.t_all_s", "flow.t_90_s", "flow.t_50_s", "arrivals.t_all_s",
              "arrivals.t_90_s", "arrivals.t_50_s")
#: what a run must reach for each evacuation column to have a value
REACHED = {"flow.t_all_s": "every agent crossing the line",
           "flow.t_90_s": "90 % of the agents crossing the line",
           "flow.t_50_s": "50 % of the agents crossing the line",
           "arrivals.t_all_s": "every agent arriving", "arrivals.t_90_s": "90 % of the agents arriving",
           "arrivals.t_50_s": "50 % of the agents arriving"}
MIN_GAP = "min_gap.min_m"
#: metrics every completed run has (the windowed mean speed, the touching constraints), drawn
#: against the varied keys beside the evacuation time and minimum gap
ALWAYS = ("speed.mean_m_per_s", "touching.mean")
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


@dataclass
class PointValues:
    """One grid point's values of a column: ``label`` (its keys), ``values`` (finite, of the
    completed runs; gaps at rounding level set to 0), the runs and completed runs, and the
    ``note`` the figure prints for it (None: nothing to say)."""

    point: Any
    row: Any
    label: str
    values: np.ndarray
    runs: int
    completed: int
    note: str | None = None
    #: every value at rounding level: stated, not plotted
    rounding: bool = False
    extra: list[str] = field(default_factory=list)

    @property
    def drawable(self) -> bool:
        return len(self.values) > 0 and not self.rounding

    def mean_ci(self) -> tuple[float, float, float]:
        """Mean and the normal 95 % interval (NaN half-width below 2 values)."""
        n = len(self.values)
        mean = float(self.values.mean())
        half = Z95 * float(self.values.std(ddof=1)) / math.sqrt(n) if n > 1 else math.nan
        return mean, mean - half, mean + half


def point_values(table: pd.DataFrame, col: str, keys: list[str]) -> list[PointValues]:
    """The values of ``col`` per grid point, each with what a figure must say about it."""
    out = []
    for point, group in table.groupby("point", sort=True):
        ok = group[group["status"] == "ok"]
        vals = (pd.to_numeric(ok[col], errors="coerce").astype(float).to_numpy()
                if col in ok else np.zeros(0))
        vals = vals[np.isfinite(vals)]
        pv = PointValues(point, group.iloc[0], _label(group.iloc[0], keys), vals, len(group),
                         len(ok))
        failed = len(group) - len(ok)
        if len(ok) == 0:
            pv.note = f"no value: all {len(group)} runs failed"
        elif len(vals) == 0:
            what = REACHED.get(col)
            pv.note = ("no value: " + (f"no run reached {what}" if what else
                                       f"{col} has no finite value in any completed run")
                       + f" ({len(ok)} completed runs)")
        else:
            if len(vals) < len(ok):
                what = REACHED.get(col, f"a finite {col}")
                pv.extra.append(f"{len(ok) - len(vals)} of {len(ok)} completed runs did not "
                                f"reach {what}")
            if col == MIN_GAP:
                small = np.abs(vals) <= ROUNDING_M
                if np.all(small):
                    pv.rounding = True
                    pv.extra.insert(0, f"at rounding level (|gap| <= {ROUNDING_M:g} m: the "
                                    f"disks touch) in all {len(vals)} runs, not plotted")
                elif np.any(small):
                    pv.values = np.where(small, 0.0, vals)
                    pv.extra.append(f"{int(small.sum())} of {len(vals)} runs at rounding level "
                                    f"(|gap| <= {ROUNDING_M:g} m), drawn at 0 m")
        if failed and len(ok):
            pv.extra.append(f"{failed} of {len(group)} runs failed")
        if pv.extra:
            pv.note = "; ".join(([pv.note] if pv.note else []) + pv.extra)
        out.append(pv)
    return out


def _notes(fig: Any, lines: list[str]) -> None:
    """The notes under the axes, one line each (the figure grows to hold them)."""
    if not lines:
        return
    w, h = fig.get_size_inches()
    extra = 0.17 * len(lines) + 0.1
    fig.set_size_inches(w, h + extra)
    fig.subplots_adjust(bottom=(extra + 0.5) / (h + extra))
    fig.text(0.01, 0.01, "\n".join(lines), ha="left", va="bottom", fontsize="small")


def histogram_figure(plt: Any, table: pd.DataFrame, col: str, keys: list[str], title: str,
                     xlabel: str) -> Any:
    """A histogram of ``col`` per grid point (at most :data:`MAX_SERIES`), every other point
    named in a note saying why it is not drawn."""
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    notes = []
    drawn = 0
    for pv in point_values(table, col, keys):
        if pv.drawable and drawn < MAX_SERIES:
            ax.hist(pv.values, bins=min(30, max(5, len(pv.values) // 3)), alpha=0.5,
                    label=f"{pv.label} (n={len(pv.values)})")
            drawn += 1
            if pv.note:
                notes.append(f"{pv.label}: {pv.note}")
        elif pv.drawable:
            notes.append(f"{pv.label}: not drawn (at most {MAX_SERIES} grid points per "
                         "histogram; see summary.csv)")
        else:
            notes.append(f"{pv.label}: {pv.note}")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("runs")
    ax.set_title(title)
    if drawn:
        ax.legend(fontsize="small")
    else:
        ax.text(0.5, 0.5, "nothing to plot: see the notes", ha="center", va="center",
                transform=ax.transAxes)
    fig.tight_layout()
    _notes(fig, notes)
    return fig


def against_figure(plt: Any, table: pd.DataFrame, key: str, keys: list[str], cols: list[str]
                   ) -> Any:
    """Mean and 95 % interval of each column against ``key``, one line per combination of the
    other keys; the grid points without a value named in a note with the reason."""
    others = [k for k in keys if k != key]
    fig, axes = plt.subplots(1, len(cols), figsize=(5.0 * len(cols), 3.8), squeeze=False)
    values = list(dict.fromkeys(table[key]))
    numeric = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)
    notes = []
    for ax, col in zip(axes[0], cols):
        series: dict[str, list[tuple[Any, float, float, float]]] = {}
        lacking = []
        for pv in point_values(table, col, keys):
            if pv.note:
                notes.append(f"{col} at {pv.label}: {pv.note}")
            if not pv.drawable:
                lacking.append(pv.row[key] if numeric else values.index(pv.row[key]))
                continue
            line = _label(pv.row, others) if others else ""
            x = pv.row[key] if numeric else values.index(pv.row[key])
            series.setdefault(line, []).append((x, *pv.mean_ci()))
        for i, (line, pts) in enumerate(series.items()):
            if i >= MAX_SERIES:
                notes.append(f"{col}: {len(series) - MAX_SERIES} more lines not drawn (see "
                             "summary.csv)")
                break
            x, mean, low, high = (np.array(c, dtype=float) for c in zip(*pts))
            ax.errorbar(x, mean, yerr=[mean - low, high - mean], marker="o", capsize=3,
                        label=line or None)
        if lacking:  # marked on the axis: a point without a value is not just absent
            from matplotlib.transforms import blended_transform_factory
            ax.plot(lacking, [0.03] * len(lacking), "x", color="0.4", clip_on=False,
                    transform=blended_transform_factory(ax.transData, ax.transAxes),
                    label="no value (see the notes)")
        ax.set_xticks(values if numeric else range(len(values)), [_fmt(v) for v in values])
        ax.set_xlabel(key)
        ax.set_ylabel(_axis_label(table, col))
        if (others and series) or lacking:
            ax.legend(fontsize="small")
    fig.suptitle(f"mean and 95 % interval (normal approximation) against {key}")
    fig.tight_layout()
    _notes(fig, notes)
    return fig


def _axis_label(table: pd.DataFrame, col: str) -> str:
    """A column's name, with the speed window (s) the runs' speeds were measured over."""
    if col.startswith("speed.") and "speed.window_s" in table:
        windows = sorted({float(w) for w in pd.to_numeric(table["speed.window_s"],
                                                          errors="coerce").dropna()})
        if windows:
            return f"{col} (over {', '.join(f'{w:g}' for w in windows)} s)"
    return col


def default_columns(table: pd.DataFrame, keys: list[str]) -> list[str]:
    """The columns drawn against the varied keys: the evacuation time, the minimum gap and
    :data:`ALWAYS`, each only when some grid point has a value to draw."""
    evac = evacuation_column(table)
    out = []
    for col in (evac, MIN_GAP, *ALWAYS):
        if col is not None and col in table and any(
                pv.drawable for pv in point_values(table, col, keys)):
            out.append(col)
    return out


def _save(plt: Any, fig: Any, png: Path) -> None:
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
        _save(plt, histogram_figure(plt, table, evac, keys, f"evacuation time ({evac})",
                                    "time, s"), png)
        files["hist_evacuation"] = str(png)
    if MIN_GAP in table:
        png = out / "hist_min_gap.png"
        _save(plt, histogram_figure(plt, table, MIN_GAP, keys, "minimum gap over the run",
                                    "gap, m"), png)
        files["hist_min_gap"] = str(png)
    cols = default_columns(table, keys)
    if cols and (table["status"] == "ok").any():
        for key in keys:
            png = out / f"vs_{key.replace('/', '_')}.png"
            _save(plt, against_figure(plt, table, key, keys, cols), png)
            files[f"vs_{key}"] = str(png)
    return files
