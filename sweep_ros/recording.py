"""The node's recording (:class:`RecordingMixin` of :class:`sweep_ros.node.SweepNode`): the MCAP
opened with the run's metadata and one channel per topic, and the helpers through which every
published message is also recorded at its log time (simulation time, going on over resets).
"""
from __future__ import annotations

import json
import os
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PointStamped, Twist
from nav_msgs.msg import OccupancyGrid
from visualization_msgs.msg import MarkerArray

from sweep_core import SweepError
from sweep_core.io import cdr, topics
from sweep_core.io.metadata import run_metadata
from sweep_core.io.recording import BackgroundRecorder, qos_profiles
from sweep_ros import msgdefs, results
from sweep_ros.errors import StartError
from sweep_ros.robots import TF_STATIC_TOPIC


class RecordingMixin:
    """Recording of :class:`~sweep_ros.node.SweepNode` (its attributes are the node's)."""

    _p: dict[str, Any]
    recorder: BackgroundRecorder | None
    _epoch_ns: int
    _last_log_ns: int

    def _open_recording(self) -> None:
        meta = run_metadata(self.scene, self.sim, None)
        names = {
            self.pub_poses.topic_name: cdr.POSE_ARRAY,
            self.pub_agents.topic_name: cdr.POINT_CLOUD2,
            self.pub_markers.topic_name: msgdefs.msgtype_of(MarkerArray),
            self.pub_walls.topic_name: msgdefs.msgtype_of(MarkerArray),
            self.pub_diag.topic_name: msgdefs.msgtype_of(DiagnosticArray),
            self.pub_results.topic_name: msgdefs.msgtype_of(DiagnosticArray),
            self.pub_navigation.topic_name: cdr.POINT_CLOUD2,
            self.sub_cmd_vel.topic_name: msgdefs.msgtype_of(Twist),
            self.sub_goal.topic_name: msgdefs.msgtype_of(PointStamped),
            **{sub.topic_name: msgdefs.msgtype_of(PointStamped)
               for sub in self.sub_group_goals},
            self.sub_field.topic_name: cdr.POINT_CLOUD2,
        }
        if self.pub_clock is not None:
            names[self.pub_clock.topic_name] = cdr.CLOCK
        if self.sub_map is not None:
            names[self.sub_map.topic_name] = msgdefs.msgtype_of(OccupancyGrid)
        names.update(self._robot_channels())
        latched = {self.pub_walls.topic_name: 1, self.pub_navigation.topic_name: 1,
                   self.pub_diag.topic_name: 1, self.pub_results.topic_name: results.DEPTH}
        if self.sub_map is not None:
            latched[self.sub_map.topic_name] = 1
        if self.robots:
            latched[TF_STATIC_TOPIC] = 1
        meta.update({
            "node": self.get_fully_qualified_name(),
            "parameters": json.dumps(self._p, sort_keys=True),
            "frame_id": self.frame_id,
            "topics": json.dumps(names, sort_keys=True),
            "log_time": "simulation time (ns) of the state or of the step a command applies to; "
                        "after a reset log times go on from the last one (records reset_*)",
        })
        record = os.path.expanduser(self._p["record"])
        scene_file = os.path.expanduser(self._p["scene"]) if self._p["scene"] else None
        map_file = (self.scene.spec.get("map") or {}).get("source")
        inputs = [scene_file, map_file if map_file and os.path.isfile(map_file) else None]
        if (os.path.isfile(record) and not self._p["record_overwrite"]
                and not any(f and os.path.samefile(f, record) for f in inputs)):
            # a recording is never replaced unasked (as sweep run's --out without --overwrite);
            # an input named as the record file is refused as such by the recorder
            raise StartError([f"parameter record: {record}: exists, and the node does not "
                              "replace a recording unasked (fix: -p record:=OTHER.mcap, or "
                              "-p record_overwrite:=true to replace it)"])
        try:
            self.recorder = BackgroundRecorder(
                record, metadata=meta,
                flush_interval_s=self._p["record_flush_interval_s"],
                inputs=inputs,
                other="-p record:=OTHER.mcap", on_error=self._recording_failed)
            for topic, msgtype in names.items():
                definition = None if msgtype in cdr.SCHEMAS else msgdefs.definition(msgtype)
                qos = (qos_profiles(latched[topic], True) if topic in latched
                       else qos_profiles(10))
                self.recorder.add_channel(topic, msgtype, definition, offered_qos_profiles=qos)
        except (SweepError, msgdefs.MsgDefError) as err:
            if self.recorder is not None:
                self.recorder.close()
            raise StartError([f"parameter record: {err}"]) from err

    def _recording_failed(self, message: str) -> None:
        """Called once, on the writer thread, when the recording stops (disk full, ...): logged
        at once; the simulation, its topics and services go on, unrecorded."""
        self.get_logger().error(f"recording stopped: {message}; the simulation goes on "
                                "without recording")

    # -- recording helpers -------------------------------------------------------------------
    def _log_ns(self, t: float) -> int:
        ns = self._epoch_ns + topics.stamp_ns(t)
        self._last_log_ns = max(self._last_log_ns, ns)
        return ns

    def _record(self, topic: str, log_ns: int, data: bytes) -> None:
        if self.recorder is not None:
            self.recorder.write(topic, log_ns, data)

    def _publish(self, pub: Any, data: bytes, log_ns: int) -> None:
        pub.publish(data)
        self._record(pub.topic_name, log_ns, data)
