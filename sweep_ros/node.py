"""sweep_node: the ROS 2 adapter of sweep_core.

    ros2 run sweep_ros sweep_node --ros-args --params-file config/sweep_node.yaml

A thin adapter: a timer steps the engine and publishes its state; commands are parsed and
validated by :mod:`sweep_ros.messages` and handed to the engine as fields; parameters are
checked by :mod:`sweep_ros.params`; every published message and every command applied is
recorded to MCAP by a background writer thread, so the timer never waits on the disk. The
node's topics, services and parameters are described in the README (section "The ROS 2 node");
:mod:`sweep_ros.main` is the executable.

Threads: the ticks run on a thread of their own (:meth:`SweepNode._step_loop`, paced at
``rate_hz``); the executor's thread (:mod:`sweep_ros.main`, a SingleThreadedExecutor) takes
the services, the command subscriptions, the parameter services and the diagnostics timer, so
a long tick never holds up a service or a command. The engine and the adapter's state are
guarded by a :class:`~sweep_ros.gate.StepGate`: a tick takes its steps one at a time, holding
the gate for one step, and a service (pause, step, reset), a parameter change or diagnostics
waiting for it goes first at the next step boundary. So a service answers within one step's
time, and a state change such as reset takes effect between two steps, never inside one.
(rclpy's MultiThreadedExecutor with callback groups would do the same, but its dispatch cost
per message is higher: at 1 kHz of cmd_vel for 10 s it took 1 700 messages against 5 300 with
this layout, on a loaded 2-core machine; see test/node_load.py.) Commands are
latest-wins (:mod:`sweep_ros.inbox`): each replaces the drift field at the start of the next
step; one replaced before a step used it is counted as superseded. Each command gets a verdict
on ``command_result`` (:mod:`sweep_ros.results`: refused, accepted while paused, superseded,
applied from step k); goals for group names the scene does not have are found in the ROS graph
and refused by name (:mod:`sweep_ros.graph`, which also keeps a second node of the same name
from starting).

Maps (parameter ``map_topic``): each nav_msgs/OccupancyGrid is parsed and its walls built on
the executor's thread (:meth:`SweepNode._on_map`), then swapped into the simulator between two
steps like a reset (``Simulator.set_scene``: time, positions, drift, noise and the Brownian
path kept). The map replaces the scene's ``map`` entry (its other walls and obstacles stay),
and stays over resets. A map is refused, the old walls kept, when an agent at its current
position, or at its initial position (where a reset returns), would be in a blocked cell or
cut by a wall: the error names the agents, diagnostics count it (``map_refused``).

Goals and navigation fields: in a scene with walls, obstacles or a map (:func:`has_geometry`)
a ``goal`` builds a geodesic field round them (parameters ``goal_cell``, ``goal_wall_buffer``,
``goal_update_every``), else a straight one; ``goal/<name>`` does the same for one of the
scene's groups (``agents.groups``) at its speed, the others keeping their drift. The field is
computed on the executor's thread for the scene's initial positions (so a replay of the
recorded spec computes the same floats: :meth:`Scene.drift_from_spec`); a goal in a wall or out
of an agent's reach is refused like a malformed command. The ``navigation_field`` topic
(latched) carries the grid of the navigation fields of the drift in effect whenever it changes
(:func:`sweep_core.io.topics.encode_navigation`).

Longer than 400 lines because it is one Node subclass (the ros2/demos layout): its
constructor, callbacks, services and shutdown read together; the message building, parameter
checks and timing it uses live in :mod:`.messages`, :mod:`.params` and :mod:`.timing`.
"""
from __future__ import annotations

import dataclasses
import json
import math
import os
import threading
import time
import traceback
from collections.abc import Callable
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PointStamped, PoseArray, Twist
from nav_msgs.msg import OccupancyGrid
from rclpy.clock import Clock as RosClock
from rclpy.clock import ClockType
from rclpy.exceptions import InvalidTopicNameException, ParameterException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import PointCloud2
from std_srvs.srv import SetBool, Trigger
from visualization_msgs.msg import MarkerArray

from sweep_core import InfeasibleError, SceneError, Simulator, SweepError
from sweep_core.io import cdr, topics
from sweep_core.io.metadata import STATUS_RECORD, run_metadata, status_metadata
from sweep_core.io.recording import BackgroundRecorder, qos_profiles
from sweep_core.model.drift import field_from_spec
from sweep_core.model.fields import Field, Goal, Groups
from sweep_core.model.geodesic import navigation_fields
from sweep_core.model.maps import OccupancyMap, map_from_spec, replace_map
from sweep_core.model.scene import Scene, load_scene
from sweep_core.numerics import kernels
from sweep_ros import graph, messages, msgdefs, params, results
from sweep_ros.errors import StartError
from sweep_ros.gate import StepGate
from sweep_ros.inbox import Applied, CommandInbox
from sweep_ros.timing import Window

NODE_NAME = "sweep_node"
DIAGNOSTICS_PERIOD_S = 1.0
#: depth of the command subscriptions' queues: room for a burst while the executor's thread
#: waits (for the gate, at most one step); under latest-wins only the newest matters, and what
#: a full queue drops is counted (diagnostics: commands_lost) where the middleware gives
#: publication sequence numbers
COMMAND_QUEUE_DEPTH = 100
#: rclpy's own parameters, never reported as unknown
_RCLPY_PARAMS = ("use_sim_time", "start_type_description_service", "qos_overrides.")


def has_geometry(scene: Scene) -> bool:
    """Whether a goal command builds a geodesic field in this scene: it has walls, obstacles
    or a map (else the goal field is straight)."""
    return not scene.geometry.is_empty


def scene_map(scene: Scene) -> OccupancyMap | None:
    """The scene's map (its blocked cells), or None."""
    packed = scene.spec.get("map")
    return None if packed is None else map_from_spec(packed, "map", None)



class SweepNode(Node):
    """Runs a sweep_core Simulator on a timer; see the module docstring."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        started = time.monotonic()
        self._p = self._declare_parameters()
        self._closed = False
        self.recorder: BackgroundRecorder | None = None
        self._parameter_changes = 0
        try:
            self.scene = load_scene(os.path.expanduser(self._p["scene"]))
            #: the scene as loaded: a map received replaces its spec's map (as replay does)
            self.scene0 = self.scene
            self.sim = Simulator(self.scene, dt=self._p["dt"], seed=self._p["seed"],
                                 solver=params.solver_options(self._p))
        except SceneError as err:
            raise StartError([f"scene {self._p['scene'] or '(bundled default)'}: {err}"]) from err
        if self._p["name_check_s"] > 0:  # 0: do not look
            graph.check_unique_name(self, started + self._p["name_check_s"])
        self._apply_sigma()
        # every kernel a step, a goal's navigation field or a map can call, compiled (first
        # run on this machine) or loaded now: no command waits for a compile once ready
        self.warm_up = kernels.warm_up(self.get_logger().info)
        self._compiled_at_start = kernels.compiled_count()
        self.frame_id: str = self._p["frame_id"]
        self._dt_ns = topics.stamp_ns(self.sim.dt)

        # state of the adapter (no model state here: that is all in self.sim)
        self.paused = False
        self.failure: str | None = None
        self._epoch_ns = 0            # log-time offset: log times keep increasing over resets
        self._last_log_ns = 0
        self._resets = 0
        self._inbox = CommandInbox()
        self._lost_reported = 0
        self._overruns = 0
        self._last_tick_start: float | None = None
        self._last_markers = -math.inf
        self._rt_anchor: tuple[float, float] | None = None
        self._window = Window(self.sim.t)
        self._maps_applied = 0
        self._maps_refused = 0
        self._map_problem: str | None = None  # the last refusal, for the next diagnostics
        #: the navigation_field last published: (its key, the drift it was of)
        self._navigation: tuple[tuple, Field | None] = ((), None)
        # moving walls and obstacles are republished with the markers, at their pose then
        self._moving_walls = bool(self.scene.geometry.is_moving or (
            len(self.scene.geometry.halfplane_velocity)
            and (self.scene.geometry.halfplane_velocity != 0).any()))
        self._agent_markers = messages.AgentMarkers(self.frame_id, self._p["marker_height"])
        # threads: see the module docstring
        self._gate = StepGate()
        self._stopping = threading.Event()
        self._wake = threading.Event()  # a rate change or a stop ends the wait between ticks
        #: the error that ended the step thread, if one did (main then stops the node)
        self.crash: str | None = None

        # interfaces (relative names: namespaces and remapping apply)
        reliable = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        inbound = QoSProfile(depth=COMMAND_QUEUE_DEPTH, reliability=ReliabilityPolicy.RELIABLE)
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.pub_poses = self.create_publisher(PoseArray, topics.POSES, reliable)
        self.pub_agents = self.create_publisher(PointCloud2, topics.AGENTS, reliable)
        self.pub_markers = self.create_publisher(MarkerArray, "markers", reliable)
        self.pub_walls = self.create_publisher(MarkerArray, "walls", latched)
        # latched, so that a client reads the last one at once instead of waiting up to 1 s
        self.pub_diag = self.create_publisher(DiagnosticArray, "diagnostics", latched)
        self.pub_results = self.create_publisher(DiagnosticArray, results.TOPIC, results.QOS)
        self._results = results.CommandResults(self.pub_results,
                                               self.get_fully_qualified_name(), self._record)
        self.pub_navigation = self.create_publisher(PointCloud2, topics.NAVIGATION, latched)
        self.pub_clock = (self.create_publisher(Clock, "clock", reliable)
                          if self._p["publish_clock"] else None)
        self.sub_cmd_vel = self.create_subscription(
            Twist, "cmd_vel", self._on_cmd_vel, inbound, raw=True)
        self.sub_goal = self.create_subscription(
            PointStamped, "goal", self._on_goal, inbound, raw=True)
        #: the scene's groups (agents.groups), whose goals come on goal/<name>
        self.groups: Groups | None = (self.scene.drift if isinstance(self.scene.drift, Groups)
                                      else None)
        self.sub_group_goals = [
            self.create_subscription(PointStamped, f"goal/{name}",
                                     lambda raw, info, k=k: self._on_group_goal(k, raw, info),
                                     inbound, raw=True)
            for k, name in enumerate(self.groups.names if self.groups is not None else ())]
        #: goal/<name> for names that are no group of the scene, subscribed to refuse them
        self.unknown_groups = graph.UnknownGroups(
            self, self.sub_goal.topic_name,
            tuple(self.groups.names) if self.groups is not None else (), inbound,
            self._on_unknown_group)
        self.sub_field = self.create_subscription(
            PointCloud2, "velocity_field", self._on_velocity_field, inbound, raw=True)
        self.sub_map = None
        if self._p["map_topic"]:
            try:  # as nav2's map_server publishes it
                self.sub_map = self.create_subscription(OccupancyGrid, self._p["map_topic"],
                                                        self._on_map, latched, raw=True)
            except InvalidTopicNameException as err:
                raise StartError([f"parameter map_topic: {self._p['map_topic']!r} is not a "
                                  f"valid topic name ({err}) (fix: e.g. 'map')"]) from err
        self.srv_reset = self.create_service(Trigger, "reset", self._on_reset)
        self.srv_pause = self.create_service(SetBool, "pause", self._on_pause)
        self.srv_step = self.create_service(Trigger, "step", self._on_step)

        if self._p["record"]:
            self._open_recording()

        self.add_on_set_parameters_callback(self._check_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)
        # on the steady clock: with use_sim_time the node's ROS clock follows /clock, which
        # stands still while paused (or, without publish_clock, never starts)
        steady = RosClock(clock_type=ClockType.STEADY_TIME)
        self._diag_timer = self.create_timer(DIAGNOSTICS_PERIOD_S, self._on_diag_timer,
                                             clock=steady)
        self._graph_timer = self.create_timer(graph.GRAPH_PERIOD_S, self.unknown_groups.watch,
                                              clock=steady)

        self._publish_walls()
        self._publish_state(force_markers=True)
        self.get_logger().info(
            f"scene {self.scene.name!r} ({self.scene.n_agents} agents), dt {self.sim.dt:g} s, "
            f"seed {self.sim.seed}, {self._p['rate_hz']:g} Hz x {self._p['steps_per_tick']} "
            f"steps, recording: {self._p['record'] or 'off'}"
            + (f", maps from {self.sub_map.topic_name}" if self.sub_map is not None else "")
            + f"; kernels ready in {self.warm_up.seconds:.1f} s; ready")
        self._step_thread = threading.Thread(target=self._step_loop, name="sweep steps",
                                             daemon=True)
        self._step_thread.start()

    # -- start-up ------------------------------------------------------------------------------
    def _declare_parameters(self) -> dict[str, Any]:
        problems = []
        for spec in params.SPECS:
            try:
                self.declare_parameter(spec.name, spec.default, params.descriptor(spec))
            except ParameterException as err:  # wrong type or out of range in the overrides
                problems.append(f"parameter {spec.name}: {err}")
        if problems:
            raise StartError(problems)
        values = {s.name: self.get_parameter(s.name).value for s in params.SPECS}
        problems = [f"parameter {p}" for p in params.check_start(values)]
        if problems:
            raise StartError(problems)
        overrides = getattr(self, "_parameter_overrides", {}) or {}
        unknown = sorted(n for n in overrides if n not in params.BY_NAME
                         and not n.startswith(_RCLPY_PARAMS))
        if unknown:
            self.get_logger().warning(f"unknown parameters ignored: {unknown} "
                                      f"(known: {sorted(params.BY_NAME)})")
        return values

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
        latched = {self.pub_walls.topic_name: 1, self.pub_navigation.topic_name: 1,
                   self.pub_diag.topic_name: 1, self.pub_results.topic_name: results.DEPTH}
        if self.sub_map is not None:
            latched[self.sub_map.topic_name] = 1
        meta.update({
            "node": self.get_fully_qualified_name(),
            "parameters": json.dumps(self._p, sort_keys=True),
            "frame_id": self.frame_id,
            "topics": json.dumps(names, sort_keys=True),
            "log_time": "simulation time (ns) of the state or of the step a command applies to; "
                        "after a reset log times go on from the last one (records reset_*)",
        })
        try:
            scene_file = os.path.expanduser(self._p["scene"]) if self._p["scene"] else None
            map_file = (self.scene.spec.get("map") or {}).get("source")
            self.recorder = BackgroundRecorder(
                os.path.expanduser(self._p["record"]), metadata=meta,
                flush_interval_s=self._p["record_flush_interval_s"],
                inputs=[scene_file, map_file if map_file and os.path.isfile(map_file) else None],
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

    def _apply_sigma(self) -> None:
        sigma = self._p["noise_sigma"]
        self.sim.set_sigma(self.scene.sigma if sigma == -1.0 else sigma)

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

    # -- publishing --------------------------------------------------------------------------
    def _publish_state(self, force_markers: bool = False) -> None:
        state = self.sim.state
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
            self._publish(self.pub_markers,
                          self._agent_markers.encode(ns, state.positions, state.radii), log_ns)
            if self._moving_walls:
                self._publish_walls()
        self._publish_navigation()

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
        msg = messages.wall_markers(self.scene.geometry, self.scene.positions, self.frame_id,
                                    topics.stamp_ns(t), t, self._p["marker_height"])
        if clear:
            msg.markers.insert(0, messages.delete_all(self.frame_id, topics.stamp_ns(t),
                                                      "walls").markers[0])
        self._publish(self.pub_walls, bytes(serialize_message(msg)), self._log_ns(t))

    def _on_diag_timer(self) -> None:
        with self._gate.control():
            if not self._closed:
                self._publish_diagnostics()

    def _publish_diagnostics(self) -> None:
        """Publishes (and records) one diagnostics message; the caller holds the gate."""
        w, now = self._window, time.monotonic()
        wall = max(now - w.wall0, 1e-9)
        sim, rec = self.sim, self.recorder
        counters = self._inbox.counters()
        lost = counters["commands_lost"]
        new_lost = lost - self._lost_reported if isinstance(lost, int) else 0
        same_name = graph.same_name_count(self)
        if self.failure:
            level, message = "ERROR", f"infeasible, paused: {self.failure}"
        elif same_name > 1:
            level, message = "WARN", (f"{same_name} nodes named "
                                      f"{self.get_fully_qualified_name()} on this ROS domain: "
                                      "services and commands reach all of them")
        elif rec is not None and rec.error:
            level, message = "WARN", f"recording stopped: {rec.error}"
        elif self._map_problem:
            level, message = "WARN", self._map_problem
        elif w.overruns:
            level, message = "WARN", f"{w.overruns} timer overruns in the last {wall:.1f} s"
        elif new_lost > 0:
            level, message = "WARN", (f"{new_lost} commands never reached the node in the last "
                                      f"{wall:.1f} s (subscription queue full; latest wins)")
        else:
            level, message = "OK", "paused" if self.paused else "running"
        if isinstance(lost, int):
            self._lost_reported = lost
        values = {
            "sim_time_s": sim.t, "steps": sim.n_steps, "agents": self.scene.n_agents,
            "paused": self.paused,
            "step_time_ms": 1e3 * w.step_s / w.steps if w.steps else 0.0,
            "steps_per_s": w.steps / wall,
            "tick_rate_hz": w.ticks / wall,
            "tick_time_ms": 1e3 * w.tick_s / w.ticks if w.ticks else 0.0,
            "real_time_factor": (sim.t - w.sim0) / wall,
            "timer_overruns": self._overruns,
            "active_contacts": sim.contacts,
            "backend_agents": sim.backend_agents,
            "projection_bound_m": sim.bound,
            "min_gap_m": sim.min_gap,
            "drift": sim.drift.kind,
            "compile_s": self.warm_up.seconds,
            "kernels_compiled_late": kernels.compiled_count() - self._compiled_at_start,
            **counters,
            "command_results": self._results.published,
            "resets": self._resets,
            "maps_applied": self._maps_applied,
            "map_refused": self._maps_refused,
            "recording": rec.path if rec is not None else "off",
            "recording_backlog": rec.backlog if rec is not None else 0,
            "recorded_messages": rec.written if rec is not None else 0,
        }
        msg = messages.diagnostics(topics.stamp_ns(sim.t), f"{self.get_name()}: simulation",
                                   self.scene.name, level, message, values)
        self._publish(self.pub_diag, bytes(serialize_message(msg)), self._log_ns(sim.t))
        self._window = Window(sim.t)
        self._map_problem = None

    # -- stepping ------------------------------------------------------------------------------
    def _steps_this_tick(self, now: float) -> int:
        rtf = self._p["real_time_factor"]
        if rtf <= 0:
            return self._p["steps_per_tick"]
        if self._rt_anchor is None:
            self._rt_anchor = (now, self.sim.t)
        wall0, sim0 = self._rt_anchor
        behind = sim0 + rtf * (now - wall0) - self.sim.t
        steps = int(math.floor(behind / self.sim.dt + 1e-9))
        cap = self._p["max_steps_per_tick"]
        if steps > cap:
            self._window.overruns += 1
            self._overruns += 1
            if behind > rtf * 1.0 + cap * self.sim.dt:  # more than 1 s behind: give it up
                self._rt_anchor = (now, self.sim.t + cap * self.sim.dt)
            steps = cap
        return max(steps, 0)

    def _advance(self) -> bool:
        """Take one step, after applying the newest waiting command; on an infeasible step
        pause and report (the state stays at the last accepted step, which is published).
        The caller holds the gate. Returns whether the step was taken."""
        while (applied := self._inbox.take()) is not None:
            self._apply_command(applied)
        start = time.perf_counter()
        try:
            self.sim.step(1)
            self.failure = None
        except (InfeasibleError, SceneError) as err:
            self.failure = str(err)
            self.paused = True
            self._rt_anchor = None
            self.get_logger().error(f"step {self.sim.n_steps + 1} failed, simulation paused: "
                                    f"{err}")
            self._publish_diagnostics()
            return False
        self._window.steps += 1
        self._window.step_s += time.perf_counter() - start
        return True

    def _step_loop(self) -> None:
        """The step timer: a tick every 1 / rate_hz s (read at every tick) until the node
        stops; after a tick that overran its period the next starts at once (_tick counts
        the periods missed). An exception ends the loop and is kept in ``crash``."""
        next_start = time.monotonic()
        try:
            while not self._stopping.is_set():
                self._tick()
                next_start += 1.0 / self._p["rate_hz"]
                now = time.monotonic()
                if next_start <= now:
                    next_start = now
                elif self._wake.wait(next_start - now):
                    self._wake.clear()
                    next_start = time.monotonic()
        except Exception as err:  # noqa: BLE001 - reported by main, which stops the node
            self.crash = f"{type(err).__name__}: {err}"
            self.get_logger().error(f"step thread stopped: {traceback.format_exc()}")

    def _tick(self) -> None:
        """One timer tick: its steps one at a time (the gate held for one step each), then
        the state. A pause, reset or stop between two steps ends the tick there."""
        start = time.monotonic()
        with self._gate.step():
            period = 1.0 / self._p["rate_hz"]
            if self._last_tick_start is not None:
                missed = int((start - self._last_tick_start) / period + 0.5) - 1
                if missed > 0:
                    self._overruns += missed
                    self._window.overruns += missed
            self._last_tick_start = start
            if self.paused or self._closed:
                return
            n = self._steps_this_tick(start)
            segment = self._resets
        taken = 0
        for _ in range(n):
            with self._gate.step():
                if (self.paused or self._stopping.is_set() or self._closed
                        or self._resets != segment or not self._advance()):
                    break
            taken += 1
        with self._gate.step():
            if taken and self._resets == segment and not self._closed:
                self._publish_state()
            self._window.ticks += 1
            self._window.tick_s += time.monotonic() - start

    # -- commands ------------------------------------------------------------------------------
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
                      lambda m: messages.grid_from_cloud(m, self._p["max_speed"],
                                                         self.sub_field.topic_name))

    # -- maps ----------------------------------------------------------------------------------
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

    # -- services (each between two steps: see the module docstring) ---------------------------
    def _on_reset(self, request: Trigger.Request, response: Trigger.Response
                  ) -> Trigger.Response:
        with self._gate.control():
            before = (self.sim.n_steps, self.sim.t)
            self._epoch_ns = self._last_log_ns + self._dt_ns
            for old in self._inbox.discard_all():  # not yet applied: superseded by the reset
                self._verdict("superseded", old.topic, old.ident,
                              "superseded by a reset before a step used it")
            self.sim.reset()
            self._apply_sigma()
            self.failure = None
            self._rt_anchor = None
            self._resets += 1
            if self.recorder is not None:
                self.recorder.metadata(f"reset_{self._resets:06d}", {
                    "log_time_ns": str(self._epoch_ns), "previous_step": str(before[0]),
                    "previous_t": repr(before[1]), "seed": str(self.sim.seed)})
            if self._p["publish_markers"]:
                clear = messages.delete_all(self.frame_id, 0)
                self._publish(self.pub_markers, bytes(serialize_message(clear)),
                              self._log_ns(0.0))
            self._publish_walls()
            self._publish_state(force_markers=True)
            response.success = True
            response.message = (f"reset to t = 0 with seed {self.sim.seed} (was step "
                                f"{before[0]}, t = {before[1]:g} s); drift back to the scene's "
                                f"{self.sim.drift.kind}")
        return response

    def _on_pause(self, request: SetBool.Request, response: SetBool.Response
                  ) -> SetBool.Response:
        self.paused = bool(request.data)  # seen by the tick at its next step boundary
        with self._gate.control():
            self.paused = bool(request.data)
            self._rt_anchor = None
            response.success = True
            response.message = (f"{'paused' if self.paused else 'running'} at step "
                                f"{self.sim.n_steps}, t = {self.sim.t:g} s")
        return response

    def _on_step(self, request: Trigger.Request, response: Trigger.Response
                 ) -> Trigger.Response:
        with self._gate.control():
            if not self.paused:
                response.success = False
                response.message = "not paused (fix: call pause with data: true first)"
            elif self._advance():
                self._publish_state(force_markers=True)
                response.success = True
                response.message = f"step {self.sim.n_steps}, t = {self.sim.t:g} s"
            else:
                response.success = False
                response.message = f"step failed: {self.failure}"
        return response

    # -- parameters ------------------------------------------------------------------------------
    def _check_parameters(self, changes: list) -> Any:
        return params.check_live([(p.name, p.value) for p in changes], self._p)

    def _apply_parameters(self, changes: list) -> None:
        with self._gate.control():
            for p in changes:
                if p.name in params.BY_NAME:
                    self._apply_parameter(p.name, p.value)

    def _apply_parameter(self, name: str, value: Any) -> None:
        old = self._p.get(name)
        self._p[name] = value
        if value == old:
            return
        if name == "rate_hz":
            self._last_tick_start = None
            self._wake.set()  # the step thread starts the next tick now, at the new period
        elif name == "noise_sigma":
            self._apply_sigma()
            if self.recorder is not None:  # replay needs every live change of the model
                self._parameter_changes += 1
                self.recorder.metadata(f"parameter_{self._parameter_changes:06d}", {
                    "name": name, "value": json.dumps(value),
                    "step": str(self.sim.n_steps),
                    "log_time_ns": str(self._log_ns(self.sim.t))})
        elif name == "marker_height":
            self._agent_markers = messages.AgentMarkers(self.frame_id, value)
            self._publish_walls()
        elif name in ("real_time_factor", "max_steps_per_tick"):
            self._rt_anchor = None
        self.get_logger().info(f"parameter {name} = {value!r}")

    # -- shutdown --------------------------------------------------------------------------------
    def request_stop(self) -> None:
        """Ends the tick in progress at its next step boundary and the step thread after it
        (any thread, signal-safe)."""
        self._stopping.set()
        self._wake.set()

    def close(self, status: str = "completed", reason: str = "") -> None:
        """Stops the timers and closes the recording cleanly (idempotent), after the step in
        progress. The recording gets a ``summary`` and a ``sweep_status`` metadata record: status
        ``completed`` (the ROS context was shut down), ``interrupted`` (a signal; ``error``
        names it) or ``failed`` (``error``: the error); ``simulation_error`` is the infeasible step the
        node is paused on, if any."""
        self.request_stop()
        if self._step_thread.is_alive() and threading.current_thread() is not self._step_thread:
            self._step_thread.join()  # after the step in progress
        with self._gate.control():
            if self._closed:
                return
            self._closed = True
            self._diag_timer.cancel()
            self._graph_timer.cancel()
            if self.recorder is None:
                return
            counters = {k: str(v) for k, v in self._inbox.counters().items()}
            self.recorder.metadata("summary", {
                "steps": str(self.sim.n_steps), "t": repr(self.sim.t),
                "resets": str(self._resets), "timer_overruns": str(self._overruns),
                **counters})
            # the record sweep run writes too, so that sweep analyze reports node runs
            self.recorder.metadata(STATUS_RECORD, {
                **status_metadata(status, steps=self.sim.n_steps, t=self.sim.t, error=reason),
                "log_time_ns": str(self._last_log_ns),
                "simulation_error": self.failure or ""})
            self.recorder.close()  # an error is logged once, when it happens (on_error)
