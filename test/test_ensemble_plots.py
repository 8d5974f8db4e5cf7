"""The ensemble's figures account for every grid point: a point without a value is named with
the reason (no run reached the fraction, every run failed), and minimum gaps at rounding level
are stated, not plotted. The figures are read from matplotlib's objects (texts, legends, line
data), not pixels; a synthetic runs table stands in for an ensemble (no Dask)."""
from __future__ import annotations

import math

import matplotlib
import numpy as np
import pandas as pd
import pytest
from matplotlib.text import Text

from sweep_core.ensemble import plots

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

NAN = math.nan


def table() -> pd.DataFrame:
    """Three grid points of dt, four runs each: dt=0.01 every run arrives, its minimum gaps are
    rounding (4e-15 .. 7.5e-15 m); dt=0.02 no run reaches 50 % arrived, gaps of 4 to 7 cm;
    dt=0.04 every run failed."""
    rows = []
    data = {0.01: ("ok", [3.1, 3.3, 3.2, 3.4], [4e-15, 7.5e-15, 5e-15, 6e-15]),
            0.02: ("ok", [NAN] * 4, [0.05, 0.06, 0.04, 0.07]),
            0.04: ("failed", [NAN] * 4, [NAN] * 4)}
    for point, (dt, (status, t50, gap)) in enumerate(data.items()):
        for run in range(4):
            rows.append({"point": point, "run": run, "seed": run, "dt": dt, "status": status,
                         "arrivals.t_50_s": t50[run], "min_gap.min_m": gap[run]})
    return pd.DataFrame(rows)


@pytest.fixture
def figures(tmp_path, monkeypatch):
    """The figures write_plots makes, kept open (plt.close does nothing meanwhile)."""
    plt.close("all")
    monkeypatch.setattr(plt, "close", lambda *a, **k: None)
    files = plots.write_plots(tmp_path, table(), ["dt"])
    assert set(files) == {"hist_evacuation", "hist_min_gap", "vs_dt"}
    figs = [plt.figure(n) for n in plt.get_fignums()]
    monkeypatch.undo()
    yield figs
    plt.close("all")


def texts(fig) -> str:
    return "\n".join(t.get_text() for t in fig.findobj(Text))


def legend(fig) -> str:
    return "\n".join(t.get_text() for ax in fig.axes if ax.get_legend()
                     for t in ax.get_legend().get_texts())


def find(figs, words: str):
    (fig,) = [f for f in figs if words in texts(f)]
    return fig


def unaccounted(fig, labels) -> list[str]:
    """The grid point labels a figure neither draws nor names in a note."""
    return [lab for lab in labels if lab not in texts(fig)]


LABELS = ["dt=0.01", "dt=0.02", "dt=0.04"]


def test_a_grid_point_without_a_value_is_named_with_the_reason(figures):
    fig = find(figures, "evacuation time (arrivals.t_50_s)")
    assert unaccounted(fig, LABELS) == []
    assert "dt=0.01 (n=4)" in legend(fig)
    t = texts(fig)
    assert "dt=0.02: no value: no run reached 50 % of the agents arriving (4 completed runs)" in t
    assert "dt=0.04: no value: all 4 runs failed" in t


def test_minimum_gaps_at_rounding_level_are_stated_not_plotted(figures):
    fig = find(figures, "minimum gap over the run")
    assert unaccounted(fig, LABELS) == []
    assert "dt=0.01: at rounding level (|gap| <= 1e-09 m: the disks touch) in all 4 runs" in (
        texts(fig))
    assert "dt=0.01" not in legend(fig) and "dt=0.02 (n=4)" in legend(fig)
    ax = fig.axes[0]
    assert ax.get_xlim()[0] > 0.01  # only the 4 .. 7 cm gaps are on the axis


def test_the_curve_against_a_key_notes_the_points_it_lacks(figures):
    fig = find(figures, "against dt")
    evac, gap = fig.axes[:2]
    assert evac.get_ylabel() == "arrivals.t_50_s" and gap.get_ylabel() == "min_gap.min_m"
    (line,) = [ln for ln in evac.get_lines() if len(ln.get_xdata()) and ln.get_marker() == "o"]
    assert list(line.get_xdata()) == [0.01]
    np.testing.assert_allclose(line.get_ydata(), [3.25])
    (line,) = [ln for ln in gap.get_lines() if len(ln.get_xdata()) and ln.get_marker() == "o"]
    assert list(line.get_xdata()) == [0.02]
    t = texts(fig)
    for note in ("arrivals.t_50_s at dt=0.02: no value: no run reached 50 %",
                 "arrivals.t_50_s at dt=0.04: no value: all 4 runs failed",
                 "min_gap.min_m at dt=0.01: at rounding level",
                 "min_gap.min_m at dt=0.04: no value: all 4 runs failed"):
        assert note in t


def test_the_default_figure_has_values_when_evacuation_and_gaps_have_none(tmp_path, monkeypatch):
    # no run reaches any evacuation fraction and every minimum gap is at rounding level: the
    # figure against dt draws the windowed mean speed and the touching constraints instead
    rows = [{"point": p, "run": r, "seed": r, "dt": dt, "status": "ok",
             "arrivals.t_50_s": NAN, "min_gap.min_m": 3e-15, "speed.mean_m_per_s": 1.0 + r / 10,
             "speed.window_s": 0.625, "touching.mean": 5.0 + r}
            for p, dt in enumerate((0.01, 0.02)) for r in range(3)]
    plt.close("all")
    monkeypatch.setattr(plt, "close", lambda *a, **k: None)
    files = plots.write_plots(tmp_path, pd.DataFrame(rows), ["dt"])
    assert "vs_dt" in files
    fig = find([plt.figure(n) for n in plt.get_fignums()], "against dt")
    monkeypatch.undo()
    labels = [ax.get_ylabel() for ax in fig.axes]
    assert labels == ["speed.mean_m_per_s (over 0.625 s)", "touching.mean"]
    for ax in fig.axes:  # every panel draws both grid points
        (line,) = [ln for ln in ax.get_lines() if ln.get_marker() == "o"]
        assert list(line.get_xdata()) == [0.01, 0.02]
    plt.close("all")
