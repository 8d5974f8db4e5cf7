"""sweep_node: the ROS 2 adapter of sweep_core.

    ros2 run sweep_ros sweep_node --ros-args --params-file config/sweep_node.yaml

A thin adapter: a timer steps the engine and publishes its state; commands are parsed and
validated by :mod:`sweep_ros.messages` and handed to the engine as fields; parameters are
checked by :mod:`sweep_ros.params`; every published message and every command applied is
recorded to MCAP by a background writer thread, so the timer never waits on the disk. The
node's topics, services and parameters are described in docs/node.md;
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

The node is one Node subclass whose jobs live in modules of their own, as mixins sharing its
state: :mod:`.recording` (the MCAP and the publish-and-record helpers), :mod:`.publishing`
(state, walls, navigation field), :mod:`.diagnostics`, :mod:`.stepping` (the step thread),
:mod:`.commands` (crowd commands and their verdicts), :mod:`.maps` (map_topic) and
:mod:`.services` (reset, pause, step, live parameters). This module builds the interfaces and
closes the node; message layouts live in :mod:`.messages`, :mod:`.clouds` and :mod:`.markers`.
"""
from __future__ import annotations

import math
import os
import re
import threading
import time
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PointStamped, PoseArray, Twist
from nav_msgs.msg import OccupancyGrid
from rclpy.clock import Clock as RosClock
from rclpy.clock import ClockType
from rclpy.exceptions import InvalidTopicNameException, ParameterException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import PointCloud2
from std_srvs.srv import SetBool, Trigger
from visualization_msgs.msg import MarkerArray

from sweep_core import SceneError, Simulator
from sweep_core.io import markers as marker_content
from sweep_core.io import topics
from sweep_core.io.metadata import STATUS_RECORD, status_metadata
from sweep_core.io.recording import BackgroundRecorder
from sweep_core.model.fields import Field, Groups
from sweep_core.model.scene import load_scene
from sweep_core.numerics import kernels
from sweep_ros import graph, params, results
from sweep_ros.commands import CommandsMixin, has_geometry, scene_map
from sweep_ros.diagnostics import DiagnosticsMixin
from sweep_ros.errors import StartError
from sweep_ros.gate import StepGate
from sweep_ros.inbox import CommandInbox
from sweep_ros.maps import MapsMixin
from sweep_ros.publishing import PublishingMixin
from sweep_ros.recording import RecordingMixin
from sweep_ros.robots import RESERVED_NAMES, RobotsMixin, robot_names
from sweep_ros.services import ServicesMixin
from sweep_ros.stepping import SteppingMixin
from sweep_ros.timing import Window

__all__ = ["NODE_NAME", "SweepNode", "has_geometry", "scene_map"]

NODE_NAME = "sweep_node"
DIAGNOSTICS_PERIOD_S = 1.0
#: depth of the command subscriptions' queues: room for a burst while the executor's thread
#: waits (for the gate, at most one step); under latest-wins only the newest matters, and what
#: a full queue drops is counted (diagnostics: commands_lost) where the middleware gives
#: publication sequence numbers
COMMAND_QUEUE_DEPTH = 100
#: the crowd's uniform velocity command: off the name ``cmd_vel``, which ROS users expect to drive
#: a robot (each robot has its own, ``NAME/cmd_vel``)
CROWD_CMD_VEL = "crowd/cmd_vel"
#: rclpy's own parameters, never reported as unknown
_RCLPY_PARAMS = ("use_sim_time", "start_type_description_service", "qos_overrides.")


#: rclpy's refusal of a value of another type than the parameter's: the types as numbers
#: ('3', the ParameterType code, on Python >= 3.11) or as enum names ('Type.DOUBLE')
_WRONG_TYPE = re.compile(r"^Wrong parameter type, expected '(?:Type\.)?(\w+)' got "
                         r"'(?:Type\.)?(\w+)'$")


def type_name(code: str) -> str:
    """A parameter type as users write it (double, string, integer, bool, ...) from rclpy's
    code ('3') or enum name ('DOUBLE')."""
    kind = Parameter.Type(int(code)) if code.isdigit() else Parameter.Type[code]
    return kind.name.lower()


def typed_reason(name: str, reason: str) -> str:
    """rclpy's wrong-type refusal of parameter ``name`` said with type names and the fix;
    any other reason unchanged."""
    m = _WRONG_TYPE.match(reason)
    if m is None:
        return reason
    try:
        want, got = type_name(m.group(1)), type_name(m.group(2))
    except (KeyError, ValueError):
        return reason

    def a(kind: str) -> str:
        return ("an " if kind[0] in "aeiou" else "a ") + kind

    fix = (f"give {a(want)} value" if (want, got) != ("double", "integer") else
           "write the number with a decimal point, e.g. 1.0: 1 is an integer")
    return f"{name}: is {a(want)} parameter, got {a(got)} value (fix: {fix})"


class SweepNode(RecordingMixin, PublishingMixin, DiagnosticsMixin, SteppingMixin,
                CommandsMixin, MapsMixin, ServicesMixin, RobotsMixin, Node):
    """Runs a sweep_core Simulator on a timer; see the module docstring."""

    def set_parameters(self, parameter_list: list[Parameter]) -> list[Any]:
        """rclpy's, with a refusal of a value of the wrong type said with type names (rclpy
        gives the types' numeric codes): the SetParameters service and ros2 param set."""
        results = super().set_parameters(parameter_list)
        for p, r in zip(parameter_list, results):
            if not r.successful:
                r.reason = typed_reason(p.name, r.reason)
        return results

    def set_parameters_atomically(self, parameter_list: list[Parameter]) -> Any:
        """rclpy's, with the refusal said as by :meth:`set_parameters`."""
        result = super().set_parameters_atomically(parameter_list)
        if not result.successful:
            name = parameter_list[0].name if len(parameter_list) == 1 else "a parameter"
            result.reason = typed_reason(name, result.reason)
        return result

    def _later_of_two(self, problem: str) -> None:
        """A node of this name started before this one: this one stops (main's loop)."""
        if self.duplicate is None:
            self.duplicate = problem
            self.get_logger().error(problem)

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
            if self.sim.robots is not None:
                # the robots follow their cmd_vel topics only: a scene's controller: key is
                # for sweep run (it would override every command the node receives)
                self.sim.robots.controllers.clear()
        except SceneError as err:
            raise StartError([f"scene {self._p['scene'] or '(bundled default)'}: {err}"]) from err
        #: why this node stops: a node of its name started before it (:class:`graph.SameName`)
        self.duplicate: str | None = None
        if self._p["name_check_s"] > 0:  # 0: do not look
            self._same_name = graph.SameName(self, self._later_of_two)
            graph.check_unique_name(self, started + self._p["name_check_s"], self._same_name)
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
        self._published: tuple[int, int] | None = None  # (reset count, step) last published
        self._rt_anchor: tuple[float, float] | None = None
        self._window = Window(self.sim.t)
        self._maps_applied = 0
        self._maps_refused = 0
        self._map_problem: str | None = None  # the last refusal, for the next diagnostics
        #: the navigation_field last published: (its key, the drift it was of)
        self._navigation: tuple[tuple, Field | None] = ((), None)
        # moving walls and obstacles are republished with the markers, at their pose then
        self._moving_walls = marker_content.moving_walls(self.scene.geometry)
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
            Twist, CROWD_CMD_VEL, self._on_cmd_vel, inbound, raw=True)
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
        names = robot_names(self.scene)
        clash = [n for n in names if n in RESERVED_NAMES]
        if clash:
            raise StartError([f"scene {self._p['scene']}: robot name {clash[0]!r} is reserved "
                              f"for the crowd's commands (crowd/cmd_vel) (fix: rename the "
                              "robot)"])
        self._create_robot_topics(names, inbound, reliable)
        self.srv_reset = self.create_service(Trigger, "reset", self._on_reset)
        self.srv_pause = self.create_service(SetBool, "pause", self._on_pause)
        self.srv_step = self.create_service(Trigger, "step", self._on_step)
        self.srv_status = self.create_service(Trigger, "status", self._on_status)

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
        if self.robots:
            self._publish_tf_static()
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
