"""Arrays <-> ROS messages for sweep_node, as pure functions (no node, no engine state).

* Incoming velocity-field commands are parsed and validated here (:func:`uniform_from_twist`,
  :func:`goal_from_point`, :func:`grid_from_cloud`), and maps (:func:`map_from_grid`);
  anything malformed raises :class:`CommandError` and never reaches the engine.
* Outgoing markers: :class:`AgentMarkers` encodes the per-agent cylinder MarkerArray straight to
  CDR with numpy (a template serialised once by rclpy, patched per agent), because building
  thousands of Marker objects takes longer than a timer tick; :func:`wall_markers` and
  :func:`delete_all` build the rare ones as message objects.
* :func:`diagnostics` builds the DiagnosticArray, :func:`time_msg` a builtin_interfaces/Time.

Longer than 400 lines because every conversion between the engine's arrays and the node's
messages lives here, in both directions, so that the node itself holds no message layout;
the refusal texts of malformed commands (each naming the field, the value and the fix) are
most of the growth.
"""
from __future__ import annotations

import math
import re
import struct
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.serialization import serialize_message
from sensor_msgs.msg import PointField
from visualization_msgs.msg import Marker, MarkerArray

from sweep_core import SceneError, grid_field
from sweep_core.checks import COORDINATE_BOUND
from sweep_core.errors import show
from sweep_core.model.fields import Goal, Grid, Uniform
from sweep_core.model.geometry import Geometry
from sweep_core.model.maps import OccupancyMap

#: largest grid (points) a velocity_field command may carry
MAX_GRID_POINTS = 1_000_000
#: goals farther than this from the origin (m) are refused: the scene's coordinate bound, within
#: which float64 distances hold (sweep_core.checks.COORDINATE_BOUND)
MAX_COORDINATE = COORDINATE_BOUND
#: relative tolerance on grid node spacing (float32 clouds carry rounding of ~1e-7 relative)
GRID_TOLERANCE = 1e-4
#: field names a velocity_field cloud must have
GRID_FIELDS = ("x", "y", "vx", "vy")

AGENT_COLOR = (0.16, 0.47, 0.80, 0.9)
WALL_COLOR = (0.45, 0.45, 0.45, 1.0)
OBSTACLE_COLOR = (0.60, 0.25, 0.20, 1.0)
WALL_THICKNESS = 0.05


class CommandError(ValueError):
    """A command that must not reach the engine: ``topic: problem``."""

    def __init__(self, topic: str, problem: str) -> None:
        self.topic = topic
        self.problem = problem
        super().__init__(f"{topic}: {problem}")


# ---------------------------------------------------------------------------------------------
# Time
# ---------------------------------------------------------------------------------------------

def time_msg(stamp_ns: int) -> Time:
    """builtin_interfaces/Time of integer nanoseconds (nanosec always in [0, 1e9))."""
    sec, nsec = divmod(int(stamp_ns), 1_000_000_000)
    return Time(sec=sec, nanosec=nsec)


def stamp_ns_of(stamp: Time) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


# ---------------------------------------------------------------------------------------------
# Commands
# ---------------------------------------------------------------------------------------------

def _check_speed(topic: str, speed: float, max_speed: float) -> None:
    if speed > max_speed:
        raise CommandError(topic, f"speed {speed:.6g} m/s exceeds max_speed {max_speed:g} m/s "
                                  "(fix: send a slower field or raise the max_speed parameter)")


def uniform_from_twist(msg: Any, max_speed: float, topic: str = "cmd_vel") -> Uniform:
    """geometry_msgs/Twist -> uniform field (linear.x, linear.y); the other components must be
    finite and are ignored."""
    values = [msg.linear.x, msg.linear.y, msg.linear.z,
              msg.angular.x, msg.angular.y, msg.angular.z]
    if not all(math.isfinite(v) for v in values):
        raise CommandError(topic, f"non-finite component in linear {show(values[:3])} / "
                                  f"angular {show(values[3:])} (fix: send finite numbers; "
                                  "linear.x and linear.y are the velocity, m/s)")
    v = np.array([float(msg.linear.x), float(msg.linear.y)])
    _check_speed(topic, float(np.hypot(*v)), max_speed)
    return Uniform(velocity=v)


def goal_point(msg: Any, frame_id: str, topic: str = "goal") -> np.ndarray:
    """geometry_msgs/PointStamped -> the goal (2,) m, checked: finite, within MAX_COORDINATE of
    the origin; the header's frame must be empty or ``frame_id`` (there is no TF lookup)."""
    frame = msg.header.frame_id
    if frame not in ("", frame_id):
        raise CommandError(topic, f"frame {frame!r} is not the simulation frame {frame_id!r} "
                                  f"(fix: send the goal in {frame_id!r})")
    p = [msg.point.x, msg.point.y, msg.point.z]
    if not all(math.isfinite(c) for c in p):
        raise CommandError(topic, f"non-finite goal {show(p)} (fix: send finite coordinates, m)")
    if max(abs(p[0]), abs(p[1])) > MAX_COORDINATE:
        raise CommandError(topic, f"goal {show(p[:2])} is more than {MAX_COORDINATE:g} m away "
                                  f"(fix: send a goal within {MAX_COORDINATE:g} m of the origin "
                                  f"of {frame_id!r})")
    return np.array([float(p[0]), float(p[1])])


def goal_from_point(msg: Any, speed: float, slow_radius: float, frame_id: str,
                    topic: str = "goal") -> Goal:
    """geometry_msgs/PointStamped -> straight goal-directed field at ``speed`` (see
    :func:`goal_point`)."""
    return Goal(goal=goal_point(msg, frame_id, topic), speed=float(speed),
                slow_radius=float(slow_radius))


#: the fields of a geodesic drift spec and the node's parameters that set them
_GOAL_PARAMETERS = {"cell": "parameter goal_cell", "wall_buffer": "parameter goal_wall_buffer",
                    "goal": "the goal", "speed": "the speed"}


def navigation_refusal(topic: str, err: SceneError, field: str = "goal",
                       members: np.ndarray | None = None) -> CommandError:
    """A geodesic field's SceneError (its ``field.key`` names) as a command refusal naming
    the node's parameters instead (``goal.cell`` -> ``parameter goal_cell``); ``members``: the
    scene's indices of the agents the field was built for (a group's), so that an agent the
    error names by its place among them is named by its index in the scene."""
    problem, fix = err.problem, err.fix
    if members is not None:
        problem = re.sub(r"\bagent (\d+) at",
                         lambda m: f"agent {int(members[int(m.group(1))])} at", problem)
    for key, name in _GOAL_PARAMETERS.items():
        problem = problem.replace(f"{field}.{key}", name)
        fix = fix.replace(f"{field}.{key}", name)
    where = err.field.removeprefix(field).lstrip(".")
    what = _GOAL_PARAMETERS.get(where, "the geodesic field")
    return CommandError(topic, f"{what} refused: {problem}" + (f" (fix: {fix})" if fix else ""))


#: largest |roll| or |pitch| quaternion component of a map's origin taken as planar
PLANAR_TOLERANCE = 1e-6


def map_from_grid(msg: Any, frame_id: str, topic: str = "map") -> OccupancyMap:
    """nav_msgs/OccupancyGrid -> OccupancyMap (its cells, resolution and origin; a cell is
    free iff its occupancy is 0..24 %, the map files' free_thresh 0.25). The header's frame
    must be empty or ``frame_id`` (there is no TF lookup); the origin's orientation must be a
    rotation about z."""
    frame = msg.header.frame_id
    if frame not in ("", frame_id):
        raise CommandError(topic, f"frame {frame!r} is not the simulation frame {frame_id!r} "
                                  f"(fix: publish the map in {frame_id!r}, or set the node's "
                                  f"frame_id to {frame!r})")
    info = msg.info
    o, p = info.origin.orientation, info.origin.position
    quat = [o.x, o.y, o.z, o.w]
    if not all(math.isfinite(c) for c in quat + [p.x, p.y]):
        raise CommandError(topic, f"non-finite info.origin {show([p.x, p.y] + quat)} (fix: "
                                  "publish a finite origin pose)")
    norm = math.sqrt(sum(c * c for c in quat))
    if norm < 1e-9 or max(abs(o.x), abs(o.y)) > PLANAR_TOLERANCE * norm:
        raise CommandError(topic, f"info.origin.orientation {show(quat)} is not a rotation "
                                  "about z (fix: publish a planar map, quaternion x = y = 0)")
    yaw = 2.0 * math.atan2(o.z, o.w)
    if not math.isfinite(info.resolution):
        raise CommandError(topic, f"info.resolution {show(info.resolution)} is not finite "
                                  "(fix: publish the cell size, m)")
    try:
        return OccupancyMap.from_occupancy_grid(
            np.asarray(msg.data, dtype=np.int8), int(info.width), int(info.height),
            float(info.resolution), (float(p.x), float(p.y), yaw), source=topic, field="grid")
    except SceneError as err:
        where = "the grid" if err.field == "grid" else err.field.removeprefix("grid.")
        fix = err.fix.replace("grid.", "")
        raise CommandError(topic, f"{where} {err.problem} (fix: {fix})") from err


_DTYPES = {PointField.FLOAT32: "f4", PointField.FLOAT64: "f8"}
_FIELDS_FIX = "send FLOAT32 or FLOAT64 fields x, y, vx, vy, count 1 each"


def _cloud_layout(msg: Any, topic: str) -> tuple[int, int, np.ndarray, dict[str, tuple[int, str]]]:
    """Check an organised cloud's layout: (height, width, data bytes, name -> (offset, code))."""
    h, w = int(msg.height), int(msg.width)
    if h < 1 or w < 1:
        raise CommandError(topic, f"empty grid (height {h}, width {w}) (fix: send an organised "
                                  "cloud of height >= 1 rows along y and width >= 1 columns "
                                  "along x)")
    if h * w > MAX_GRID_POINTS:
        raise CommandError(topic, f"{h} x {w} grid exceeds {MAX_GRID_POINTS} points (fix: "
                                  f"resample the field onto at most {MAX_GRID_POINTS} nodes)")
    by_name = {f.name: f for f in msg.fields}
    missing = [n for n in GRID_FIELDS if n not in by_name]
    if missing:
        raise CommandError(topic, f"missing fields {missing} (has {sorted(by_name)}) (fix: "
                                  f"{_FIELDS_FIX})")
    step, row = int(msg.point_step), int(msg.row_step)
    data = np.frombuffer(memoryview(msg.data).cast("B"), dtype=np.uint8)
    if row < w * step or len(data) < row * (h - 1) + w * step:
        raise CommandError(topic, f"data holds {len(data)} bytes, too few for {h} x {w} points "
                                  f"of point_step {step}, row_step {row} (fix: send row_step >= "
                                  "width * point_step and height * row_step bytes of data)")
    layout = {}
    for name in GRID_FIELDS:
        f = by_name[name]
        code = _DTYPES.get(int(f.datatype))
        if code is None or int(f.count) != 1:
            raise CommandError(topic, f"field {name!r} must be one FLOAT32 or FLOAT64 "
                                      f"(datatype {f.datatype}, count {f.count}) (fix: "
                                      f"{_FIELDS_FIX})")
        if int(f.offset) + int(code[1]) > step:
            raise CommandError(topic, f"field {name!r} at offset {f.offset} overruns "
                                      f"point_step {step} (fix: set point_step to the size of "
                                      "one point, at least the end of its last field)")
        layout[name] = (int(f.offset), code)
    return h, w, data, layout


def _cloud_columns(h: int, w: int, data: np.ndarray, layout: dict[str, tuple[int, str]],
                   step: int, row: int, order: str) -> dict[str, np.ndarray]:
    """The x, y, vx, vy columns as float64 (height, width) arrays, read in byte order
    ``order`` ("<" little-endian, ">" big-endian)."""
    return {name: np.ndarray((h, w), dtype=order + code, buffer=data, offset=offset,
                             strides=(row, step)).astype(np.float64)
            for name, (offset, code) in layout.items()}


def _axis_nodes(values: np.ndarray, axis: int, name: str, topic: str) -> np.ndarray:
    """Node coordinates of a grid axis: values must depend on one index only and be evenly
    spaced (within GRID_TOLERANCE of the spacing); returned snapped to x0 + k dx."""
    nodes = values[0, :] if axis == 1 else values[:, 0]
    along = "column" if axis == 1 else "row"
    other = values - (nodes[None, :] if axis == 1 else nodes[:, None])
    n = nodes.size
    spacing = float(np.max(np.abs(np.diff(nodes)))) if n > 1 else 1.0
    if np.max(np.abs(other)) > GRID_TOLERANCE * spacing:
        r, c = (int(i) for i in np.unravel_index(int(np.argmax(np.abs(other))), other.shape))
        raise CommandError(topic, f"{name} must depend on the {along} index only, but row {r}, "
                                  f"column {c} holds {name} = {values[r, c]:g} (fix: rows "
                                  "along y, columns along x)")
    if n == 1:
        return nodes.copy()
    step = (nodes[-1] - nodes[0]) / (n - 1)
    ideal = nodes[0] + step * np.arange(n)
    if step == 0 or np.max(np.abs(nodes - ideal)) > GRID_TOLERANCE * abs(step):
        raise CommandError(topic, f"{name} is an irregular grid {show(nodes)} (fix: resample "
                                  "onto evenly spaced nodes)")
    return ideal


def _grid(cols: dict[str, np.ndarray], max_speed: float, topic: str) -> Grid:
    """The Grid of a cloud's columns (see :func:`grid_from_cloud`)."""
    for name, arr in cols.items():
        if not np.all(np.isfinite(arr)):
            r, c = (int(i) for i in np.argwhere(~np.isfinite(arr))[0])
            raise CommandError(topic, f"non-finite {name} {arr[r, c]:g} at row {r}, column {c} "
                                      "(fix: send finite numbers only)")
    x = _axis_nodes(cols["x"], 1, "x", topic)
    y = _axis_nodes(cols["y"], 0, "y", topic)
    vx, vy = cols["vx"], cols["vy"]
    if x.size > 1 and x[1] < x[0]:
        x, vx, vy = x[::-1], vx[:, ::-1], vy[:, ::-1]
    if y.size > 1 and y[1] < y[0]:
        y, vx, vy = y[::-1], vx[::-1], vy[::-1]
    _check_speed(topic, float(np.max(np.hypot(vx, vy))), max_speed)
    try:
        return grid_field(x, y, np.ascontiguousarray(vx), np.ascontiguousarray(vy), topic)
    except SceneError as err:
        raise CommandError(topic, str(err).removeprefix(f"{topic}.")) from err


def grid_from_cloud(msg: Any, max_speed: float, topic: str = "velocity_field") -> Grid:
    """sensor_msgs/PointCloud2 organised grid (height x width; fields x, y, vx, vy) -> Grid.

    Row r, column c holds the node (x_c, y_r). Axes may run either way (they are sorted);
    spacing must be even. Big- and little-endian data are both read (``is_bigendian``). The
    field is bilinear inside the grid and, outside, takes the value at the nearest point of the
    grid (sweep_core's Grid). A cloud refused as it is flagged, but valid in the other byte
    order, is refused with a message saying that is_bigendian does not match its data."""
    h, w, data, layout = _cloud_layout(msg, topic)
    step, row = int(msg.point_step), int(msg.row_step)
    big = bool(msg.is_bigendian)
    try:
        return _grid(_cloud_columns(h, w, data, layout, step, row, ">" if big else "<"),
                     max_speed, topic)
    except CommandError as err:
        try:
            _grid(_cloud_columns(h, w, data, layout, step, row, "<" if big else ">"),
                  max_speed, topic)
        except CommandError:
            raise err from None
        flag, other = ("true", "little") if big else ("false", "big")
        raise CommandError(topic, f"is_bigendian={flag} but the data is {other}-endian: read "
                                  f"as flagged, {err.problem.split(' (fix: ')[0]} (fix: set "
                                  f"is_bigendian={'false' if big else 'true'} to match the "
                                  "data's byte order)") from None


# ---------------------------------------------------------------------------------------------
# Markers
# ---------------------------------------------------------------------------------------------

def _color(marker: Marker, rgba: tuple[float, float, float, float]) -> None:
    marker.color.r, marker.color.g, marker.color.b, marker.color.a = (float(c) for c in rgba)


def agent_marker(frame_id: str, stamp_ns: int, i: int, x: float, y: float, radius: float,
                 height: float, ns: str = "agents",
                 color: tuple[float, float, float, float] = AGENT_COLOR) -> Marker:
    """One agent's cylinder (diameter 2 r, standing on z = 0), as a message object."""
    m = Marker()
    m.header.frame_id = frame_id
    m.header.stamp = time_msg(stamp_ns)
    m.ns, m.id, m.type, m.action = ns, int(i), Marker.CYLINDER, Marker.ADD
    m.pose.position.x, m.pose.position.y, m.pose.position.z = float(x), float(y), height / 2
    m.pose.orientation.w = 1.0
    m.scale.x = m.scale.y = 2.0 * float(radius)
    m.scale.z = float(height)
    _color(m, color)
    return m


_SENTINELS = {  # field -> (struct code, value of marker k = base + k)
    "sec": ("<i", 0x5A5A0000), "nanosec": ("<I", 0x3C3C0000), "id": ("<i", 0x7E7E0000),
    "x": ("<d", 123456.789012345), "y": ("<d", 234567.890123456),
    "sx": ("<d", 345678.901234567), "sy": ("<d", 456789.012345678),
}


@dataclass(frozen=True)
class _Layout:
    prefix: bytes         # encapsulation + array length (patched)
    count_offset: int     # offset of the uint32 array length
    block: np.ndarray     # uint8 bytes of one marker, trailing alignment padding included
    last_length: int      # length of the last marker (no trailing padding)
    offsets: dict[str, int]  # field offsets within the block


class AgentMarkers:
    """Encodes ``visualization_msgs/MarkerArray`` of one CYLINDER per agent to CDR bytes.

    The bytes deserialise to the same message rclpy would serialise from :func:`agent_marker`
    objects; they can be published with ``publisher.publish(bytes)`` and recorded as they are.
    A template array is serialised by rclpy once; markers differ only in stamp, id, position
    and diameter, which are patched in with numpy. If the template's markers do not all share
    one layout (a Marker whose size is not a multiple of the 8-byte alignment), encoding falls
    back to building message objects.
    """

    def __init__(self, frame_id: str, height: float = 1.0, ns: str = "agents",
                 color: tuple[float, float, float, float] = AGENT_COLOR) -> None:
        self.frame_id, self.height, self.ns, self.color = frame_id, float(height), ns, color
        self._layout = self._probe()

    def _probe(self) -> _Layout | None:
        markers = []
        for k in range(3):
            m = agent_marker(self.frame_id, 0, 0, 0.0, 0.0, 0.5, self.height, self.ns,
                             self.color)
            m.header.stamp = Time(sec=_SENTINELS["sec"][1] + k,
                                  nanosec=_SENTINELS["nanosec"][1] + k)
            m.id = _SENTINELS["id"][1] + k
            m.pose.position.x = _SENTINELS["x"][1] + k
            m.pose.position.y = _SENTINELS["y"][1] + k
            m.scale.x = _SENTINELS["sx"][1] + k
            m.scale.y = _SENTINELS["sy"][1] + k
            markers.append(m)
        data = bytes(serialize_message(MarkerArray(markers=markers)))

        def find(key: str, k: int) -> int | None:
            code, base = _SENTINELS[key]
            pattern = struct.pack(code, base + k)
            at = data.find(pattern)
            return None if at < 0 or data.find(pattern, at + 1) >= 0 else at

        found = {(key, k): find(key, k) for key in _SENTINELS for k in range(3)}
        if any(v is None for v in found.values()):
            return None
        s = [found["sec", k] for k in range(3)]
        size = s[1] - s[0]
        if size % 8 or s[2] - s[1] != size:
            return None
        offsets = {key: found[key, 0] - s[0] for key in _SENTINELS}
        if any(found[key, k] - s[k] != offsets[key] for key in _SENTINELS for k in (1, 2)):
            return None
        count_offset = s[0] - 4
        if struct.unpack_from("<I", data, count_offset)[0] != 3:
            return None
        return _Layout(data[:s[0]], count_offset,
                       np.frombuffer(data[s[0]:s[1]], dtype=np.uint8).copy(),
                       len(data) - s[2], offsets)

    def encode(self, stamp_ns: int, positions: np.ndarray, radii: np.ndarray) -> bytes:
        """CDR bytes of the MarkerArray for positions (N, 2) and radii (N,), m."""
        q = np.asarray(positions, dtype="<f8").reshape(-1, 2)
        d = 2.0 * np.asarray(radii, dtype="<f8").reshape(-1)
        n = len(q)
        lay = self._layout
        if lay is None:
            return bytes(serialize_message(MarkerArray(markers=[
                agent_marker(self.frame_id, stamp_ns, i, q[i, 0], q[i, 1], d[i] / 2,
                             self.height, self.ns, self.color) for i in range(n)])))
        prefix = bytearray(lay.prefix)
        struct.pack_into("<I", prefix, lay.count_offset, n)
        if n == 0:
            return bytes(prefix)
        buf = np.tile(lay.block, (n, 1))
        sec, nsec = divmod(int(stamp_ns), 1_000_000_000)
        columns = {"sec": np.full(n, sec, "<i4"), "nanosec": np.full(n, nsec, "<u4"),
                   "id": np.arange(n, dtype="<i4"), "x": np.ascontiguousarray(q[:, 0]),
                   "y": np.ascontiguousarray(q[:, 1]), "sx": d, "sy": d}
        for key, values in columns.items():
            raw = values.view(np.uint8).reshape(n, -1)
            off = lay.offsets[key]
            buf[:, off:off + raw.shape[1]] = raw
        end = (n - 1) * len(lay.block) + lay.last_length
        return bytes(prefix) + buf.reshape(-1)[:end].tobytes()


def delete_all(frame_id: str, stamp_ns: int, ns: str = "agents") -> MarkerArray:
    """A MarkerArray whose one marker clears every marker (of every namespace) in viewers."""
    m = Marker()
    m.header.frame_id = frame_id
    m.header.stamp = time_msg(stamp_ns)
    m.ns, m.action = ns, Marker.DELETEALL
    return MarkerArray(markers=[m])


def scene_extent(geometry: Geometry, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper corners (m) of what a scene contains, for drawing infinite walls."""
    pts = [np.asarray(positions).reshape(-1, 2), geometry.segment_a, geometry.segment_b]
    if len(geometry.circle_center):
        r = geometry.circle_radius[:, None]
        pts += [geometry.circle_center - r, geometry.circle_center + r]
    allp = np.concatenate([p for p in pts if len(p)]) if any(len(p) for p in pts) else \
        np.zeros((1, 2))
    return allp.min(axis=0) - 1.0, allp.max(axis=0) + 1.0


def _box(m: Marker, a: np.ndarray, b: np.ndarray, thickness: float, height: float) -> None:
    """A CUBE marker spanning the segment a-b (thickness across, height up)."""
    mid, d = (a + b) / 2, b - a
    yaw = math.atan2(d[1], d[0])
    m.type = Marker.CUBE
    m.pose.position.x, m.pose.position.y, m.pose.position.z = float(mid[0]), float(mid[1]), \
        height / 2
    m.pose.orientation.z, m.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
    m.scale.x, m.scale.y, m.scale.z = float(np.hypot(*d)), thickness, height


def wall_markers(geometry: Geometry, positions: np.ndarray, frame_id: str, stamp_ns: int,
                 t: float, height: float = 1.0) -> MarkerArray:
    """Walls (namespace ``walls``: CUBE per segment, a long CUBE per half-plane at time t; a
    map's wall pieces in namespace ``map``, id = piece) and
    obstacles (namespace ``obstacles``: CYLINDER per circle); moving obstacles at their pose
    at t."""
    out = []
    geometry = geometry.at(t)
    lo, hi = scene_extent(geometry, positions)
    centre, reach = (lo + hi) / 2, float(np.hypot(*(hi - lo)))

    def base(ns: str, i: int, color: tuple) -> Marker:
        m = Marker()
        m.header.frame_id = frame_id
        m.header.stamp = time_msg(stamp_ns)
        m.ns, m.id, m.action = ns, int(i), Marker.ADD
        m.pose.orientation.w = 1.0
        _color(m, color)
        return m

    for k in range(len(geometry.segment_a)):
        # a plain segment is marker walls/<index>; the pieces of a polyline or the edges of a
        # polygon obstacle get a namespace of their own (walls[i], obstacles[i]), id = piece
        poly, index = int(geometry.segment_polygon[k]), int(geometry.segment_index[k])
        if poly >= 0:
            m = base(f"obstacles[{poly}]", int(geometry.segment_part[k]), OBSTACLE_COLOR)
        elif geometry.segment_kind[k] == "map":
            m = base("map", int(geometry.segment_part[k]), WALL_COLOR)
        elif geometry.segment_kind[k] != "segment":
            m = base(f"walls[{index}]", int(geometry.segment_part[k]), WALL_COLOR)
        else:
            m = base("walls", index, WALL_COLOR)
        _box(m, geometry.segment_a[k], geometry.segment_b[k], WALL_THICKNESS, height)
        out.append(m)
    for k in range(len(geometry.halfplane_offset)):
        n = geometry.halfplane_normal[k]
        c = geometry.halfplane_offset[k] + geometry.halfplane_velocity[k] * t
        foot = centre + (c - float(n @ centre)) * n - n * (WALL_THICKNESS / 2)
        along = np.array([n[1], -n[0]]) * reach
        m = base("walls", int(geometry.halfplane_index[k]), WALL_COLOR)
        _box(m, foot - along, foot + along, WALL_THICKNESS, height)
        out.append(m)
    for k in range(len(geometry.circle_radius)):
        m = base("obstacles", int(geometry.circle_index[k]), OBSTACLE_COLOR)
        m.type = Marker.CYLINDER
        cx, cy = geometry.circle_center[k]
        m.pose.position.x, m.pose.position.y, m.pose.position.z = float(cx), float(cy), \
            height / 2
        m.scale.x = m.scale.y = 2.0 * float(geometry.circle_radius[k])
        m.scale.z = height
        out.append(m)
    return MarkerArray(markers=out)


# ---------------------------------------------------------------------------------------------
# Diagnostics
# ---------------------------------------------------------------------------------------------

LEVELS = {"OK": DiagnosticStatus.OK, "WARN": DiagnosticStatus.WARN,
          "ERROR": DiagnosticStatus.ERROR, "STALE": DiagnosticStatus.STALE}


def _show(value: Any) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value)


def diagnostics(stamp_ns: int, name: str, hardware_id: str, level: str, message: str,
                values: Mapping[str, Any]) -> DiagnosticArray:
    """A DiagnosticArray with one status; ``level`` is OK, WARN, ERROR or STALE."""
    status = DiagnosticStatus(level=LEVELS[level], name=name, message=message,
                              hardware_id=hardware_id,
                              values=[KeyValue(key=k, value=_show(v)) for k, v in values.items()])
    arr = DiagnosticArray(status=[status])
    arr.header.stamp = time_msg(stamp_ns)
    return arr
