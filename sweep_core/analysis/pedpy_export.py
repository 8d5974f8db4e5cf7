"""Trajectories for PedPy, the Jülich group's pedestrian analysis package: a recording (or
arrays) as a ``pedpy.TrajectoryData``, its text export, and PedPy's own measurements (classic
and Voronoi density, speed, flow at a line, fundamental diagram) called on it.

Frames: frame k is recorded step k * record_every, so the frame rate is 1 / (dt record_every)
frames per second (dt and record_every from the recording's metadata; without record_every,
from the smallest step between recorded states). Ids: the ``id`` column of ``/agents`` (agents
keep their id when others leave or enter); a recording without ``/agents`` numbers the agents
of each frame 0 .. N - 1. Coordinates in metres.

PedPy is imported when one of these functions runs (it pulls in shapely and pandas).
"""
from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sweep_core.analysis.frames import FrameReader
from sweep_core.analysis.run import NS, load_run
from sweep_core.errors import RecordingError, SweepError
from sweep_core.io.outputs import replacing


@dataclass
class Trajectories:
    """Every agent's recorded positions, one row per agent and frame: ``ids`` (M,) int,
    ``frames`` (M,) int, ``xy`` (M, 2) m, and ``frame_rate`` (frames per second)."""

    ids: np.ndarray
    frames: np.ndarray
    xy: np.ndarray
    frame_rate: float

    @classmethod
    def from_frames(cls, frames: Sequence[tuple[int, np.ndarray, np.ndarray]],
                    frame_rate: float) -> Trajectories:
        """From (frame number, ids (N,), positions (N, 2) m) per frame."""
        if not frames:
            return cls(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 2)),
                       frame_rate)
        return cls(np.concatenate([np.asarray(i, np.int64) for _, i, _ in frames]),
                   np.concatenate([np.full(len(i), k, np.int64) for k, i, _ in frames]),
                   np.concatenate([np.asarray(q, np.float64).reshape(-1, 2)
                                   for _, _, q in frames]), float(frame_rate))

    def to_pedpy(self) -> Any:
        """A ``pedpy.TrajectoryData`` (columns id, frame, x, y)."""
        import pandas as pd
        import pedpy

        data = pd.DataFrame({"id": self.ids, "frame": self.frames,
                             "x": self.xy[:, 0], "y": self.xy[:, 1]})
        return pedpy.TrajectoryData(data=data, frame_rate=self.frame_rate)


def read_trajectories(path: str | os.PathLike[str]) -> Trajectories:
    """The trajectories of a recording (module docstring).

    Raises:
        RecordingError: not a recording of ``sweep run`` or the node, or no dt in it.
    """
    meta = load_run(path)
    if meta.resets:
        raise RecordingError(f"{path}: has {len(meta.resets)} resets; a trajectory for PedPy "
                             "is one run (fix: export a recording without resets)")
    rows: list[tuple[int, np.ndarray, np.ndarray]] = []
    steps: list[int] = []
    flows = meta.changes_population
    for fr in FrameReader(meta):
        if meta.dt is None:
            raise RecordingError(f"{path}: its metadata give no time step dt; PedPy needs "
                                 "the frame rate (fix: export a recording of sweep run or "
                                 "the node)")
        step = int(round(fr.stamp_ns / (meta.dt * NS)))
        known = fr.agents is not None and "id" in fr.agents and len(fr.agents["id"]) == \
            len(fr.positions)
        if not known and flows:
            raise RecordingError(f"{path}: the state at t = {fr.stamp_ns / NS:g} s has no "
                                 "readable /agents ids, which a scene whose agents enter and "
                                 "leave needs (numbering them 0 .. N - 1 would mix agents up) "
                                 "(fix: record /agents, as sweep run does)")
        ids = (np.rint(fr.agents["id"]).astype(np.int64) if known and fr.agents is not None
               else np.arange(len(fr.positions)))
        steps.append(step)
        rows.append((step, ids, fr.positions))
    every = meta.record_every
    if not every:
        diffs = np.diff(np.asarray(steps))
        every = int(diffs[diffs > 0].min()) if np.any(diffs > 0) else 1
    if meta.dt is None:
        raise RecordingError(f"{path}: holds no recorded state (fix: record at least one step)")
    return Trajectories.from_frames([(s // every, i, q) for s, i, q in rows],
                                    1.0 / (meta.dt * every))


def write_pedpy_txt(traj: Trajectories, out: str | os.PathLike[str],
                    inputs: Sequence[str | os.PathLike[str]] = ()) -> Path:
    """PedPy's text format (``pedpy.load_trajectory_from_txt`` reads it): a commented header
    with the frame rate and the unit, then one line ``id frame x y z`` per agent and frame."""
    order = np.lexsort((traj.frames, traj.ids))
    header = (f"# sweep_ros trajectories for PedPy\n# framerate: {traj.frame_rate:.10g}\n"
              "# x/m y/m z/m\n# id frame x y z\n")
    table = np.column_stack([traj.ids[order], traj.frames[order], traj.xy[order],
                             np.zeros(len(order))])
    with replacing(out, inputs, other="--pedpy OTHER") as tmp:
        with open(tmp, "w") as f:
            f.write(header)
            np.savetxt(f, table, fmt=["%d", "%d", "%.6f", "%.6f", "%.1f"])
    return Path(os.fspath(out))


def rectangle(lo: Sequence[float], hi: Sequence[float]) -> list[tuple[float, float]]:
    """The corners of the axis-aligned rectangle [lo, hi] (m), counter-clockwise."""
    (x0, y0), (x1, y1) = lo, hi
    return [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]


def density_speed(traj: Trajectories, area: Sequence[tuple[float, float]],
                  walkable: Sequence[tuple[float, float]], frame_step: int,
                  since_s: float = 0.0,
                  obstacles: Sequence[Sequence[tuple[float, float]]] = ()) -> dict[str, float]:
    """Mean classic and Voronoi density (1/m^2) and mean and Voronoi speed (m/s) in the
    measurement ``area`` (a polygon, m) of the ``walkable`` polygon less the ``obstacles``
    polygons, by PedPy, over the frames at or after ``since_s``
    seconds; speeds from positions ``frame_step`` frames either side (PedPy's
    ``compute_individual_speed``; one-sided at the first and last frames of an agent)."""
    import pedpy

    data = traj.to_pedpy()
    ma = pedpy.MeasurementArea(list(area))
    wa = pedpy.WalkableArea(list(walkable), obstacles=[list(o) for o in obstacles])
    first = int(math.ceil(since_s * traj.frame_rate))
    classic = pedpy.compute_classic_density(traj_data=data, measurement_area=ma)
    polygons = pedpy.compute_individual_voronoi_polygons(traj_data=data, walkable_area=wa)
    voronoi, intersecting = pedpy.compute_voronoi_density(individual_voronoi_data=polygons,
                                                          measurement_area=ma)
    speed = pedpy.compute_individual_speed(
        traj_data=data, frame_step=frame_step,
        speed_calculation=pedpy.SpeedCalculation.BORDER_SINGLE_SIDED)
    mean_speed = pedpy.compute_mean_speed_per_frame(traj_data=data, individual_speed=speed,
                                                    measurement_area=ma)
    v_speed = pedpy.compute_voronoi_speed(traj_data=data, individual_speed=speed,
                                          individual_voronoi_intersection=intersecting,
                                          measurement_area=ma)

    def mean(frame: Any, column: str) -> float:
        kept = frame[frame.index >= first][column] if len(frame) else frame
        return float(kept.mean()) if len(kept) else math.nan

    return {"classic_density": mean(classic, "density"),
            "voronoi_density": mean(voronoi, "density"),
            "mean_speed": mean(mean_speed, "speed"),
            "voronoi_speed": mean(v_speed, "speed")}


def classic_density(traj: Trajectories, area: Sequence[tuple[float, float]]) -> np.ndarray:
    """PedPy's classic density (1/m^2) in the measurement ``area`` (a polygon, m), one value
    per frame from the first to the last recorded (frames without agents in it: 0)."""
    import pedpy

    if not len(traj.frames):
        return np.zeros(0)
    frame = pedpy.compute_classic_density(traj_data=traj.to_pedpy(),
                                          measurement_area=pedpy.MeasurementArea(list(area)))
    return np.asarray(frame["density"], dtype=np.float64)


def line_flow(traj: Trajectories, line: Sequence[tuple[float, float]]) -> dict[str, float]:
    """Crossings of a measurement ``line`` (two points, m) by PedPy's ``compute_n_t``: the
    number of agents that crossed, the first and last crossing times (s) and the mean flow
    (crossings - 1) / (last - first) (1/s; NaN with fewer than two crossings)."""
    import pedpy

    nt, crossing = pedpy.compute_n_t(traj_data=traj.to_pedpy(),
                                     measurement_line=pedpy.MeasurementLine(list(line)))
    frames = np.sort(np.asarray(crossing["frame"], dtype=np.float64))
    n = len(frames)
    if n == 0:
        return {"crossed": 0, "first_s": math.nan, "last_s": math.nan, "flow": math.nan}
    first, last = frames[0] / traj.frame_rate, frames[-1] / traj.frame_rate
    flow = (n - 1) / (last - first) if n > 1 and last > first else math.nan
    return {"crossed": n, "first_s": first, "last_s": last, "flow": flow}


def check_pedpy() -> None:
    """Raise a SweepError saying how to install PedPy when it is missing."""
    try:
        import pedpy  # noqa: F401
    except ImportError as err:
        raise SweepError("PedPy is not installed (fix: pip install pedpy==1.5.1)") from err
