"""Metrics of a recorded run (``sweep analyze``), read from its MCAP file alone.

A recording (from ``sweep run`` or the ROS node) holds, per recorded step, ``/poses``
(PoseArray, float64 centres) and ``/agents`` (PointCloud2, float32 id, x, y, radius, vx, vy,
reaction_x, reaction_y), stamped with simulation time, and a metadata record ``sweep_ros``
(scene YAML, seed, dt, scheme, solver, versions; the node adds ``command_*``, ``reset_*`` and
``parameter_*`` records). :func:`load_run` reads the metadata, :class:`FrameReader` the
frames (one per recorded step), :func:`analyze` the metrics.

Precision of each metric:

* minimum gap, touching (true constraints with gap <= CONTACT_TOL: agent pairs, agent-wall
  and agent-obstacle; not ``sweep run``'s active_rows, the rows of the linearised set that hold
  with equality after a step's projection), flow through a line, arrival times, density map: from ``/poses``
  (float64, the engine's own numbers) with radii r_i(t) evaluated from the recorded scene in
  float64, so the minimum gap is the engine's ``State.min_gap`` bit for bit;
* speeds: from ``/poses`` (float64), each agent's displacement over a window centred on the
  frame (:mod:`sweep_core.analysis.speed`; ``speed.window_s`` in the summary), on the recorded
  simulation times;
* reaction (contact pressure): from ``/agents`` (float32, relative error about 6e-8).

Time is the log time of the messages (equal to simulation time for ``sweep run``; the node
keeps it increasing over resets). A file cut short (SIGKILL) is read up to its last complete
chunk and reported as truncated.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sweep_core.analysis.arrivals import ArrivalTracker, arrive_radius_for, start_exits, stats
from sweep_core.analysis.crowd import FundamentalDiagram, Tracks
from sweep_core.analysis.density import MAX_CELLS as MAX_CELLS  # re-exported for the CLI
from sweep_core.analysis.density import Hist2D
from sweep_core.analysis.frames import Frame, FrameReader, GapFinder, progress_bar
from sweep_core.analysis.lines import flow_summary, line_outside_sinks
from sweep_core.analysis.lines import line_crossings as line_crossings  # re-exported
from sweep_core.analysis.lines import parse_line as parse_line  # re-exported for the CLI
from sweep_core.analysis.robots import for_run as robot_metrics
from sweep_core.analysis.roster import Roster, grow
from sweep_core.analysis.run import NS, RunMeta, Schedule, load_run, scene_with_map
from sweep_core.analysis.speed import (
    DEFAULT_WINDOW_S,
    Ready,
    SpeedStats,
    WindowSpeeds,
    check_window,
    choose_window,
    fits,
)
from sweep_core.analysis.speed import SPEED_BIN as SPEED_BIN  # re-exported
from sweep_core.errors import RecordingError, SweepError
from sweep_core.model.gaps import gaps, smallest_gap
from sweep_core.model.geometry import Geometry

#: a constraint whose true value is at most this (m) counts as an active contact
CONTACT_TOL = 1e-6

@dataclass
class Analysis:
    """Result of :func:`analyze`: ``summary`` (JSON-ready), ``table`` (one row per frame,
    columns ``COLUMNS``), ``density`` (agents/m^2, rows along y) with its origin and cell,
    ``speed_hist`` (counts per SPEED_BIN), ``arrival`` and ``evacuation`` times per agent
    (s from the first frame, NaN if never)."""

    COLUMNS = ("t_s", "step", "min_gap_m", "touching", "reaction_total_m", "pressure_m_per_s",
               "speed_mean_m_per_s", "speed_max_m_per_s", "crossings_net", "arrived")

    meta: RunMeta
    summary: dict
    table: np.ndarray
    density: np.ndarray
    density_origin: tuple[float, float]
    cell: float
    speed_hist: np.ndarray
    arrival: np.ndarray
    evacuation: np.ndarray
    #: the exit each agent reached (its label, see :mod:`sweep_core.analysis.arrivals`), or
    #: None (not arrived, or not under an exits drift)
    arrival_exit: list[str | None] = field(default_factory=list)
    #: one line per skipped chunk or message and per gap (also in the summary as counts)
    problems: list[str] = field(default_factory=list)
    #: log time (ns) of the first frame: t = 0 of ``table``
    t0_ns: int = 0
    #: centres at up to crowd.TRACK_FRAMES frames (K, N, 2) m, and their times (K,) s
    tracks: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 2)))
    track_times: np.ndarray = field(default_factory=lambda: np.zeros(0))
    #: local density against speed, every agent of every frame with a speed
    fundamental: FundamentalDiagram | None = None
    #: the robots' frames (:attr:`SocialMetrics.COLUMNS`), None without robots
    robots: np.ndarray | None = None
    #: the window (s) of every speed (:mod:`sweep_core.analysis.speed`)
    speed_window: float = DEFAULT_WINDOW_S


def _finite(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


def _empty_geometry() -> Geometry:
    e2, e1, ei = np.zeros((0, 2)), np.zeros(0), np.zeros(0, dtype=np.intp)
    return Geometry(e2, e1, e1, e2, e2, e2, e1, ei, ei, ei)


class _Metrics:
    """Accumulates the metrics frame by frame (one pass, bounded memory per agent and cell)."""

    def __init__(self, meta: RunMeta, line: tuple[float, float, float, float] | None,
                 arrive_radius: float | None, cell: float, window: float) -> None:
        self.meta, self.line, self.arrive_radius = meta, line, arrive_radius
        self.window = window
        self.speeds = WindowSpeeds(window)
        self.stats = SpeedStats(window)
        self.crossing_times: list[float] = []  # every positive crossing of the line (s)
        self.schedule = Schedule(meta)
        self.geometry = meta.scene.geometry if meta.scene is not None else _empty_geometry()
        self.rows: list[tuple] = []
        self.density = Hist2D(cell)
        self.n: int | None = None
        self.t0 = 0
        self.worst: tuple[float, float, str] | None = None  # (gap, t, between)
        self.prev: tuple[int, np.ndarray] | None = None
        self.net, self.positive, self.negative = 0, 0, 0
        self.arrival = self.evacuation = np.zeros(0)
        self.goal_seen = False
        self.tracker = ArrivalTracker(0, arrive_radius)
        self._map_geometry: dict[int, Geometry] = {}
        self.tracks = Tracks(meta.frames)
        # agents who enter or leave (sources, sinks) are followed by id (roster.py); a speed
        # law, speeds or delays alone keep the scene's agents, row by row
        flows = meta.scene.flows if meta.scene is not None else None
        self.roster = (Roster(meta.scene, meta.path) if meta.scene is not None
                       and flows is not None and flows.changes_population else None)
        # journeys and exit choices send agents elsewhere than their drift's goal
        self.drift_goals = flows is None or not (flows.journeys or flows.exit_choices)
        self.sinks = flows is not None and bool(flows.sinks)
        self.ids = self.prev_ids = np.zeros(0, dtype=np.int64)

    def add(self, fr: Frame) -> list[Ready]:
        """One frame; returns the frames whose windowed velocities are now known (their
        payload: (frame index, Frame, segment, step))."""
        meta, q = self.meta, fr.positions
        if self.n is None:
            self.n, self.t0 = len(q), fr.log_ns
            self.evacuation = np.full(self.n, np.nan)
            if meta.scene is not None and meta.scene.n_agents != self.n:
                raise RecordingError(f"{meta.path}: {self.n} poses but the recorded scene has "
                                     f"{meta.scene.n_agents} agents")
            start = (start_exits(meta.scene.drift, meta.scene.positions)
                     if meta.scene is not None else {})
            self.tracker = ArrivalTracker(self.n, self.arrive_radius, start)
            self.arrival = self.tracker.arrival
        elif len(q) != self.n and self.roster is None:
            raise RecordingError(f"{meta.path}: frame at t = {fr.log_ns / NS:g} s has "
                                 f"{len(q)} poses, the first had {self.n}")
        t = (fr.log_ns - self.t0) / NS
        if self.roster is not None:
            self.ids = self.roster.ids(fr.agents, len(q), t)
            self.roster.add(self.ids, t)
        seg = meta.segment_of(fr.log_ns)
        step = meta.step_of(fr.stamp_ns) if meta.dt is not None else -1
        geometry = self._geometry_at(seg, step)
        g, smallest, pair = self._gaps(fr, step, geometry)
        react_total = self._reaction(fr.agents)
        if self.line is not None:
            self._flow(seg, q, t)
        if self.roster is None and self.drift_goals and self._arrivals(seg, step, q, t):
            self.goal_seen = True
        self.density.add(q)
        self.tracks.add(t, q, self.ids if self.roster is not None else None)
        dt = meta.dt
        ids = self.ids if self.roster is not None else np.arange(len(q))
        ready = self.speeds.push(fr.stamp_ns / NS, ids, q, (self.stats.frame(), fr, seg, step),
                                 seg)
        self.rows.append((t, step, smallest, g.contacts, react_total,
                          react_total / dt if dt else math.nan, math.nan, math.nan,
                          self.net if self.line is not None else math.nan,
                          self._arrived()))
        if math.isfinite(smallest) and (self.worst is None or smallest < self.worst[0]):
            if pair is not None:
                between = f"agents {pair[0]} and {pair[1]}"
            else:
                a, kind, item, _ = g.worst_single
                between = f"agent {a} and {geometry.describe(kind, item)}"
            self.worst = (smallest, t, between)
        self.stats.add(ready)
        return ready

    def _arrived(self) -> float:
        """Agents arrived by now: at their drift's goal, or (by id) those that left at sinks."""
        if self.roster is not None:
            return float(np.isfinite(self.roster.left_at).sum()) if self.sinks else math.nan
        return float(np.isfinite(self.arrival).sum()) if self.goal_seen else math.nan

    def finish(self) -> list[Ready]:
        """The frames still waiting for their windows (the recording ended)."""
        ready = self.speeds.finish()
        self.stats.add(ready)
        return ready

    def _geometry_at(self, seg: int, step: int) -> Geometry:
        """The walls a frame's state holds: the scene's, with the map the node received
        (``map_NNNNNN`` records) in effect at that step instead of the scene's own."""
        scene = self.meta.scene
        packed = self.schedule.map_at(seg, step) if scene is not None and step >= 0 else None
        if packed is None or scene is None:
            return self.geometry
        key = id(packed)
        if key not in self._map_geometry:
            self._map_geometry[key] = scene_with_map(scene, packed).geometry
        return self._map_geometry[key]

    def _gaps(self, fr: Frame, step: int, geometry: Geometry
              ) -> tuple[Any, float, tuple[int, int] | None]:
        """True constraint values (float64 poses and float64 radii r_i(t) from the scene):
        their :func:`gaps`, the smallest gap and the pair that gives it (None: a wall or
        obstacle, or nothing)."""
        scene, dt = self.meta.scene, self.meta.dt
        if scene is not None:
            t_sim = step * dt if dt is not None else fr.stamp_ns / NS
            r = (scene.radii(t_sim) if self.roster is None or fr.agents is None
                 else self.roster.radii(self.ids, fr.agents, t_sim))
            g = gaps(geometry, t_sim, fr.positions, r, CONTACT_TOL)
        else:  # no scene in the metadata: disks only, with the float32 radii of /agents
            r = (fr.agents["radius"].astype(np.float64) if fr.agents is not None
                 else np.zeros(len(fr.positions)))
            g = gaps(self.geometry, 0.0, fr.positions, r, CONTACT_TOL)
        return (g, *smallest_gap(g, fr.positions, r, CONTACT_TOL))

    @staticmethod
    def _reaction(ag: dict[str, np.ndarray] | None) -> float:
        """Total reaction of a frame (float32 /agents), NaN if unknown."""
        if ag is None:
            return math.nan
        return float(np.hypot(ag["reaction_x"].astype(np.float64),
                              ag["reaction_y"].astype(np.float64)).sum())

    def _flow(self, seg: int, q: np.ndarray, t: float) -> None:
        """Crossings of the line since the previous frame of the same segment (with flows:
        of the agents both frames hold, by id)."""
        if self.prev is not None and self.prev[0] == seg:
            p0, p1, who = self.prev[1], q, np.arange(len(q))
            if self.roster is not None:
                who, p0, p1 = Roster.common(self.prev_ids, p0, self.ids, q)
                self.evacuation = grow(self.evacuation, int(self.ids.max(initial=-1)) + 1)
            c = line_crossings(p0, p1, self.line)
            self.positive += int(np.count_nonzero(c > 0))
            self.negative += int(np.count_nonzero(c < 0))
            self.net += int(c.sum())
            first = who[(c > 0) & np.isnan(self.evacuation[who])]
            self.evacuation[first] = t
            self.crossing_times += [t] * int(np.count_nonzero(c > 0))
        self.prev = (seg, q)
        self.prev_ids = self.ids

    def _arrivals(self, seg: int, step: int, q: np.ndarray, t: float) -> bool:
        """Marks agents that reached the goal of their drift in effect (goal, geodesic,
        exits, or their group's: :mod:`sweep_core.analysis.arrivals`); False if none has
        one."""
        return self.tracker.add(self.schedule.spec_at(seg, step), q, t)

    def result(self, reader: FrameReader) -> Analysis:
        self.density.check()
        meta, cell = self.meta, self.density.cell
        table = np.array(self.rows, dtype=np.float64).reshape(-1, len(Analysis.COLUMNS))
        frames = len(table)
        if frames == 0:
            raise RecordingError(f"{meta.path}: no complete frame (poses) in the recording"
                                 + reader.none_read())
        table[:, 6:8] = self.stats.table()
        n, worst = self.n or 0, self.worst
        if self.roster is not None:  # every agent seen, the scene's and the entered
            n = self.roster.total
            self.evacuation = grow(self.evacuation, n)
        duration = float(table[-1, 0] - table[0, 0])
        dens = self.density.counts / (frames * cell * cell)
        origin = (self.density.ix0 * cell, self.density.iy0 * cell)
        touching = {
            "mean": float(np.mean(table[:, 3])),
            "max": int(np.max(table[:, 3])),
            "tolerance_m": CONTACT_TOL,
            "precision": "float64 (/poses): true constraints (agent pairs, agent-wall, "
                         "agent-obstacle) with gap <= tolerance in the recorded frame",
        }
        summary: dict[str, Any] = {
            "recording": meta.path,
            "status": meta.status,
            "truncated": bool(reader.truncated),
            "read_until": reader.error if reader.truncated else None,
            "scene": meta.scene.name if meta.scene is not None else None,
            "agents": n,
            "frames": frames,
            "duration_s": duration,
            "t_last_s": float(table[-1, 0]),
            "last_step": int(table[-1, 1]),
            "dt_s": meta.dt,
            "segments": len(meta.resets) + 1,
            "commands": len(meta.commands),
            "min_gap": {
                "min_m": _finite(worst[0]) if worst else None,
                "t_s": worst[1] if worst else None,
                "between": worst[2] if worst else None,
                "precision": "float64 (/poses, radii from the scene)" if meta.scene is not None
                             else "float64 centres, float32 radii (no scene in the metadata)",
            },
            "touching": touching,
            # the same numbers under their old name, kept for scripts that read it; "touching"
            # says what they are (sweep run's active_rows counts something else)
            "contacts": dict(touching),
            "reaction": {
                "total_mean_m": stats(table[:, 4], np.mean),
                "total_max_m": stats(table[:, 4], np.max),
                "pressure_mean_m_per_s": stats(table[:, 5], np.mean),
                "precision": "float32 (/agents): sum over agents of |prediction - result|; "
                             "pressure = that / dt",
            },
            "speed": self.stats.summary(),
            "flow": None,
            "arrivals": None,
            "per_exit": None,
            "per_group": None,
            "density": {
                "cell_m": cell,
                "max_per_m2": float(dens.max()) if dens.size else 0.0,
                "x0_m": origin[0], "y0_m": origin[1],
                "shape": list(dens.shape),
                "precision": "float64 (/poses): time-averaged centres per m^2",
            },
        }
        if self.line is not None:
            summary["flow"] = flow_summary(self.line, (self.net, self.positive, self.negative),
                                           np.array(self.crossing_times), self.evacuation, n)
        if self.goal_seen:
            summary["arrivals"] = self.tracker.summary(n)
            summary["per_exit"] = self.tracker.per_exit()
            summary["per_group"] = self.tracker.per_group()
            for name, idx in self.tracker.groups.items():
                if summary["per_group"] is not None and name in summary["per_group"]:
                    summary["per_group"][name]["speed_mean_m_per_s"] = self.stats.group_mean(idx)
                    summary["per_group"][name]["speed_window_s"] = self.window
        labels = self.tracker.labels
        exits = [labels[k] if k >= 0 else None for k in self.tracker.exit.tolist()]
        arrival = self.arrival
        if self.roster is not None:  # by id: an arrival is leaving at a sink
            arrival = self.roster.report(summary)
            exits = [None] * len(arrival)
        return Analysis(meta, summary, table, dens, origin, cell, self.stats.hist, arrival,
                        self.evacuation, exits, t0_ns=self.t0, tracks=self.tracks.array(),
                        track_times=np.array(self.tracks.times),
                        fundamental=self.stats.fundamental.result(), speed_window=self.window)


def analyze(path: str | Path, line: tuple[float, float, float, float] | None = None,
            arrive_radius: float | None = None, cell: float = 0.5,
            progress: bool = False, goal_radius: float | None = None,
            time_limit: float | None = None, speed_window: float | None = None) -> Analysis:
    """Reads a recording and computes every metric (see the module docstring).

    Args:
        line: counting line x0, y0, x1, y1 (m): flow through it (net agents crossing in the
            positive direction, see :func:`line_crossings`) and evacuation time per agent (its
            first positive crossing, at the time of the first frame past the line).
        arrive_radius: an agent has arrived when its centre is within this distance (m) of
            the goal in effect (goal scenes and goal commands); default: the goal's
            slow_radius; refused with sinks, sources, journeys or exit choices.
        cell: side of the density map cells (m).
        progress: a progress bar on stderr (shown on a terminal only).
        goal_radius, time_limit: a robot has reached its goal within this distance (m; default
            the scene's), within this time (s from the first frame; default the scene's, else
            the whole recording): docs/social_metrics.md.
        speed_window: the window (s) of every speed (:mod:`sweep_core.analysis.speed`);
            default :data:`~sweep_core.analysis.speed.DEFAULT_WINDOW_S`, widened to two
            recorded frame intervals when the frames lie further apart. A given window
            longer than the recording or shorter than two frame intervals is refused.
    """
    if isinstance(cell, bool) or not isinstance(cell, (int, float)) or not (
            cell > 0 and math.isfinite(cell)):
        raise SweepError(f"--cell: must be a positive number of metres, got {cell!r}")
    given = speed_window is not None
    if given:
        check_window(speed_window)
    meta = load_run(path)
    window = choose_window(speed_window, meta.frame_interval)
    metrics = _Metrics(meta, line_outside_sinks(line, meta.scene),
                       arrive_radius_for(arrive_radius, meta.scene), float(cell), window)
    robots = robot_metrics(meta, goal_radius, time_limit)
    reader, finder = FrameReader(meta), GapFinder(meta.record_every)
    with progress_bar(meta.frames or None, "frame", progress) as bar:
        for fr in reader:
            ready = metrics.add(fr)
            finder.add(fr, meta.segment_of(fr.log_ns), int(metrics.rows[-1][1]))
            if robots is not None:
                for r in ready:  # people's velocities over the window, once it is complete
                    robots.add(r.payload[1], r.payload[2], r.payload[3], r.v)
            bar.update()
    for r in metrics.finish():
        if robots is not None:
            robots.add(r.payload[1], r.payload[2], r.payload[3], r.v)
    note = fits(window, np.array([row[0] for row in metrics.rows]), given=given) if metrics.rows else None
    an = metrics.result(reader)
    an.summary["speed"].update({"note": note} if note else {})
    if robots is not None:
        an.summary["robots"], an.robots = robots.summary(), robots.table()
        for entry in an.summary["robots"].values():
            if entry is not None:  # the people's velocities in ttc: over the speed window
                entry["people_velocity_window_s"] = window
    # states the file lacks (gaps) or holds unreadably (skipped), each listed on stderr
    an.summary["gaps"] = finder.to_dict()
    an.summary["skipped_messages"] = reader.bad
    an.problems = reader.problems + finder.lines(meta.path)
    if robots is not None:
        an.problems += robots.problems
    return an
