"""Trajectories for PedPy, the Jülich group's pedestrian analysis package: a recording (or
arrays) as a ``pedpy.TrajectoryData``, its text export, and PedPy's own measurements (classic
and Voronoi density, speed, flow at a line, fundamental diagram) called on it.

Frames: PedPy needs one frame rate, so frame k is the time k P (s) with P the frame period.
P is dt record_every when the recording says record_every (``sweep run``), else dt times the
most common number of steps between recorded states (the node records once per tick, and a
tick may hold more or fewer steps: one cut short by ``initialpose``, several under
``real_time_factor``). Times come from the recorded stamps, never from a count of messages.
When every recorded state lies on that grid, one after the other, the frames are the
recorded states themselves. Otherwise each agent's centre is interpolated linearly in time
between its two recorded states either side of k P, for the k P between its first and last
recorded state (an agent is never extended before it entered or after it left); a frame on
a recorded time takes that state exactly. :attr:`Trajectories.resampling` says how many
frames were interpolated and the recorded step gaps. A linear interpolation is exact for a
straight walk at constant velocity; over a gap of G steps it replaces the path by its chord,
so a speed measured by PedPy over a window of W frames is off by at most the path's turning
within the gaps at the window's two ends.

Ids: the ``id`` column of ``/agents`` (agents keep their id when others leave or enter); a
recording without ``/agents`` numbers the agents of each frame 0 .. N - 1. Coordinates in
metres.

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
    """Every agent's positions, one row per agent and frame: ``ids`` (M,) int, ``frames``
    (M,) int, ``xy`` (M, 2) m, and ``frame_rate`` (frames per second); frame k is the time
    k / frame_rate (s). ``resampling``: how the frames were made from uneven recorded states
    ("" when they are the recorded states); ``cut``: where a recording cut short ends (""
    when it is whole); ``damaged``: the first chunk of the recording that could not be read
    and was skipped ("" when none was); ``recovered``: where the states of ``sweep
    recover``'s copy of a recording cut short or damaged end ("" for any other recording)."""

    ids: np.ndarray
    frames: np.ndarray
    xy: np.ndarray
    frame_rate: float
    resampling: str = ""
    cut: str = ""
    damaged: str = ""
    recovered: str = ""

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


#: stamps this close (ns) are one time: a frame there is the recorded state
SAME_NS = 1000


def _mode(gaps: np.ndarray) -> int:
    """The most common gap (steps); of several equally common, the largest."""
    values, counts = np.unique(gaps, return_counts=True)
    return int(values[counts == counts.max()].max())


def even_frames(stamps_ns: Sequence[int], ids: Sequence[np.ndarray], xy: Sequence[np.ndarray],
                dt: float, record_every: int | None) -> Trajectories:
    """Recorded states (stamp (ns), ids (N,), centres (N, 2) m each, in any order; a stamp
    recorded twice keeps its last state) on frames of one period (module docstring).

    Raises:
        RecordingError: no state.
    """
    if not len(stamps_ns):
        raise RecordingError("no recorded state")
    order = np.argsort(np.asarray(stamps_ns, dtype=np.int64), kind="stable")
    t_all = np.asarray(stamps_ns, dtype=np.int64)[order]
    last = np.append(t_all[1:] != t_all[:-1], True)  # the last state of each stamp
    keep = order[last]
    t = t_all[last].astype(np.float64)
    steps = np.rint(t / (dt * NS)).astype(np.int64)
    gaps = np.diff(steps)
    g = int(record_every) if record_every else (_mode(gaps[gaps > 0]) if np.any(gaps > 0)
                                                 else 1)
    period = g * dt * NS  # ns
    rate = 1.0 / (g * dt)
    on_grid = np.all(np.abs(t - steps * dt * NS) <= SAME_NS) and np.all(steps % g == 0)
    if on_grid and np.all(gaps == g):  # the recorded states are the frames
        return Trajectories.from_frames(
            [(int(s) // g, ids[k], xy[k]) for s, k in zip(steps, keep)], rate)
    row_t = np.concatenate([np.full(len(ids[k]), t[j]) for j, k in enumerate(keep)])
    row_id = np.concatenate([np.asarray(ids[k], np.int64) for k in keep])
    row_xy = np.concatenate([np.asarray(xy[k], np.float64).reshape(-1, 2) for k in keep])
    by = np.lexsort((row_t, row_id))
    row_t, row_id, row_xy = row_t[by], row_id[by], row_xy[by]
    starts = np.flatnonzero(np.append(True, row_id[1:] != row_id[:-1]))
    ends = np.append(starts[1:], len(row_id))
    out_id, out_frame, out_xy = [], [], []
    for a, b in zip(starts, ends):  # one agent's recorded states, in time order
        tk, qk = row_t[a:b], row_xy[a:b]
        k = np.arange(math.ceil((tk[0] - SAME_NS) / period),
                      math.floor((tk[-1] + SAME_NS) / period) + 1, dtype=np.int64)
        at = k * period
        out_id.append(np.full(len(k), row_id[a]))
        out_frame.append(k)
        out_xy.append(np.column_stack([np.interp(at, tk, qk[:, 0]),
                                       np.interp(at, tk, qk[:, 1])]))
    frames = np.concatenate(out_frame)
    made = np.unique(frames)
    nearest = np.searchsorted(t, made * period).clip(1, len(t) - 1)
    exact = np.minimum(np.abs(t[nearest] - made * period),
                       np.abs(t[nearest - 1] - made * period)) <= SAME_NS
    lo, hi = (int(gaps.min()), int(gaps.max())) if len(gaps) else (0, 0)
    note = (f"{int((~exact).sum())} of {len(made)} frames interpolated linearly in time "
            f"between recorded states (frame period {g} steps of dt = {dt:g} s; recorded "
            f"states {lo}-{hi} steps apart)")
    return Trajectories(np.concatenate(out_id), frames, np.concatenate(out_xy), rate, note)


def read_trajectories(path: str | os.PathLike[str]) -> Trajectories:
    """The trajectories of a recording on frames of one period (module docstring). A file
    cut short is read up to its last complete chunk, said in ``cut``; a chunk that cannot be
    read (its CRC does not match, it cannot be decompressed) is skipped, said in ``damaged``.

    Raises:
        RecordingError: not a recording of ``sweep run`` or the node, no dt in it, resets,
            a state without ids where agents come and go, or no recorded state.
    """
    meta = load_run(path)
    if meta.resets:
        raise RecordingError(f"{path}: has {len(meta.resets)} resets; a trajectory for PedPy "
                             "is one run (fix: export a recording without resets)")
    if meta.dt is None:
        raise RecordingError(f"{path}: its metadata give no time step dt, so its states "
                             "cannot be put on PedPy's frames (fix: export a recording of "
                             "sweep run or the node)")
    stamps: list[int] = []
    ids: list[np.ndarray] = []
    xy: list[np.ndarray] = []
    flows = meta.changes_population
    reader = FrameReader(meta)
    for fr in reader:
        known = fr.agents is not None and "id" in fr.agents and len(fr.agents["id"]) == \
            len(fr.positions)
        if not known and flows:
            raise RecordingError(f"{path}: the state at t = {fr.stamp_ns / NS:g} s has no "
                                 "readable /agents ids, which a scene whose agents enter and "
                                 "leave needs (numbering them 0 .. N - 1 would mix agents up) "
                                 "(fix: record /agents, as sweep run does)")
        stamps.append(fr.stamp_ns)
        ids.append(np.rint(fr.agents["id"]).astype(np.int64) if known and fr.agents is not None
                   else np.arange(len(fr.positions)))
        xy.append(fr.positions)
    if not stamps:
        why = reader.none_read() or " (no readable /poses message)"
        raise RecordingError(f"{path}: holds no recorded state{why}, so it has no frame to "
                             "export (fix: export a recording of at least one recorded step)")
    traj = even_frames(stamps, ids, xy, meta.dt, meta.record_every)
    if reader.skipped_chunks:
        traj.damaged = reader.skipped_chunks[0]
    if reader.truncated:
        traj.cut = (f"cut short: read up to its last complete chunk (t = "
                    f"{max(stamps) / NS:g} s)")
    if meta.recovered_short:
        traj.recovered = (f"recovered from a recording cut short or damaged: its states end "
                          f"at t = {max(stamps) / NS:g} s, before the run did")
    return traj


def write_pedpy_txt(traj: Trajectories, out: str | os.PathLike[str],
                    inputs: Sequence[str | os.PathLike[str]] = ()) -> Path:
    """PedPy's text format (``pedpy.load_trajectory_from_txt`` reads it): a commented header
    with the frame rate, how the frames were made (when resampled) and the unit, then one line
    ``id frame x y z`` per agent and frame."""
    order = np.lexsort((traj.frames, traj.ids))
    made = f"# frames: {traj.resampling}\n" if traj.resampling else ""
    made += f"# note: {traj.recovered}\n" if traj.recovered else ""
    header = (f"# sweep_ros trajectories for PedPy\n# framerate: {traj.frame_rate:.10g}\n"
              f"{made}# x/m y/m z/m\n# id frame x y z\n")
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
