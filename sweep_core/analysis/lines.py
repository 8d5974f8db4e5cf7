"""Measurement lines of ``sweep analyze --line``: the segment parsed, and which agents' moves
cross it in which direction."""
from __future__ import annotations

import math

import numpy as np

from sweep_core.errors import SweepError

__all__ = ["line_crossings", "parse_line"]


def parse_line(text: str) -> tuple[float, float, float, float]:
    """``x0,y0,x1,y1`` -> 4 floats (a segment of non-zero length)."""
    try:
        vals = tuple(float(v) for v in text.split(","))
    except ValueError:
        vals = ()
    if len(vals) != 4 or not all(math.isfinite(v) for v in vals):
        raise SweepError(f"--line: {text!r} is not x0,y0,x1,y1 (four numbers, m)")
    if vals[0] == vals[2] and vals[1] == vals[3]:
        raise SweepError(f"--line: {text!r} has zero length")
    return vals  # type: ignore[return-value]


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
