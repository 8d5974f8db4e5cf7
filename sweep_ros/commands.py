"""The node's commands (:class:`CommandsMixin` of :class:`sweep_ros.node.SweepNode`): crowd
velocity, goals (all agents or one group), velocity fields; parsed and validated on the
executor's thread, offered to the inbox (latest wins), applied at the start of the next step
and recorded, each with its verdict on ``command_result``.
"""
from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from geometry_msgs.msg import PointStamped, Twist
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import PointCloud2

from sweep_core import SceneError
from sweep_core.io import topics
from sweep_core.model.drift import field_from_spec
from sweep_core.model.fields import Field, Goal, Groups
from sweep_core.model.geodesic import navigation_fields
from sweep_core.model.maps import OccupancyMap, map_from_spec
from sweep_core.model.scene import Scene
from sweep_ros import clouds, graph, messages, results
from sweep_ros.inbox import Applied


def has_geometry(scene: Scene) -> bool:
    """Whether a goal command builds a geodesic field in this scene: it has walls, obstacles
    or a map (else the goal field is straight)."""
    return not scene.geometry.is_empty


def scene_map(scene: Scene) -> OccupancyMap | None:
    """The scene's map (its blocked cells), or None."""
    packed = scene.spec.get("map")
    return None if packed is None else map_from_spec(packed, "map", None)


class CommandsMixin:
    """Commands of :class:`~sweep_ros.node.SweepNode` (its attributes are the node's)."""

    _p: dict[str, Any]
    groups: Groups | None

    def _command(self, sub: Any, msg_class: type, raw: bytes, info: Any,
                 parse: Callable[[Any], Any], group: int | None = None,
                 built_for: Scene | None = None) -> None:
        """A command message: counted, parsed and validated here (command thread), then left
        in the inbox for the next step (latest wins; a group's command replaces that group's
        drift only). ``built_for``: the scene a navigation field is computed for by parse."""
        arrival = time.monotonic()
        topic = sub.topic_name
        self._inbox.arrived(topic, info)
        msg = None
        try:
            try:
                msg = deserialize_message(raw, msg_class)
            except Exception as err:  # noqa: BLE001 - any undecodable payload is refused
                raise messages.CommandError(topic, f"cannot decode ({err})") from err
            field = parse(msg)
        except messages.CommandError as err:
            self._inbox.refuse()
            self.get_logger().warning(f"command refused, {err}", throttle_duration_sec=2.0)
            self._verdict("refused", topic, results.command_id(info, msg), str(err))
            return
        ident = results.command_id(info, msg)
        if self.paused:  # said before the offer: a step cannot take it before this
            self._verdict("accepted", topic, ident, "accepted: the node is paused at step "
                          f"{self.sim.n_steps}; it applies from the next step taken",
                          paused=True)
        for old in self._inbox.offer(topic, field, bytes(raw), arrival, group,
                                     built_for if navigation_fields(field) else None, ident):
            self._verdict("superseded", old.topic, old.ident,
                          f"superseded by a newer command on {topic} before a step used it")

    def _verdict(self, verdict: str, topic: str, ident: Any, text: str,
                 log_ns: int | None = None, **extra: Any) -> None:
        """Publishes a command's verdict on command_result (:mod:`sweep_ros.results`) at the
        step the simulation is at (the one a command applies from, for ``applied``)."""
        self._results.verdict(verdict, topic, ident or results.CommandId(), text,
                              self.sim.n_steps, self.sim.t, topics.stamp_ns(self.sim.t),
                              self._last_log_ns if log_ns is None else log_ns, **extra)

    def _on_unknown_group(self, sub: Any, raw: bytes, info: Any) -> None:
        problem = graph.unknown_group_problem(sub.topic_name.rsplit("/", 1)[1],
                                              self.sub_goal.topic_name,
                                              self.unknown_groups.groups)

        def refuse(msg: Any) -> Field:
            raise messages.CommandError(sub.topic_name, problem)
        self._command(sub, PointStamped, raw, info, refuse)

    def _apply_command(self, applied: Applied) -> None:
        """Makes a command the drift from the step about to start; records it (the message on
        its topic and a ``command_NNNNNN`` metadata record) at that step's log time. The
        caller holds the gate."""
        cmd = applied.command
        field = cmd.field
        try:
            if cmd.built_for is not None and cmd.built_for is not self.scene:
                # a map arrived after the command's field was computed: again, round its walls
                field = self._navigation_field(field.to_spec(), cmd.group, cmd.topic,
                                               self.scene)
            drift = field if cmd.group is None else self._with_group(cmd.group, field)
        except (messages.CommandError, SceneError) as err:
            self._inbox.refuse_taken()
            self.get_logger().warning(f"command refused, {err}")
            self._verdict("refused", cmd.topic, cmd.ident, str(err))
            return
        self.sim.set_drift(drift)
        k = self._inbox.applied
        log_ns = self._log_ns(self.sim.t)
        self._verdict("applied", cmd.topic, cmd.ident,
                      f"applied from step {self.sim.n_steps} (t = {self.sim.t:g} s)", log_ns,
                      latency_ms=f"{1e3 * applied.latency_s:g}")
        self._record(cmd.topic, log_ns, cmd.raw)
        if self.recorder is not None:
            self.recorder.metadata(f"command_{k:06d}", {
                "topic": cmd.topic, "step": str(self.sim.n_steps), "t": repr(self.sim.t),
                "log_time_ns": str(log_ns), "field": json.dumps(drift.to_spec()),
                "latency_ms": f"{1e3 * applied.latency_s:g}",
                "superseded_before": str(applied.superseded)})
        self.get_logger().info(f"{cmd.topic}: {field.kind} field from step "
                               f"{self.sim.n_steps}", throttle_duration_sec=1.0)

    def _on_cmd_vel(self, raw: bytes, info: Any) -> None:
        self._command(self.sub_cmd_vel, Twist, raw, info,
                      lambda m: messages.uniform_from_twist(m, self._p["max_speed"],
                                                            self.sub_cmd_vel.topic_name))

    def _on_goal(self, raw: bytes, info: Any) -> None:
        self._goal_command(self.sub_goal, None, raw, info)

    def _on_group_goal(self, k: int, raw: bytes, info: Any) -> None:
        self._goal_command(self.sub_group_goals[k], k, raw, info)

    def _group_members(self, k: int) -> np.ndarray:
        """The agents (indices) of the scene's group k."""
        assert self.groups is not None  # group topics exist only for a scene with groups
        return self.groups.members[k]

    def _group_speed(self, k: int) -> float:
        """The preferred speed (m/s) of the scene's group k."""
        assert self.groups is not None
        return float(self.groups.speeds[k])

    def _with_group(self, k: int, field: Field) -> Field:
        """The drift in effect with group k following ``field``: a groups drift of the
        scene's groups is copied with that group's drift replaced; any other drift (a whole
        command in effect) goes on for the other groups and the rest, as a groups drift (built
        again for each group's agents when it holds a navigation field, as a replay of its
        spec builds it). The caller holds the gate."""
        assert self.groups is not None
        drift = self.sim.drift
        if isinstance(drift, Groups) and drift.names == self.groups.names:
            return drift.with_member_drift(k, field)
        base = dataclasses.replace(self.groups, fields=(drift,) * len(self.groups.fields),
                                   rest=drift).with_member_drift(k, field)
        if not navigation_fields(drift):
            return base
        return self.scene.drift_from_spec(base.to_spec())

    def _goal_command(self, sub: Any, group: int | None, raw: bytes, info: Any) -> None:
        """A goal for every agent (group None) or for the scene's group k: a geodesic field
        round the walls when the scene has any (computed here, on the executor's thread), a
        straight one otherwise, at the scene's speed or the group's."""
        scene, topic = self.scene, sub.topic_name

        def parse(msg: Any) -> Field:
            goal = messages.goal_point(msg, self.frame_id, topic)
            speed = self.scene.speed if group is None else self._group_speed(group)
            if not has_geometry(scene):
                return Goal(goal=goal, speed=float(speed),
                            slow_radius=float(self._p["goal_slow_radius"]))
            spec: dict[str, Any] = {
                "kind": "geodesic", "goal": goal.tolist(), "speed": float(speed),
                "slow_radius": self._p["goal_slow_radius"], "cell": self._p["goal_cell"],
                "wall_buffer": self._p["goal_wall_buffer"]}
            if self._p["goal_update_every"] > 0 and scene.geometry.is_moving:
                spec["update_every"] = self._p["goal_update_every"]
            return self._navigation_field(spec, group, topic, scene)

        self._command(sub, PointStamped, raw, info, parse, group, scene)

    def _navigation_field(self, spec: dict, group: int | None, topic: str, scene: Scene
                          ) -> Field:
        """A geodesic field of ``spec`` for the scene's walls, obstacles and map, checked
        against the initial positions of the agents that follow it (all, or group k's: the
        grid covers them, so a replay builds the same field)."""
        members = None if group is None else self._group_members(group)
        positions = scene.positions if members is None else scene.positions[members]
        try:
            return field_from_spec(spec, len(positions), "goal", scene.geometry,
                                   scene_map(scene), positions)
        except SceneError as err:
            raise messages.navigation_refusal(topic, err, members=members) from None

    def _on_velocity_field(self, raw: bytes, info: Any) -> None:
        self._command(self.sub_field, PointCloud2, raw, info,
                      lambda m: clouds.grid_from_cloud(m, self._p["max_speed"],
                                                         self.sub_field.topic_name))
