"""Markers for viewers (RViz, Foxglove): :class:`AgentMarkers` encodes the per-agent cylinder
MarkerArray straight to CDR with numpy (a template serialised once by rclpy, patched per
agent), because building thousands of Marker objects takes longer than a timer tick;
:func:`wall_markers` and :func:`delete_all` build the rare ones as message objects.
"""
from __future__ import annotations

import math
import struct
from dataclasses import dataclass

import numpy as np
from builtin_interfaces.msg import Time
from rclpy.serialization import serialize_message
from visualization_msgs.msg import Marker, MarkerArray

from sweep_core.model.geometry import Geometry
from sweep_ros.messages import time_msg

AGENT_COLOR = (0.16, 0.47, 0.80, 0.9)
WALL_COLOR = (0.45, 0.45, 0.45, 1.0)
OBSTACLE_COLOR = (0.60, 0.25, 0.20, 1.0)
WALL_THICKNESS = 0.05

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
