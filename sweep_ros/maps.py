"""Maps received on the node's ``map_topic`` (:class:`MapsMixin` of
:class:`sweep_ros.node.SweepNode`): parsed and their walls built on the executor's thread,
swapped into the simulator between two steps, or refused with the old walls kept.
"""
from __future__ import annotations

import json
from typing import Any

from nav_msgs.msg import OccupancyGrid
from rclpy.serialization import deserialize_message

from sweep_core import SceneError
from sweep_core.model.maps import replace_map
from sweep_core.model.scene import Scene
from sweep_ros import messages


class MapsMixin:
    """Maps of :class:`~sweep_ros.node.SweepNode` (its attributes are the node's)."""

    _p: dict[str, Any]

    def _on_map(self, raw: bytes) -> None:
        """A map (executor thread): parsed and its walls built here, then swapped in between
        two steps (and recorded: the message on its topic, a ``map_NNNNNN`` metadata record),
        or refused (see the module docstring)."""
        topic = self.sub_map.topic_name if self.sub_map is not None else "map"
        try:
            try:
                msg = deserialize_message(raw, OccupancyGrid)
            except Exception as err:  # noqa: BLE001 - any undecodable payload is refused
                raise messages.CommandError(topic, f"cannot decode ({err})") from err
            grid = messages.map_from_grid(msg, self.frame_id, topic)
        except messages.CommandError as err:
            self._refuse_map(str(err))
            return
        spec = grid.to_spec()
        try:
            scene = Scene.from_dict(replace_map(self.scene0.spec, spec))
        except SceneError as err:
            self._refuse_map(f"{topic}: the scene's initial positions (where reset returns) do "
                             f"not fit it: {err}")
            return
        with self._gate.control():
            if self._closed:
                return
            try:
                self.sim.set_scene(scene)
            except SceneError as err:  # names the agents
                self._refuse_map(f"{topic}: {err.problem} (fix: {err.fix})")
                return
            self.scene = scene
            self._moving_walls = bool(scene.geometry.is_moving or (
                len(scene.geometry.halfplane_velocity)
                and (scene.geometry.halfplane_velocity != 0).any()))
            self._maps_applied += 1
            log_ns = self._log_ns(self.sim.t)
            self._record(topic, log_ns, bytes(raw))
            if self.recorder is not None:
                self.recorder.metadata(f"map_{self._maps_applied:06d}", {
                    "topic": topic, "step": str(self.sim.n_steps), "t": repr(self.sim.t),
                    "log_time_ns": str(log_ns), "map": json.dumps(spec)})
            self._publish_walls(clear=True)
            self._publish_navigation()
            h, w = grid.shape
            self.get_logger().info(
                f"{topic}: map of {w} x {h} cells of {grid.resolution:g} m, "
                f"{sum(1 for k in scene.geometry.segment_kind if k == 'map')} wall pieces, "
                f"in effect from step "
                f"{self.sim.n_steps}")

    def _refuse_map(self, why: str) -> None:
        self._maps_refused += 1
        self._map_problem = f"map refused, old walls kept: {why}"
        self.get_logger().error(self._map_problem)
