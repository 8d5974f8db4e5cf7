"""Measurement lines of ``sweep analyze --line``: the segment parsed, and which agents' moves
cross it in which direction."""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from sweep_core.analysis.arrivals import stats, time_for
from sweep_core.analysis.references import flow_reference
from sweep_core.errors import SweepError
from sweep_core.model.outlines import segments_meet

__all__ = ["crossing_flows", "flow_summary", "line_crossings", "line_outside_sinks",
           "line_width", "parse_line"]


def parse_line(text: str) -> tuple[float, float, float, float]:
    """``x0,y0,x1,y1`` -> 4 floats (a segment of non-zero length)."""
    try:
        vals = tuple(float(v) for v in text.split(","))
    except ValueError:
        vals = ()
    if len(vals) != 4 or not all(math.isfinite(v) for v in vals):
        raise SweepError(f"--line: {text!r} is not x0,y0,x1,y1 (four numbers, m)")
    if vals[0] == vals[2] and vals[1] == vals[3]:
        raise SweepError(f"--line: {text!r} has zero length: both ends are the same point "
                         "(fix: give two different ends x0,y0,x1,y1, e.g. 10,4.4,10,5.6)")
    return vals  # type: ignore[return-value]


def line_outside_sinks(line: tuple[float, float, float, float] | None, scene: Any
                       ) -> tuple[float, float, float, float] | None:
    """The line, or a SweepError when it meets a sink of the recorded scene (``scene``, a
    :class:`~sweep_core.model.scene.Scene` or None): an agent leaves as its centre enters a
    sink, so no frame holds it past a line there and its crossing is never counted."""
    flows = getattr(scene, "flows", None)
    if line is None or flows is None:
        return line
    a, b = np.array(line[:2]), np.array(line[2:])
    for k, sink in enumerate(flows.sinks):
        edges = segments_meet(a, b, sink.points, np.roll(sink.points, -1, axis=0))
        if edges.any() or sink.contains(np.array([a, b])).any():
            shown = ",".join(f"{v:g}" for v in line)
            where = (f"(rectangle {sink.lo.tolist()} to {sink.hi.tolist()})" if sink.is_rectangle
                     else f"(polygon of {len(sink.points)} points)")
            raise SweepError(f"--line {shown}: meets the scene's flows.sinks[{k}] "
                             f"{where}; an agent leaves as its centre enters a sink, so "
                             "no frame holds it past the line and its crossing would not be "
                             "counted (fix: put the line outside every sink, before it)")
    return line


def line_crossings(p0: np.ndarray, p1: np.ndarray, line: tuple[float, float, float, float]
                   ) -> np.ndarray:
    """Per agent: +1 if the move p0 -> p1 crosses the segment in the positive direction, -1 in
    the negative one, 0 otherwise.

    Positive is along the normal (y1 - y0, -(x1 - x0)), i.e. from left to right looking from
    (x0, y0) to (x1, y1). A point on the line counts as on its positive side.
    """
    a = np.array(line[:2])
    d = np.array(line[2:]) - a
    nrm = np.array([d[1], -d[0]])
    s0 = (p0 - a) @ nrm
    s1 = (p1 - a) @ nrm
    up = (s0 < 0) & (s1 >= 0)
    down = (s0 >= 0) & (s1 < 0)
    out = np.zeros(len(p0), dtype=np.int64)
    moved = up | down
    if moved.any():
        frac = s0[moved] / (s0[moved] - s1[moved])
        x = p0[moved] + frac[:, None] * (p1[moved] - p0[moved])
        u = (x - a) @ d / (d @ d)
        inside = (u >= 0) & (u <= 1)
        idx = np.nonzero(moved)[0][inside]
        out[idx] = np.where(up[idx], 1, -1)
    return out


#: the share of the crossings left out at each end of the steady flow (as sweep verify's
#: bottleneck test counts it)
STEADY_TRIM = 0.1
#: fewest crossings for the steady flow (fewer: the flow from the first to the last crossing)
STEADY_LEAST = 10


def line_width(line: tuple[float, float, float, float]) -> float:
    """The segment's length (m)."""
    return math.hypot(line[2] - line[0], line[3] - line[1])


def crossing_flows(times: np.ndarray) -> dict[str, float | None]:
    """Flows (1/s) from the times (s) of the positive crossings, in order: ``per_s``, the
    crossings after the first over the time from the first to the last, (n - 1) / (t_n - t_1)
    (PedPy's flow at a line; None below two crossings or with no time between them), and
    ``steady_per_s``, the same between the crossings at 10 % and 90 % of them (sweep verify's
    steady flow; None below :data:`STEADY_LEAST` crossings)."""
    t = np.sort(np.asarray(times, dtype=np.float64))
    n = len(t)
    per_s = (n - 1) / float(t[-1] - t[0]) if n > 1 and t[-1] > t[0] else None
    steady = None
    if n >= STEADY_LEAST:
        a, b = int(STEADY_TRIM * n), int((1 - STEADY_TRIM) * n) - 1
        steady = (b - a) / float(t[b] - t[a]) if t[b] > t[a] else None
    return {"per_s": per_s, "steady_per_s": steady}


def flow_summary(line: tuple[float, float, float, float], counts: tuple[int, int, int],
                 crossings: np.ndarray, evacuation: np.ndarray, n: int) -> dict[str, Any]:
    """The summary's ``flow`` section: the line, its width, the ``counts`` (net, positive,
    negative), the flows of :func:`crossing_flows` from the times (s) of the positive
    ``crossings``, the evacuation times (each agent's first positive crossing, s; NaN: never)
    of ``n`` agents, and the experiments' flow for its width (``reference``)."""
    flows = crossing_flows(crossings)
    width = line_width(line)
    net, positive, negative = counts
    rate = flows["steady_per_s"] or flows["per_s"]
    return {
        "line": list(line),
        "width_m": width,
        "net": net, "positive": positive, "negative": negative,
        "per_s": flows["per_s"],
        "steady_per_s": flows["steady_per_s"],
        "counted": "per_s from the first to the last positive crossing, steady_per_s from the "
                   "crossing at 10 % of them to the one at 90 %",
        "specific_per_m_s": rate / width if rate is not None else None,
        "evacuated": int(np.count_nonzero(np.isfinite(evacuation))),
        "t_first_s": stats(evacuation, np.min),
        "t_50_s": time_for(evacuation, n, 0.5),
        "t_90_s": time_for(evacuation, n, 0.9),
        "t_all_s": time_for(evacuation, n, 1.0),
        "precision": "float64 (/poses); crossings between recorded frames, positive along "
                     "(y1 - y0, x0 - x1), timed at the frame after; per_s: (positive "
                     "crossings - 1) / (last - first crossing); steady_per_s: the same between "
                     "the crossings at 10 % and 90 % of them (sweep verify's bottleneck flow); "
                     "specific: steady (else per_s) / width",
        "reference": flow_reference(width, rate),
    } | ({"note": f"{negative} of the {positive + negative} crossings are negative (right to "
                  "left): per_s, steady_per_s and the evacuation times count the positive ones "
                  "only (fix: for the other direction give the ends swapped, --line "
                  + ",".join(f"{v:g}" for v in (*line[2:], *line[:2])) + ")"}
         if negative > positive else {})
