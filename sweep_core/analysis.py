"""Metrics of a recorded run (``sweep analyze``), read from its MCAP file alone.

A recording (from ``sweep run`` or the ROS node) holds, per recorded step, ``/poses``
(PoseArray, float64 centres) and ``/agents`` (PointCloud2, float32 id, x, y, radius, vx, vy,
reaction_x, reaction_y), stamped with simulation time, and a metadata record ``sweep_ros``
(scene YAML, seed, dt, scheme, solver, versions; the node adds ``command_*``, ``reset_*`` and
``parameter_*`` records). :func:`load_run` reads the metadata, :class:`FrameReader` the
frames (one per recorded step), :func:`analyze` the metrics.

Precision of each metric:

* minimum gap, contacts, flow through a line, arrival times, density map: from ``/poses``
  (float64, the engine's own numbers) with radii r_i(t) evaluated from the recorded scene in
  float64, so the minimum gap is the engine's ``State.min_gap`` bit for bit;
* speeds and reaction (contact pressure): from ``/agents`` (float32, relative error about 6e-8).

Time is the log time of the messages (equal to simulation time for ``sweep run``; the node
keeps it increasing over resets). A file cut short (SIGKILL) is read up to its last complete
chunk and reported as truncated.
"""
from __future__ import annotations

import bisect
import csv
import json
import math
import re
from dataclasses import dataclass, field, fields as dc_fields
from pathlib import Path
from typing import Any, Iterator

import numpy as np
import yaml

from . import cdr
from .constraints import Geometry, gaps
from .errors import RecordingError, SweepError
from .projection import SolverOptions
from .recording import ChannelInfo, read_recording, scan_recording
from .scene import Scene

#: a constraint whose true value is at most this (m) counts as an active contact
CONTACT_TOL = 1e-6
#: width of the speed histogram bins (m/s); speed quantiles are exact to half of it
SPEED_BIN = 1e-3
NS = 1_000_000_000


# ---------------------------------------------------------------------------------------------
# Metadata
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Command:
    """A velocity-field command as the node records it (metadata ``command_NNNNNN``): the
    drift ``spec`` (``Field.to_spec()``) replaces the drift before step ``step`` -> step + 1
    of segment ``segment`` (a segment is the run between two resets)."""

    index: int
    topic: str
    step: int
    log_time_ns: int
    spec: dict
    segment: int


@dataclass(frozen=True)
class ParameterChange:
    """A live parameter change recorded by the node (metadata ``parameter_NNNNNN``: keys
    ``name``, ``value`` (JSON), ``step``, ``log_time_ns``); in effect from step ``step`` on."""

    index: int
    name: str
    value: Any
    step: int
    log_time_ns: int
    segment: int


@dataclass
class RunMeta:
    """What a recording says about its run (None where it does not say)."""

    path: str
    raw: dict[str, str]
    scene: Scene | None
    dt: float | None
    seed: int | None
    scheme: str
    solver: dict
    t_end: float | None
    record_every: int | None
    path_dt: float | None
    versions: dict
    parameters: dict
    commands: list[Command]
    parameter_changes: list[ParameterChange]
    resets: list[int]
    poses_topic: str
    agents_topic: str | None
    frames: int
    truncated: bool
    error: str | None
    problems: list[str] = field(default_factory=list)

    @property
    def dt_ns(self) -> int | None:
        return None if self.dt is None else int(round(self.dt * NS))

    def segment_of(self, log_ns: int) -> int:
        """0 before the first reset, k after the k-th."""
        return bisect.bisect_right(self.resets, log_ns)

    def step_of(self, stamp_ns: int) -> int:
        """The step of a state stamped stamp_ns (simulation time)."""
        if self.dt is None:
            raise RecordingError(f"{self.path}: no dt in the metadata, steps are unknown")
        return int(round(stamp_ns / (self.dt * NS)))

    def commands_in(self, segment: int) -> list[Command]:
        return [c for c in self.commands if c.segment == segment]

    def solver_options(self) -> SolverOptions:
        names = {f.name for f in dc_fields(SolverOptions)}
        unknown = sorted(set(self.solver) - names)
        if unknown:
            raise RecordingError(f"{self.path}: solver settings {unknown} are unknown to this "
                                 "version of sweep_core (fix: replay with the version that "
                                 "recorded it, see its versions metadata)")
        return SolverOptions(**self.solver)


def _number(raw: dict[str, str], key: str, cast: type, problems: list[str]) -> Any:
    text = raw.get(key, "")
    if text == "":
        return None
    try:
        return cast(text)
    except ValueError:
        problems.append(f"metadata {key}={text!r} is not a {cast.__name__}")
        return None


def _json(text: str | None, what: str, problems: list[str]) -> Any:
    if not text:
        return None
    try:
        return json.loads(text)
    except ValueError:
        problems.append(f"metadata {what} is not JSON")
        return None


def _indexed(metadata: dict[str, dict[str, str]], prefix: str) -> list[tuple[int, dict]]:
    pat = re.compile(rf"^{prefix}_(\d+)$")
    out = [(int(m.group(1)), rec) for name, rec in metadata.items() if (m := pat.match(name))]
    return sorted(out, key=lambda x: x[0])


def _pick_topic(channels: dict[str, ChannelInfo], default: str, msgtype: str,
                declared: dict | None) -> str | None:
    if default in channels:
        return default
    suffix = default  # e.g. "/poses": a namespaced node records "/crowd/poses"
    cands = [t for t, c in channels.items() if t.endswith(suffix) and c.msgtype == msgtype]
    if not cands and declared:
        cands = [t for t, m in declared.items() if t.endswith(suffix) and m == msgtype]
    return sorted(cands, key=len)[0] if cands else None


def load_run(path: str | Path) -> RunMeta:
    """Metadata, topics, frame count and truncation of a recording.

    Raises:
        RecordingError: not an MCAP file, or no PoseArray topic ``.../poses`` in it.
    """
    info = scan_recording(path)
    problems: list[str] = []
    raw = dict(info.metadata.get("sweep_ros", {}))
    scene = None
    if raw.get("scene"):
        try:
            scene = Scene.from_dict(yaml.safe_load(raw["scene"]) or {})
        except (SweepError, yaml.YAMLError) as err:
            problems.append(f"the recorded scene does not load: {err}")
    dt = _number(raw, "dt", float, problems)
    seed = _number(raw, "seed", int, problems)
    declared = _json(raw.get("topics"), "topics", problems)
    poses = _pick_topic(info.channels, "/poses", cdr.POSE_ARRAY, declared)
    if poses is None:
        raise RecordingError(f"{info.path}: no geometry_msgs/msg/PoseArray topic '/poses' "
                             f"(topics: {sorted(info.channels)}) (fix: analyse a recording "
                             "made by sweep run or sweep_node)")
    agents = _pick_topic(info.channels, "/agents", cdr.POINT_CLOUD2, declared)
    resets = sorted(int(rec.get("log_time_ns", 0))
                    for _, rec in _indexed(info.metadata, "reset"))
    meta = RunMeta(
        path=info.path, raw=raw, scene=scene, dt=dt, seed=seed,
        scheme=raw.get("scheme", "projected_euler"),
        solver=_json(raw.get("solver"), "solver", problems) or {},
        t_end=_number(raw, "t_end", float, problems),
        record_every=_number(raw, "record_every", int, problems),
        path_dt=_number(raw, "path_dt", float, problems),
        versions=_json(raw.get("versions"), "versions", problems) or {},
        parameters=_json(raw.get("parameters"), "parameters", problems) or {},
        commands=[], parameter_changes=[], resets=resets, poses_topic=poses,
        agents_topic=agents,
        frames=info.channels[poses].message_count if poses in info.channels else 0,
        truncated=info.truncated, error=info.error, problems=problems)
    for k, rec in _indexed(info.metadata, "command"):
        spec = _json(rec.get("field"), f"command_{k:06d}.field", problems)
        try:
            step, log_ns = int(rec["step"]), int(rec["log_time_ns"])
        except (KeyError, ValueError):
            problems.append(f"metadata command_{k:06d} has no valid step / log_time_ns")
            continue
        if isinstance(spec, dict):
            meta.commands.append(Command(k, rec.get("topic", ""), step, log_ns, spec,
                                         meta.segment_of(log_ns)))
    for k, rec in _indexed(info.metadata, "parameter"):
        try:
            change = ParameterChange(k, rec["name"], json.loads(rec["value"]), int(rec["step"]),
                                     int(rec["log_time_ns"]), 0)
        except (KeyError, ValueError):
            problems.append(f"metadata parameter_{k:06d} is incomplete (name, value, step, "
                            "log_time_ns)")
            continue
        meta.parameter_changes.append(ParameterChange(
            change.index, change.name, change.value, change.step, change.log_time_ns,
            meta.segment_of(change.log_time_ns)))
    return meta


def require_replayable(meta: RunMeta) -> None:
    """Raise unless the metadata fully describes the run (scene, dt, seed, scheme, solver)."""
    missing = [k for k, v in (("scene", meta.scene), ("dt", meta.dt), ("seed", meta.seed))
               if v is None]
    if missing or meta.problems:
        why = ", ".join([f"no {m}" for m in missing] + meta.problems)
        raise RecordingError(f"{meta.path}: the metadata record 'sweep_ros' does not describe "
                             f"the run ({why}) (fix: use a recording made by sweep run or "
                             "sweep_node)")


class Schedule:
    """The drift spec in effect at (segment, step): the scene's, replaced by each command from
    its step on (a command with step k is in effect for the step k -> k + 1)."""

    def __init__(self, meta: RunMeta) -> None:
        base = meta.scene.drift.to_spec() if meta.scene is not None else {"kind": "none"}
        self._base = base
        self._by_segment: dict[int, tuple[list[int], list[dict]]] = {}
        for c in sorted(meta.commands, key=lambda c: (c.segment, c.step, c.index)):
            steps, specs = self._by_segment.setdefault(c.segment, ([], []))
            steps.append(c.step)
            specs.append(c.spec)

    def spec_at(self, segment: int, step: int) -> dict:
        steps, specs = self._by_segment.get(segment, ([], []))
        k = bisect.bisect_right(steps, step)
        return specs[k - 1] if k else self._base


# ---------------------------------------------------------------------------------------------
# Frames
# ---------------------------------------------------------------------------------------------


@dataclass
class Frame:
    """One recorded state: log time and stamp (ns), float64 centres (N, 2) and the float32
    ``/agents`` columns (None if that message is missing)."""

    log_ns: int
    stamp_ns: int
    positions: np.ndarray
    agents: dict[str, np.ndarray] | None


class FrameReader:
    """Iterates the frames of a recording in file order; after the iteration ``truncated``
    and ``error`` tell whether (and where) the file was cut short."""

    def __init__(self, meta: RunMeta, agents: bool = True) -> None:
        self.meta = meta
        self.want_agents = agents and meta.agents_topic is not None
        topics = [meta.poses_topic] + ([meta.agents_topic] if self.want_agents else [])
        self._reader = read_recording(meta.path, topics)
        self.truncated: bool | None = None
        self.error: str | None = None

    def __iter__(self) -> Iterator[Frame]:
        pending: dict[int, list] = {}
        poses_topic = self.meta.poses_topic
        try:
            for msg in self._reader:
                slot = pending.setdefault(msg.log_time_ns, [None, None])
                if msg.topic == poses_topic:
                    stamp, _, q = cdr.decode_pose_array(msg.data)
                    slot[0] = (stamp, q)
                else:
                    slot[1] = cdr.decode_point_cloud2(msg.data).fields
                if slot[0] is not None and (slot[1] is not None or not self.want_agents):
                    for key in sorted(k for k in pending if k <= msg.log_time_ns):
                        done = pending.pop(key)
                        if done[0] is not None:
                            yield Frame(key, done[0][0], done[0][1], done[1])
            for key in sorted(pending):
                done = pending[key]
                if done[0] is not None:
                    yield Frame(key, done[0][0], done[0][1], done[1])
        finally:
            self._reader.close()
            self.truncated = self._reader.truncated
            self.error = self._reader.error


def progress_bar(total: int | None, unit: str, enabled: bool) -> Any:
    """A tqdm bar on stderr (only on a terminal), or a no-op."""
    from tqdm import tqdm
    return tqdm(total=total, unit=unit, dynamic_ncols=True, disable=None if enabled else True,
                leave=False)


# ---------------------------------------------------------------------------------------------
# Metrics
# ---------------------------------------------------------------------------------------------


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


class _Hist2D:
    """Counts of points per square cell, on a grid that grows as needed."""

    def __init__(self, cell: float) -> None:
        self.cell = cell
        self.counts = np.zeros((0, 0), dtype=np.int64)
        self.ix0 = self.iy0 = 0

    def add(self, q: np.ndarray) -> None:
        if not len(q):
            return
        ix = np.floor(q[:, 0] / self.cell).astype(np.int64)
        iy = np.floor(q[:, 1] / self.cell).astype(np.int64)
        h, w = self.counts.shape
        if self.counts.size == 0:
            self.ix0, self.iy0 = int(ix.min()), int(iy.min())
        lo_x, lo_y = min(self.ix0, int(ix.min())), min(self.iy0, int(iy.min()))
        hi_x, hi_y = max(self.ix0 + w, int(ix.max()) + 1), max(self.iy0 + h, int(iy.max()) + 1)
        if (lo_x, lo_y, hi_x - lo_x, hi_y - lo_y) != (self.ix0, self.iy0, w, h):
            grown = np.zeros((hi_y - lo_y, hi_x - lo_x), dtype=np.int64)
            grown[self.iy0 - lo_y:self.iy0 - lo_y + h, self.ix0 - lo_x:self.ix0 - lo_x + w] = \
                self.counts
            self.counts, self.ix0, self.iy0 = grown, lo_x, lo_y
        np.add.at(self.counts, (iy - self.iy0, ix - self.ix0), 1)


@dataclass
class Analysis:
    """Result of :func:`analyze`: ``summary`` (JSON-ready), ``table`` (one row per frame,
    columns ``COLUMNS``), ``density`` (agents/m^2, rows along y) with its origin and cell,
    ``speed_hist`` (counts per SPEED_BIN), ``arrival`` and ``evacuation`` times per agent
    (s from the first frame, NaN if never)."""

    COLUMNS = ("t_s", "step", "min_gap_m", "contacts", "reaction_total_m", "pressure_m_per_s",
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


def _quantile(hist: np.ndarray, p: float) -> float | None:
    total = int(hist.sum())
    if total == 0:
        return None
    i = int(np.searchsorted(np.cumsum(hist), p * total))
    return (i + 0.5) * SPEED_BIN


def _time_for(times: np.ndarray, n_agents: int, fraction: float) -> float | None:
    """Time at which ceil(fraction N) agents have a finite time (None if never)."""
    need = max(1, math.ceil(fraction * n_agents - 1e-9))
    done = np.sort(times[np.isfinite(times)])
    return float(done[need - 1]) if len(done) >= need else None


def _finite(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


def _empty_geometry() -> Geometry:
    e2, e1, ei = np.zeros((0, 2)), np.zeros(0), np.zeros(0, dtype=np.intp)
    return Geometry(e2, e1, e1, e2, e2, e2, e1, ei, ei, ei)


def _stats(values: np.ndarray, how: Any) -> float | None:
    """how(values) over the finite values, or None if there are none."""
    ok = values[np.isfinite(values)]
    return float(how(ok)) if len(ok) else None


class _Metrics:
    """Accumulates the metrics frame by frame (one pass, bounded memory per agent and cell)."""

    def __init__(self, meta: RunMeta, line: tuple[float, float, float, float] | None,
                 arrive_radius: float | None, cell: float) -> None:
        self.meta, self.line, self.arrive_radius = meta, line, arrive_radius
        self.schedule = Schedule(meta)
        self.geometry = meta.scene.geometry if meta.scene is not None else _empty_geometry()
        self.rows: list[tuple] = []
        self.hist = np.zeros(0, dtype=np.int64)
        self.density = _Hist2D(cell)
        self.n: int | None = None
        self.t0 = 0
        self.worst: tuple[float, float, str] | None = None  # (gap, t, between)
        self.prev: tuple[int, np.ndarray] | None = None
        self.net, self.positive, self.negative = 0, 0, 0
        self.arrival = self.evacuation = np.zeros(0)
        self.speed_sum, self.speed_count, self.speed_max = 0.0, 0, 0.0
        self.goal_seen = False
        self.radii_used: set[float] = set()

    def add(self, fr: Frame) -> None:
        meta, q = self.meta, fr.positions
        if self.n is None:
            self.n, self.t0 = len(q), fr.log_ns
            self.arrival = np.full(self.n, np.nan)
            self.evacuation = np.full(self.n, np.nan)
            if meta.scene is not None and meta.scene.n_agents != self.n:
                raise RecordingError(f"{meta.path}: {self.n} poses but the recorded scene has "
                                     f"{meta.scene.n_agents} agents")
        elif len(q) != self.n:
            raise RecordingError(f"{meta.path}: frame at t = {fr.log_ns / NS:g} s has "
                                 f"{len(q)} poses, the first had {self.n}")
        t = (fr.log_ns - self.t0) / NS
        seg = meta.segment_of(fr.log_ns)
        step = meta.step_of(fr.stamp_ns) if meta.dt is not None else -1
        g = self._gaps(fr, step)
        react_total, sp_mean, sp_max = self._agents(fr.agents, step)
        if self.line is not None:
            self._flow(seg, q, t)
        if self._arrivals(seg, step, q, t):
            self.goal_seen = True
        self.density.add(q)
        dt = meta.dt
        self.rows.append((t, step, g.min_gap, g.contacts, react_total,
                          react_total / dt if dt else math.nan, sp_mean, sp_max,
                          self.net if self.line is not None else math.nan,
                          np.count_nonzero(np.isfinite(self.arrival)) if self.goal_seen
                          else math.nan))
        if math.isfinite(g.min_gap) and (self.worst is None or g.min_gap < self.worst[0]):
            if g.min_pair <= g.min_single:
                between = f"agents {g.worst_pair[0]} and {g.worst_pair[1]}"
            else:
                a, kind, item, _ = g.worst_single
                between = f"agent {a} and {self.geometry.describe(kind, item)}"
            self.worst = (g.min_gap, t, between)

    def _gaps(self, fr: Frame, step: int) -> Any:
        """True constraint values: float64 poses and float64 radii r_i(t) from the scene."""
        scene, dt = self.meta.scene, self.meta.dt
        if scene is not None:
            t_sim = step * dt if dt is not None else fr.stamp_ns / NS
            return gaps(scene.geometry, t_sim, fr.positions, scene.radii(t_sim), CONTACT_TOL)
        # no scene in the metadata: disks only, with the float32 radii of /agents
        r = (fr.agents["radius"].astype(np.float64) if fr.agents is not None
             else np.zeros(len(fr.positions)))
        return gaps(self.geometry, 0.0, fr.positions, r, CONTACT_TOL)

    def _agents(self, ag: dict[str, np.ndarray] | None, step: int) -> tuple[float, float, float]:
        """Total reaction, mean and max speed of a frame (float32 /agents), NaN if unknown."""
        if ag is None:
            return math.nan, math.nan, math.nan
        f64 = {k: ag[k].astype(np.float64) for k in ("reaction_x", "reaction_y", "vx", "vy")}
        react_total = float(np.hypot(f64["reaction_x"], f64["reaction_y"]).sum())
        if step == 0 or not self.n:  # no step taken yet: velocities are zero by definition
            return react_total, math.nan, math.nan
        v = np.hypot(f64["vx"], f64["vy"])
        self.speed_sum += float(v.sum())
        self.speed_count += len(v)
        self.speed_max = max(self.speed_max, float(v.max()))
        counts = np.bincount(np.floor(v / SPEED_BIN).astype(np.int64))
        if len(counts) > len(self.hist):
            self.hist = np.concatenate([self.hist,
                                        np.zeros(len(counts) - len(self.hist), np.int64)])
        self.hist[:len(counts)] += counts
        return react_total, float(v.mean()), float(v.max())

    def _flow(self, seg: int, q: np.ndarray, t: float) -> None:
        """Crossings of the line since the previous frame of the same segment."""
        if self.prev is not None and self.prev[0] == seg:
            c = line_crossings(self.prev[1], q, self.line)
            self.positive += int(np.count_nonzero(c > 0))
            self.negative += int(np.count_nonzero(c < 0))
            self.net += int(c.sum())
            self.evacuation[(c > 0) & np.isnan(self.evacuation)] = t
        self.prev = (seg, q)

    def _arrivals(self, seg: int, step: int, q: np.ndarray, t: float) -> bool:
        """Marks agents within the arrival radius of the goal in effect; False if no goal."""
        spec = self.schedule.spec_at(seg, step)
        if spec.get("kind") != "goal":
            return False
        radius = (self.arrive_radius if self.arrive_radius is not None
                  else float(spec.get("slow_radius", 0.5)))
        self.radii_used.add(radius)
        d = np.hypot(*(q - np.asarray(spec["goal"], dtype=np.float64)).T)
        self.arrival[(d <= radius) & np.isnan(self.arrival)] = t
        return True

    def result(self, reader: FrameReader) -> Analysis:
        meta, cell = self.meta, self.density.cell
        table = np.array(self.rows, dtype=np.float64).reshape(-1, len(Analysis.COLUMNS))
        frames = len(table)
        if frames == 0:
            raise RecordingError(f"{meta.path}: no complete frame (poses) in the recording"
                                 + (f" ({reader.error})" if reader.error else ""))
        n, worst = self.n or 0, self.worst
        duration = float(table[-1, 0] - table[0, 0])
        dens = self.density.counts / (frames * cell * cell)
        origin = (self.density.ix0 * cell, self.density.iy0 * cell)
        summary: dict[str, Any] = {
            "recording": meta.path,
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
            "contacts": {
                "mean": float(np.mean(table[:, 3])),
                "max": int(np.max(table[:, 3])),
                "tolerance_m": CONTACT_TOL,
                "precision": "float64 (/poses): constraints with gap <= tolerance",
            },
            "reaction": {
                "total_mean_m": _stats(table[:, 4], np.mean),
                "total_max_m": _stats(table[:, 4], np.max),
                "pressure_mean_m_per_s": _stats(table[:, 5], np.mean),
                "precision": "float32 (/agents): sum over agents of |prediction - result|; "
                             "pressure = that / dt",
            },
            "speed": {
                "mean_m_per_s": self.speed_sum / self.speed_count if self.speed_count else None,
                "max_m_per_s": self.speed_max if self.speed_count else None,
                "p10_m_per_s": _quantile(self.hist, 0.10),
                "p50_m_per_s": _quantile(self.hist, 0.50),
                "p90_m_per_s": _quantile(self.hist, 0.90),
                "samples": self.speed_count,
                "precision": f"float32 (/agents): |v| of each agent's last step, step 0 "
                             f"excluded; quantiles to {SPEED_BIN / 2:g} m/s",
            },
            "flow": None,
            "arrivals": None,
            "density": {
                "cell_m": cell,
                "max_per_m2": float(dens.max()) if dens.size else 0.0,
                "x0_m": origin[0], "y0_m": origin[1],
                "shape": list(dens.shape),
                "precision": "float64 (/poses): time-averaged centres per m^2",
            },
        }
        if self.line is not None:
            summary["flow"] = {
                "line": list(self.line),
                "net": self.net, "positive": self.positive, "negative": self.negative,
                "per_s": self.net / duration if duration > 0 else None,
                "evacuated": int(np.count_nonzero(np.isfinite(self.evacuation))),
                "t_first_s": _stats(self.evacuation, np.min),
                "t_50_s": _time_for(self.evacuation, n, 0.5),
                "t_90_s": _time_for(self.evacuation, n, 0.9),
                "t_all_s": _time_for(self.evacuation, n, 1.0),
                "precision": "float64 (/poses); crossings between recorded frames, positive "
                             "along (y1 - y0, x0 - x1)",
            }
        if self.goal_seen:
            radii = sorted(self.radii_used)
            summary["arrivals"] = {
                "radius_m": radii[0] if len(radii) == 1 else radii,
                "arrived": int(np.count_nonzero(np.isfinite(self.arrival))),
                "t_first_s": _stats(self.arrival, np.min),
                "t_mean_s": _stats(self.arrival, np.mean),
                "t_50_s": _time_for(self.arrival, n, 0.5),
                "t_90_s": _time_for(self.arrival, n, 0.9),
                "t_all_s": _time_for(self.arrival, n, 1.0),
                "precision": "float64 (/poses); first recorded frame within the radius of the "
                             "goal in effect (default radius: the goal's slow_radius)",
            }
        return Analysis(meta, summary, table, dens, origin, cell, self.hist, self.arrival,
                        self.evacuation)


def analyze(path: str | Path, line: tuple[float, float, float, float] | None = None,
            arrive_radius: float | None = None, cell: float = 0.5,
            progress: bool = False) -> Analysis:
    """Reads a recording and computes every metric (see the module docstring).

    Args:
        line: counting line x0, y0, x1, y1 (m): flow through it (net agents crossing in the
            positive direction, see :func:`line_crossings`) and evacuation time per agent (its
            first positive crossing, at the time of the first frame past the line).
        arrive_radius: an agent has arrived when its centre is within this distance (m) of
            the goal in effect (goal scenes and goal commands); default: the goal's
            slow_radius.
        cell: side of the density map cells (m).
        progress: a progress bar on stderr (shown on a terminal only).
    """
    if isinstance(cell, bool) or not isinstance(cell, (int, float)) or not (
            cell > 0 and math.isfinite(cell)):
        raise SweepError(f"--cell: must be a positive number of metres, got {cell!r}")
    if arrive_radius is not None and not (arrive_radius > 0 and math.isfinite(arrive_radius)):
        raise SweepError(f"--arrive-radius: must be a positive number of metres, "
                         f"got {arrive_radius!r}")
    meta = load_run(path)
    metrics = _Metrics(meta, line, arrive_radius, float(cell))
    reader = FrameReader(meta)
    with progress_bar(meta.frames or None, "frame", progress) as bar:
        for fr in reader:
            metrics.add(fr)
            bar.update()
    return metrics.result(reader)


# ---------------------------------------------------------------------------------------------
# Output
# ---------------------------------------------------------------------------------------------


def output_paths(recording: str | Path, suffix: str) -> dict[str, Path]:
    p = Path(recording)
    return {ext: p.with_name(f"{p.stem}{suffix}.{ext}") for ext in ("csv", "png")}


def _fmt(x: float) -> str:
    if isinstance(x, float) and not math.isfinite(x):
        return "" if math.isnan(x) else ("inf" if x > 0 else "-inf")
    if isinstance(x, float) and x == int(x) and abs(x) < 2**53:
        return str(int(x))
    return repr(float(x))


def write_table(path: Path, header: tuple[str, ...] | list[str], rows: np.ndarray) -> None:
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        for row in rows:
            w.writerow([_fmt(float(v)) for v in row])


def write_outputs(an: Analysis, plots: bool = True) -> dict[str, str]:
    """``RUN.analysis.csv`` (per frame), ``RUN.density.csv`` (x, y of each cell centre,
    agents/m^2), ``RUN.analysis.png``; returns their paths."""
    out = output_paths(an.meta.path, ".analysis")
    write_table(out["csv"], Analysis.COLUMNS, an.table)
    dens_path = output_paths(an.meta.path, ".density")["csv"]
    iy, ix = np.nonzero(an.density)
    cells = np.column_stack([an.density_origin[0] + (ix + 0.5) * an.cell,
                             an.density_origin[1] + (iy + 0.5) * an.cell, an.density[iy, ix]])
    write_table(dens_path, ("x_m", "y_m", "agents_per_m2"), cells)
    files = {"csv": str(out["csv"]), "density_csv": str(dens_path)}
    if plots:
        plot_analysis(an, out["png"])
        files["png"] = str(out["png"])
    return files


def _pyplot() -> Any:
    try:
        import matplotlib
    except ImportError as err:
        raise SweepError("matplotlib is not installed (fix: pip install matplotlib, or pass "
                         "--no-plots)") from err
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def draw_scene(ax: Any, scene: Scene | None) -> None:
    """Walls (segments) and circular obstacles of a scene on a matplotlib axis."""
    if scene is None:
        return
    from matplotlib.patches import Circle
    g = scene.geometry
    for a, b in zip(g.segment_a, g.segment_b):
        ax.plot([a[0], b[0]], [a[1], b[1]], color="k", lw=1.5)
    for c, r in zip(g.circle_center, g.circle_radius):
        ax.add_patch(Circle(c, r, fill=False, color="k", lw=1.0))


def plot_analysis(an: Analysis, png: Path) -> None:
    plt = _pyplot()
    tab, s = an.table, an.summary
    t = tab[:, 0]
    fig, axes = plt.subplots(2, 3, figsize=(12, 6.5), dpi=72)
    title = f"{s['scene'] or Path(an.meta.path).name}: {s['agents']} agents, {s['duration_s']:g} s"
    if s["truncated"]:
        title += " (truncated recording)"
    fig.suptitle(title)
    ax = axes[0, 0]
    gap = tab[:, 2]
    ax.plot(t, np.where(np.isfinite(gap), gap, np.nan), lw=1)
    ax.set_yscale("symlog", linthresh=1e-9)
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("minimum gap (m)")
    ax.set_title("minimum gap")
    ax = axes[0, 1]
    ax.plot(t, tab[:, 3], lw=1, color="C0")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("active contacts", color="C0")
    ax2 = ax.twinx()
    ax2.plot(t, tab[:, 5], lw=1, color="C3")
    ax2.set_ylabel("total reaction / dt (m/s)", color="C3")
    ax.set_title("contacts and pressure")
    ax = axes[0, 2]
    ax.plot(t, tab[:, 6], lw=1, label="mean")
    ax.plot(t, tab[:, 7], lw=0.8, alpha=0.6, label="max")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("speed (m/s)")
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title("speed over time")
    ax = axes[1, 0]
    h = an.speed_hist
    if h.sum():
        k = max(1, math.ceil(len(h) / 60))
        pad = np.concatenate([h, np.zeros(-len(h) % k, dtype=h.dtype)]).reshape(-1, k).sum(1)
        edges = np.arange(len(pad) + 1) * k * SPEED_BIN
        ax.stairs(pad / pad.sum(), edges, fill=True, alpha=0.7)
    ax.set_xlabel("speed (m/s)")
    ax.set_ylabel("fraction")
    ax.set_title("speed distribution")
    ax = axes[1, 1]
    drawn = False
    if s["flow"] is not None:
        ax.plot(t, tab[:, 8], lw=1.2, label="net crossings")
        drawn = True
    if s["arrivals"] is not None:
        ax.plot(t, tab[:, 9], lw=1.2, label="arrived")
        drawn = True
    if drawn:
        ax.legend(loc="upper left", fontsize=8)
    else:
        ax.text(0.5, 0.5, "no --line, no goal", ha="center", va="center",
                transform=ax.transAxes)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("agents")
    ax.set_title("flow and arrivals (cumulative)")
    ax = axes[1, 2]
    d = an.density
    x0, y0 = an.density_origin
    im = ax.imshow(np.ma.masked_equal(d, 0.0), origin="lower", cmap="viridis",
                   interpolation="nearest",
                   extent=(x0, x0 + d.shape[1] * an.cell, y0, y0 + d.shape[0] * an.cell))
    draw_scene(ax, an.meta.scene)
    if s["flow"] is not None:
        x_0, y_0, x_1, y_1 = s["flow"]["line"]
        ax.plot([x_0, x_1], [y_0, y_1], color="r", lw=1.5)
    fig.colorbar(im, ax=ax, label="agents / m²")
    ax.set_aspect("equal")
    ax.set_title("density (time average)")
    fig.tight_layout()
    fig.savefig(png)
    plt.close(fig)


def jsonable(obj: Any) -> Any:
    """inf / NaN -> None, numpy scalars -> Python, recursively."""
    if isinstance(obj, dict):
        return {k: jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, (np.floating, float)):
        return float(obj) if math.isfinite(obj) else None
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


def format_summary(summary: dict, skip: tuple[str, ...] = ("precision",)) -> str:
    """The summary as aligned ``key  value`` lines (nested keys joined with '.')."""
    flat: list[tuple[str, str]] = []

    def walk(prefix: str, obj: Any) -> None:
        if isinstance(obj, dict):
            for k, v in obj.items():
                if k not in skip:
                    walk(f"{prefix}.{k}" if prefix else k, v)
        elif obj is None:
            flat.append((prefix, "-"))
        elif isinstance(obj, float):
            flat.append((prefix, f"{obj:.6g}"))
        elif isinstance(obj, list):
            flat.append((prefix, ", ".join(f"{v:g}" if isinstance(v, float) else str(v)
                                           for v in obj)))
        else:
            flat.append((prefix, str(obj)))

    walk("", summary)
    width = max(len(k) for k, _ in flat)
    return "\n".join(f"{k:<{width}}  {v}" for k, v in flat)
