"""Markers for viewers (RViz, Foxglove) as rclpy messages: the content is
:mod:`sweep_core.io.markers`' (shared with ``sweep run`` and the live view); :func:`to_message`
turns its batches into a ``visualization_msgs/MarkerArray``. The per-tick ``/markers`` are
published as the CDR bytes of :func:`sweep_core.io.cdr.markers.encode_marker_array` (the same
message, without building thousands of Marker objects each tick)."""
from __future__ import annotations

import numpy as np
from rclpy.serialization import serialize_message
from visualization_msgs.msg import Marker, MarkerArray

from sweep_core.io import markers as content
from sweep_core.io.cdr.markers import MarkerBatch
from sweep_core.io.cdr.markers import delete_all as delete_all_batch
from sweep_core.model import elementary
from sweep_core.model.geometry import Geometry
from sweep_ros.messages import time_msg

WALL_THICKNESS = content.WALL_THICKNESS


def to_message(frame_id: str, stamp_ns: int, batches: list[MarkerBatch]) -> MarkerArray:
    """The batches' markers as a MarkerArray message, stamped ``stamp_ns`` in ``frame_id``."""
    out = []
    stamp = time_msg(stamp_ns)
    for b in batches:
        half = 0.5 * np.asarray(b.yaw, dtype=np.float64)
        for i in range(len(b)):
            m = Marker()
            m.header.frame_id = frame_id
            m.header.stamp = stamp
            m.ns, m.id, m.type, m.action = b.ns, int(b.ids[i]), int(b.type), int(b.action)
            p = m.pose.position
            p.x, p.y, p.z = (float(v) for v in b.position[i])
            m.pose.orientation.z, m.pose.orientation.w = elementary.sincos(float(half[i]))
            m.scale.x, m.scale.y, m.scale.z = (float(v) for v in b.scale[i])
            m.color.r, m.color.g, m.color.b, m.color.a = (float(v) for v in b.color[i])
            out.append(m)
    return MarkerArray(markers=out)


def delete_all(frame_id: str, stamp_ns: int, ns: str = "agents") -> MarkerArray:
    """A MarkerArray whose one marker clears every marker (of every namespace) in viewers."""
    return to_message(frame_id, stamp_ns, [delete_all_batch(ns)])


def wall_markers(geometry: Geometry, positions: np.ndarray, frame_id: str, stamp_ns: int,
                 t: float, height: float = 1.0, clear: bool = False) -> MarkerArray:
    """The ``/walls`` message at time t (s) (:func:`sweep_core.io.markers.wall_batches`)."""
    return to_message(frame_id, stamp_ns,
                      content.wall_batches(geometry, positions, t, height, clear))


def serialized(msg: MarkerArray) -> bytes:
    """CDR bytes of a message, for publishing and recording."""
    return bytes(serialize_message(msg))
