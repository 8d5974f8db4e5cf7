"""What a recording says about its run: the ``sweep_ros`` metadata record (scene, seed, dt,
scheme, solver) and the node's command, reset, parameter and map records (:func:`load_run`,
:class:`RunMeta`, :class:`Schedule`)."""
from __future__ import annotations

import bisect
import json
import os
import re
from dataclasses import dataclass, field
from dataclasses import fields as dc_fields
from pathlib import Path
from typing import Any

from sweep_core.errors import CostError, RecordingError, SweepError, show
from sweep_core.io import cdr
from sweep_core.io.metadata import RECOVER_RECORD, describe_status
from sweep_core.io.recording import ChannelInfo, RecordingReader, scan_recording
from sweep_core.model.maps import replace_map
from sweep_core.model.scene import Scene, scene_data
from sweep_core.model.speed_law import recorded_headway
from sweep_core.numerics.projection import SolverOptions

#: nanoseconds per second
NS = 1_000_000_000
#: values, keys, lists and mappings a recorded scene may hold besides what its agents need
#: (walls, obstacles, groups, flows, a packed map: a wall chain of 250 000 points is 750 000)
RECORDED_BASE_NODES = 1 << 20
#: and per agent of the recording's first state (a position is 3, its radius and speed 1
#: each): a scene is read within what the recording's own frames hold, not what it claims
RECORDED_NODES_PER_AGENT = 16


@dataclass(frozen=True)
class Command:
    """A velocity-field command as the node records it (metadata ``command_NNNNNN``): the
    drift ``spec`` (``Field.to_spec()``) replaces the drift before step ``step`` -> step + 1
    of segment ``segment`` (a segment is the run between two resets). ``topic`` says where it
    came from (``/crowd/cmd_vel``, ``/goal``, ...; ``/cmd_vel`` in older recordings); replay
    reads only ``spec``, so every name a node ever recorded replays alike."""

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


@dataclass(frozen=True)
class MapChange:
    """A map the node accepted from its map topic (metadata ``map_NNNNNN``: ``topic``,
    ``step``, ``log_time_ns``, ``map`` the packed map spec as JSON): the scene's walls are
    rebuilt with it (:func:`scene_with_map`) before step ``step`` -> step + 1 of segment
    ``segment``; it stays in effect over later resets, until the next map."""

    index: int
    topic: str
    step: int
    log_time_ns: int
    spec: dict
    segment: int


def scene_with_map(scene: Scene, spec: dict) -> Scene:
    """``scene`` with its map replaced by ``spec`` (the packed form), as the node builds it."""
    return Scene.from_dict(replace_map(scene.spec, spec), files=False)


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
    #: how the run ended (its ``sweep_status`` record), see :func:`describe_status`
    status: str = ""
    #: maps received by the node, in the order it accepted them
    maps: list[MapChange] = field(default_factory=list)
    #: robots placed by the node (initialpose; ``robot_pose_NNNNNN``): spec {robot, pose}
    robot_poses: list[MapChange] = field(default_factory=list)
    #: a copy that ``sweep recover`` made of a recording cut short or damaged (its last
    #: state may be cut from its /agents, as in the file it was recovered from)
    recovered_short: bool = False

    @property
    def dt_ns(self) -> int | None:
        return None if self.dt is None else int(round(self.dt * NS))

    @property
    def changes_population(self) -> bool:
        """Whether agents enter or leave in the recorded scene (sources or sinks): then a
        state's ids are only known from its /agents, not numbered 0 .. N - 1."""
        return (self.scene is not None and self.scene.flows is not None
                and self.scene.flows.changes_population)

    @property
    def frame_interval(self) -> float | None:
        """Seconds between recorded states, dt x record_every (None when the recording does
        not say both)."""
        return self.dt * self.record_every if self.dt and self.record_every else None

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
        # recordings made before the certified solver existed were projected by the cluster
        # solvers alone: replay them so
        return SolverOptions(**{"method": "clusters", **self.solver})


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
    except (ValueError, RecursionError):  # RecursionError: nested past the decoder's depth
        problems.append(f"metadata {what} is not JSON (or nested too deep)")
        return None


def _stepped(metadata: dict[str, dict[str, str]], prefix: str, key: str, problems: list[str]
             ) -> list[tuple[int, str, int, int, dict]]:
    """The node's records ``PREFIX_NNNNNN`` that apply a JSON spec (in ``key``) from a step:
    (index, topic, step, log_time_ns, spec) each, in index order; a record without a valid
    step, log time or spec is reported in ``problems`` and left out."""
    out = []
    for k, rec in _indexed(metadata, prefix):
        spec = _json(rec.get(key), f"{prefix}_{k:06d}.{key}", problems)
        try:
            step, log_ns = int(rec["step"]), int(rec["log_time_ns"])
        except (KeyError, ValueError):
            problems.append(f"metadata {prefix}_{k:06d} has no valid step / log_time_ns")
            continue
        if isinstance(spec, dict):
            out.append((k, rec.get("topic", ""), step, log_ns, spec))
    return out


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


def _first_count(path: str, topic: str | None) -> int:
    """The poses in the first message of ``topic`` (0 when there is none or it does not
    decode: its reader names the damage)."""
    if topic is None:
        return 0
    try:
        with RecordingReader(path, topics=[topic]) as reader:
            for message in reader:
                return len(cdr.decode_pose_array(message.data)[2])
    except Exception:  # noqa: BLE001 - whatever the damage, the frames are read again later
        return 0
    return 0


def load_run(path: str | Path) -> RunMeta:
    """Metadata, topics, frame count and truncation of a recording.

    Raises:
        RecordingError: not an MCAP file, or no PoseArray topic ``.../poses`` in it.
    """
    info = scan_recording(path)
    problems: list[str] = []
    raw = dict(info.metadata.get("sweep_ros", {}))
    declared = _json(raw.get("topics"), "topics", problems)
    poses = _pick_topic(info.channels, "/poses", cdr.POSE_ARRAY, declared)
    scene = None
    if raw.get("scene"):
        first = _first_count(info.path, poses)
        try:
            # a recording is data: its scene is rebuilt from what it carries, and a map it
            # names by path is refused, never read from this machine
            data = scene_data(raw["scene"], source="the recorded scene", recorded=True,
                              max_nodes=RECORDED_BASE_NODES + RECORDED_NODES_PER_AGENT * first,
                              limit_name=f"the limit for a recording whose first state holds "
                                         f"{first} agents: {RECORDED_BASE_NODES} + "
                                         f"{RECORDED_NODES_PER_AGENT} per agent",
                              fix="use the recording as sweep run or sweep_node wrote it: its "
                                  "scene holds its first state's agents, and walls within "
                                  "MAX_SEGMENTS")
            older = recorded_headway(data)  # a speed law recorded before some keys existed
            scene = Scene.from_dict(data if older is None else older, files=False)
        except CostError as err:  # refused outright: nothing of it is rebuilt
            raise RecordingError(f"{info.path}: the recorded scene (metadata sweep_ros.scene) "
                                 f"is refused: {err}") from err
        except SweepError as err:
            problems.append(f"the recorded scene does not load: {err}")
    dt = _number(raw, "dt", float, problems)
    seed = _number(raw, "seed", int, problems)
    if info.message_count == 0 and poses is None:
        if os.path.getsize(info.path) == 0:
            raise RecordingError(f"{info.path}: the file is empty (0 bytes), not a recording "
                                 "(fix: give the .mcap that sweep run or the node wrote)")
        if info.truncated:
            raise RecordingError(f"{info.path}: no messages: the file ends at byte "
                                 f"{os.path.getsize(info.path)} before its first chunk; it was "
                                 "cut short before its first flush (fix: record again and let "
                                 "the run last more than a second)")
        raise RecordingError(f"{info.path}: no messages: the recording is empty (fix: record "
                             "at least one step)")
    if poses is None:
        raise RecordingError(f"{info.path}: no geometry_msgs/msg/PoseArray topic '/poses' "
                             f"(topics: {sorted(info.channels)}) (fix: analyse a recording "
                             "made by sweep run or sweep_node)")
    for topic in (poses, _pick_topic(info.channels, "/agents", cdr.POINT_CLOUD2, declared)):
        encoding = info.channels[topic].message_encoding if topic in info.channels else "cdr"
        if encoding != "cdr":
            raise RecordingError(f"{info.path}: topic {topic} is recorded in the "
                                 f"{show(encoding)} encoding, not cdr (fix: analyse a "
                                 "recording made by sweep run, sweep_node or ros2 bag record)")
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
        truncated=info.truncated, error=info.error, problems=problems,
        status=describe_status(info.metadata, info.truncated),
        recovered_short=info.metadata.get(RECOVER_RECORD, {}).get("complete") == "false")
    meta.commands = [Command(k, topic, step, log_ns, spec, meta.segment_of(log_ns))
                     for k, topic, step, log_ns, spec
                     in _stepped(info.metadata, "command", "field", problems)]
    for k, rec in _indexed(info.metadata, "parameter"):
        try:
            change = ParameterChange(k, rec["name"], json.loads(rec["value"]), int(rec["step"]),
                                     int(rec["log_time_ns"]), 0)
        except (KeyError, ValueError, RecursionError):
            problems.append(f"metadata parameter_{k:06d} is incomplete (name, value, step, "
                            "log_time_ns)")
            continue
        meta.parameter_changes.append(ParameterChange(
            change.index, change.name, change.value, change.step, change.log_time_ns,
            meta.segment_of(change.log_time_ns)))
    meta.maps = [MapChange(k, topic, step, log_ns, spec, meta.segment_of(log_ns))
                 for k, topic, step, log_ns, spec in _stepped(info.metadata, "map", "map", problems)]
    meta.robot_poses = [MapChange(k, topic, step, log_ns, spec, meta.segment_of(log_ns))
                        for k, topic, step, log_ns, spec
                        in _stepped(info.metadata, "robot_pose", "placement", problems)]
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
    its step on (a command with step k is in effect for the step k -> k + 1); and the map in
    effect (:meth:`map_at`)."""

    def __init__(self, meta: RunMeta) -> None:
        base = meta.scene.drift.to_spec() if meta.scene is not None else {"kind": "none"}
        self._base = base
        self._by_segment: dict[int, tuple[list[int], list[dict]]] = {}
        for c in sorted(meta.commands, key=lambda c: (c.segment, c.step, c.index)):
            steps, specs = self._by_segment.setdefault(c.segment, ([], []))
            steps.append(c.step)
            specs.append(c.spec)

        #: (segment, step) from which each recorded map is in effect, and its spec
        self._maps = sorted(((m.segment, m.step), m.index, m.spec) for m in meta.maps)

    def spec_at(self, segment: int, step: int) -> dict:
        steps, specs = self._by_segment.get(segment, ([], []))
        k = bisect.bisect_right(steps, step)
        return specs[k - 1] if k else self._base

    def map_at(self, segment: int, step: int) -> dict | None:
        """The packed map in effect for the step step -> step + 1 of segment (a recorded map
        stays over resets), or None: the scene's own."""
        k = bisect.bisect_right([m[0] for m in self._maps], (segment, step))
        return self._maps[k - 1][2] if k else None
