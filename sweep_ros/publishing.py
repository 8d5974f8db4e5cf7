"""What the node publishes of the simulation's state (:class:`PublishingMixin` of
:class:`sweep_ros.node.SweepNode`): poses, agents, clock and markers after each tick, the
navigation field when it changes, the walls (latched). Each message is recorded as published.
"""
from __future__ import annotations

import time
from typing import Any

from rclpy.serialization import serialize_message

from sweep_core.io import cdr, topics
from sweep_core.io import markers as content
from sweep_core.io.cdr.markers import encode_marker_array
from sweep_ros import markers


class PublishingMixin:
    """Publishing of :class:`~sweep_ros.node.SweepNode` (its attributes are the node's)."""

    _p: dict[str, Any]

    def _publish_state(self, force_markers: bool = False) -> None:
        state = self.sim.state
        self._published = (self._resets, self.sim.n_steps)
        ns = topics.stamp_ns(state.t)
        log_ns = self._log_ns(state.t)
        encoded = topics.encode_state(state, self.frame_id)
        self._publish(self.pub_poses, encoded[topics.POSES], log_ns)
        self._publish(self.pub_agents, encoded[topics.AGENTS], log_ns)
        if self.pub_clock is not None:
            self._publish(self.pub_clock, cdr.encode_clock(ns), log_ns)
        now = time.monotonic()
        if self._p["publish_markers"] and (
                force_markers or now - self._last_markers >= 1.0 / self._p["marker_rate_hz"]):
            self._last_markers = now
            batches = content.state_batches(self.sim, height=self._p["marker_height"])
            self._publish(self.pub_markers, encode_marker_array(ns, self.frame_id, batches),
                          log_ns)
            if self._moving_walls:
                self._publish_walls()
        self._publish_robots(log_ns)
        self._publish_navigation()

    def _publish_pending(self) -> None:
        """The state, when its step's has not been published yet (a control callback about
        to change it between two steps of a tick: the recording then holds the state the
        step made, before the change, as replay expects). The caller holds the gate."""
        if self._published != (self._resets, self.sim.n_steps):
            self._publish_state()

    def _publish_navigation(self) -> None:
        """The navigation_field of the drift in effect, when it differs from the one last
        published (another drift, or a field recomputed for moving obstacles); an empty cloud
        once the drift has none any more. The caller holds the gate."""
        drift, t = self.sim.drift, self.sim.t
        key = topics.navigation_key(drift, t)
        if key == self._navigation[0]:
            return
        self._navigation = (key, drift)  # the drift kept alive: its fields' ids stay its own
        ns = topics.stamp_ns(t)
        self._publish(self.pub_navigation,
                      topics.encode_navigation(ns, self.frame_id, drift, t), self._log_ns(t))

    def _publish_walls(self, clear: bool = False) -> None:
        """The walls markers at the current time; clear: first delete every marker (a new map
        can have fewer wall pieces than the last)."""
        t = self.sim.t
        msg = markers.wall_markers(self.scene.geometry, self.scene.positions, self.frame_id,
                                   topics.stamp_ns(t), t, self._p["marker_height"], clear)
        self._publish(self.pub_walls, bytes(serialize_message(msg)), self._log_ns(t))
