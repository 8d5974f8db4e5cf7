"""The field's references a run is put beside (``sweep analyze``, ``sweep verify``): the
experiments' flow through a bottleneck against its width (``data/bottleneck_flow.csv``:
Seyfried et al. 2009, Kretz et al. 2006) and Weidmann's speed against density
(:func:`sweep_core.model.ring.weidmann`).

The reference flow at a width is the experiments' line: the least-squares line J = a + b w
through every bundled experimental point of width :data:`LINE_WIDTHS` (both experiments: 18
points at 0.8-1.2 m), the line ``sweep verify``'s bottleneck test judges against, within
:data:`TOLERANCE`. It is given only for widths inside that range.
"""
from __future__ import annotations

import csv
import functools
import math
from importlib import resources
from typing import Any

import numpy as np

from sweep_core.model.ring import weidmann as weidmann

__all__ = ["LINE_WIDTHS", "TOLERANCE", "experimental_line", "experiments", "flow_reference",
           "line_flow_at", "source_flow", "weidmann"]

#: widths (m) of the points the experiments' line is fitted to, and where it is used
LINE_WIDTHS = (0.8, 1.2)
#: relative departure from the experiments' line ``sweep verify`` accepts
TOLERANCE = 0.15
#: the experiments the data holds: key -> citation
SOURCES = {"seyfried2009": "Seyfried et al. 2009", "kretz2006": "Kretz et al. 2006"}


@functools.cache
def experiments() -> tuple[tuple[str, float, float], ...]:
    """(source, width m, flow 1/s) of the bundled experimental data, read once."""
    text = resources.files("sweep_core").joinpath("analysis/data/bottleneck_flow.csv"
                                                  ).read_text()
    rows = csv.DictReader(ln for ln in text.splitlines() if not ln.startswith("#"))
    return tuple((r["source"], float(r["width_m"]), float(r["flow_per_s"])) for r in rows)


def source_flow(source: str, width: float) -> float:
    """One experiment's flow (1/s) at a width (m): the mean of its points at each width,
    interpolated linearly between widths. ``source`` as in the data ("seyfried2009",
    "kretz2006")."""
    by_width: dict[float, list[float]] = {}
    for s, w, j in experiments():
        if s == source:
            by_width.setdefault(w, []).append(j)
    if not by_width:
        raise ValueError(f"no experimental bottleneck data from {source!r}; the sources are "
                         f"{sorted({s for s, _, _ in experiments()})}")
    ws = sorted(by_width)
    return float(np.interp(width, ws, [math.fsum(by_width[w]) / len(by_width[w]) for w in ws]))


@functools.cache
def experimental_line() -> tuple[float, float]:
    """(a (1/s), b (1/(m s))) of the least-squares line J = a + b w through every bundled
    experimental point of width in :data:`LINE_WIDTHS`. Closed form with correctly rounded
    sums, so the same on every CPU."""
    pts = [(w, j) for _, w, j in experiments() if LINE_WIDTHS[0] <= w <= LINE_WIDTHS[1]]
    n = len(pts)
    w_mean = math.fsum(w for w, _ in pts) / n
    j_mean = math.fsum(j for _, j in pts) / n
    b = (math.fsum((w - w_mean) * (j - j_mean) for w, j in pts)
         / math.fsum((w - w_mean) ** 2 for w, _ in pts))
    return j_mean - b * w_mean, b


def line_flow_at(width: float) -> float:
    """The experiments' line (:func:`experimental_line`) at a width (m): flow J (1/s)."""
    a, b = experimental_line()
    return a + b * width


def flow_reference(width: float, flow: float | None) -> dict[str, Any]:
    """A flow (1/s) through a line of ``width`` m beside the experiments: their line's flow
    and specific flow there, the band ``sweep verify`` accepts, and the departure (%); the
    reason instead when the width lies outside :data:`LINE_WIDTHS` or there is no flow."""
    out: dict[str, Any] = {"width_m": width, "source": " and ".join(SOURCES.values())
                           + f": least-squares line through their points at "
                           f"{LINE_WIDTHS[0]:g}-{LINE_WIDTHS[1]:g} m"}
    lo, hi = LINE_WIDTHS
    if not lo - 1e-9 <= width <= hi + 1e-9:
        out["note"] = (f"no reference: the line is {width:.3g} m wide, the experiments' line "
                       f"covers {lo:g}-{hi:g} m")
        return out
    ref = line_flow_at(width)
    out.update({"flow_per_s": ref, "specific_flow_per_m_s": ref / width,
                "band_per_s": [ref * (1 - TOLERANCE), ref * (1 + TOLERANCE)],
                "departure_pct": (100.0 * (flow / ref - 1.0) if flow is not None
                                  and math.isfinite(flow) else None)})
    return out


def points_near(width: float, tol: float = 0.05) -> np.ndarray:
    """(K, 2): width (m) and flow (1/s) of the experimental points within ``tol`` m of a
    width."""
    pts = [(w, j) for _, w, j in experiments() if abs(w - width) <= tol]
    return np.array(pts, dtype=np.float64).reshape(-1, 2)
