"""What the analysis figure shows of the crowd besides the per-frame metrics: trajectories
sampled at a bounded number of frames (:class:`Tracks`), the run's fundamental diagram
(:class:`Fundamental`: local density against speed, every agent of every frame counted) and
the distribution of the per-frame minimum gap (:func:`gap_distribution`)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sweep_core.model.neighbours import pairs_within

#: most frames a trajectory keeps (evenly spaced over the recording)
TRACK_FRAMES = 400
#: radius (m) of the disk the local density is counted in: agents (the agent itself included)
#: whose centres lie within it, over its area pi R^2 (no correction near walls)
DENSITY_RADIUS = 1.0
#: bins of the fundamental diagram: density, one bin per agent counted in the disk (bin k holds
#: k + 1 agents, (k + 1) / (pi R^2) per m^2; at most DENSITY_AGENTS), and speed (m/s); values
#: past the last bin fall in it
DENSITY_AGENTS = 30
SPEED_BIN, SPEED_MAX = 0.05, 3.0
#: |gap| at or below this (m) is rounding: the simulator accepts no state that breaks a
#: constraint by more than 1e-9 m, so touching disks show gaps of either sign at this level
ROUNDING_M = 1e-9


class Tracks:
    """Centres of every agent at up to :data:`TRACK_FRAMES` frames of a recording with
    ``frames`` frames (every ``stride``-th), with their times (s)."""

    def __init__(self, frames: int) -> None:
        self.stride = max(1, math.ceil(max(frames, 1) / TRACK_FRAMES))
        self.count = 0
        self.times: list[float] = []
        self.points: list[np.ndarray] = []

    def add(self, t: float, q: np.ndarray, ids: np.ndarray | None = None) -> None:
        """Keep the centres q (N, 2) m at time t (s); with ``ids`` (N,) (a scene with flows,
        where agents enter and leave) each agent keeps its row, its id."""
        if self.count % self.stride == 0:
            self.times.append(t)
            if ids is None:
                self.points.append(np.array(q, dtype=np.float64))
            else:
                p = np.full((int(ids.max(initial=-1)) + 1, 2), np.nan)
                p[ids] = q
                self.points.append(p)
        self.count += 1

    def array(self) -> np.ndarray:
        """(K, N, 2) m: the kept centres (NaN where an agent has none)."""
        if not self.points:
            return np.zeros((0, 0, 2))
        out = np.full((len(self.points), max(len(p) for p in self.points), 2), np.nan)
        for k, p in enumerate(self.points):
            out[k, :len(p)] = p
        return out


@dataclass
class FundamentalDiagram:
    """counts (D, S): agent-frames per (density, speed) bin; edges in 1/m^2 and m/s."""

    counts: np.ndarray
    density_edges: np.ndarray
    speed_edges: np.ndarray

    def mean_speed(self, least: int = 20) -> tuple[np.ndarray, np.ndarray]:
        """Density bin centres and the mean speed (m/s) in each bin with at least ``least``
        agent-frames (NaN elsewhere)."""
        centres = 0.5 * (self.speed_edges[1:] + self.speed_edges[:-1])
        n = self.counts.sum(axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = (self.counts * centres).sum(axis=1) / n
        mean[n < least] = np.nan
        return 0.5 * (self.density_edges[1:] + self.density_edges[:-1]), mean


class Fundamental:
    """Accumulates the fundamental diagram frame by frame."""

    def __init__(self) -> None:
        area = math.pi * DENSITY_RADIUS ** 2
        self.density_edges = (np.arange(DENSITY_AGENTS + 1) + 0.5) / area
        self.speed_edges = np.arange(0.0, SPEED_MAX + SPEED_BIN / 2, SPEED_BIN)
        self.counts = np.zeros((len(self.density_edges) - 1, len(self.speed_edges) - 1),
                               dtype=np.int64)

    def add(self, q: np.ndarray, speed: np.ndarray) -> None:
        """One frame: centres (N, 2) m and speeds (N,) m/s."""
        ok = np.all(np.isfinite(q), axis=1) & np.isfinite(speed)
        q, speed = q[ok], speed[ok]
        if len(q) == 0:
            return
        i, j = pairs_within(q, DENSITY_RADIUS)
        near = 1 + np.bincount(i, minlength=len(q)) + np.bincount(j, minlength=len(q))
        di = np.minimum(near - 1, self.counts.shape[0] - 1)
        si = np.minimum((speed / SPEED_BIN).astype(np.int64), self.counts.shape[1] - 1)
        np.add.at(self.counts, (di, si), 1)

    def result(self) -> FundamentalDiagram:
        return FundamentalDiagram(self.counts, self.density_edges, self.speed_edges)


def gap_distribution(gaps: np.ndarray) -> tuple[int, int, np.ndarray]:
    """Of the per-frame minimum gaps (m): frames touching at rounding level (|gap| <=
    :data:`ROUNDING_M`), frames below it (a real overlap), and the gaps above it."""
    g = gaps[np.isfinite(gaps)]
    touching = int(np.count_nonzero(np.abs(g) <= ROUNDING_M))
    overlap = int(np.count_nonzero(g < -ROUNDING_M))
    return touching, overlap, g[g > ROUNDING_M]
