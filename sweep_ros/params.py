"""Parameters of sweep_node: specs, descriptors and validation, as pure functions.

Every parameter has a :class:`ParamSpec` (default, description, range, whether it may change
while the node runs). :func:`check_value` and :func:`check_start` return the problems of a value
or of the whole start-up set as ``"name: problem (fix: ...)"`` strings, reusing sweep_core's
validators; :func:`check_live` turns a set-parameters request into a ``SetParametersResult``.
The ``--params-file`` files are checked in :mod:`sweep_ros.params_files`. Nothing here touches
a node.
"""
from __future__ import annotations

import math
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    ParameterType,
    SetParametersResult,
)
from rclpy.exceptions import InvalidTopicNameException
from rclpy.validate_topic_name import validate_topic_name

from sweep_core import SceneError, SolverOptions
from sweep_core.errors import show
from sweep_core.io.limits import DT_MAX, DT_MIN
from sweep_core.model import geodesic
from sweep_core.model.gallery import resolve_scene_path
from sweep_core.numerics.projection.options import check_backend

_INT64_MAX = 2**63 - 1


@dataclass(frozen=True)
class ParamSpec:
    """One parameter: name, default (its type is the parameter's type), description, inclusive
    range (numbers only), and whether it may change while running (``live``)."""

    name: str
    default: Any
    description: str
    live: bool
    lo: float | int | None = None
    hi: float | int | None = None
    constraints: str = ""

    @property
    def type(self) -> type:
        return type(self.default)


_DEFAULT_SOLVER = SolverOptions()

SPECS: tuple[ParamSpec, ...] = (
    ParamSpec("scene", "", "Scene YAML file, or a bundled scene's name (sweep scenes) when no "
              "such file exists; empty = the bundled room with a door (200 agents).",
              False, constraints="readable scene YAML or a bundled scene's name"),
    ParamSpec("map_topic", "", "nav_msgs/OccupancyGrid topic (e.g. map, as nav2's map_server "
              "publishes it, transient-local) whose maps replace the scene's map walls between "
              "two steps; empty = off.", False,
              constraints="a ROS topic name, or empty"),
    ParamSpec("dt", 0.01, "Time step h of the projected Euler scheme, s.", False, DT_MIN, DT_MAX),
    ParamSpec("seed", 0, "Seed of the Brownian path; reset restarts it.", False, 0, _INT64_MAX),
    ParamSpec("rate_hz", 20.0, "Timer rate, Hz: each tick steps, then publishes poses, agents "
              "and clock once.", True, 0.1, 1000.0),
    ParamSpec("steps_per_tick", 5, "Steps per tick when real_time_factor is 0 (simulated time "
              "per tick = steps_per_tick * dt).", True, 1, 10000),
    ParamSpec("real_time_factor", 0.0, "0: fixed steps_per_tick. > 0: step as needed to keep "
              "simulated time = real_time_factor x wall time (at most max_steps_per_tick per "
              "tick; a tick that cannot keep up counts as an overrun).", True, 0.0, 1000.0),
    ParamSpec("max_steps_per_tick", 50, "Cap on steps per tick in real-time-factor mode.", True,
              1, 10000),
    ParamSpec("frame_id", "map", "frame_id of every published header.", False,
              constraints="non-empty, no spaces, no leading '/'"),
    ParamSpec("odom_frame_id", "odom", "A robot's odometry frame (REP 105); NAME/odom_frame_id "
              "when the scene has several robots.", False, constraints="a frame id"),
    ParamSpec("base_frame_id", "base_link", "A robot's body frame (REP 105); "
              "NAME/base_frame_id when the scene has several robots.", False,
              constraints="a frame id"),
    ParamSpec("enable_stamped_cmd_vel", True, "A robot's NAME/cmd_vel is "
              "geometry_msgs/TwistStamped (true, as Nav2 sends it) or Twist (false).", False),
    ParamSpec("cmd_vel_timeout", 1.0, "A robot stops when its newest NAME/cmd_vel is older "
              "than this, s of simulated time.", True, 1e-6, 1e6),
    ParamSpec("record", "", "MCAP file to record every published and received message to; "
              "empty = no recording. Relative paths are relative to the working directory.",
              False, constraints="its folder must exist"),
    ParamSpec("record_overwrite", False, "Replace the record file when it exists (false: the "
              "node refuses to start rather than replace a recording).", False),
    ParamSpec("record_flush_interval_s", 1.0, "Close an MCAP chunk and flush it to disk at least "
              "this often, s (what a SIGKILL can lose).", False, 0.05, 60.0),
    ParamSpec("publish_markers", True, "Publish the markers topic (one cylinder per agent).",
              True),
    ParamSpec("marker_rate_hz", 2.0, "Maximum rate of the markers topic, Hz.", True, 0.01, 100.0),
    ParamSpec("marker_height", 1.0, "Height of agent and wall markers, m.", True, 0.01, 10.0),
    ParamSpec("publish_clock", False, "Publish rosgraph_msgs/Clock (simulated time) on clock "
              "every tick.", False),
    ParamSpec("name_check_s", 1.0, "At start, watch the ROS graph this long (s) for another "
              "node with this node's name and namespace, and refuse to start if one shows up "
              "that started before this one; later, the later of two such nodes stops when "
              "discovery joins them; 0 = do not look.", False, 0.0, 60.0),
    ParamSpec("noise_sigma", -1.0, "Noise intensity sigma, m/sqrt(s), for every agent; -1 = the "
              "scene's own (possibly per-agent) sigma.", True, -1.0, 100.0,
              "-1 or >= 0"),
    ParamSpec("max_speed", 10.0, "Velocity commands whose speed exceeds this (m/s) are refused.",
              True, 1e-3, 1000.0),
    ParamSpec("goal_slow_radius", 0.5, "Radius (m) inside which a goal field slows down "
              "linearly, for the next goal command.", True, 0.01, 100.0),
    ParamSpec("goal_cell", geodesic.CELL, "Grid cell (m) of the geodesic field a goal command "
              "builds in a scene with walls, obstacles or a map (finer: more exact, slower to "
              "build).", True, 0.001, 100.0,
              f"goal_wall_buffer >= {geodesic.buffer_cells(geodesic.NEIGHBOURS):.4g} x goal_cell"),
    ParamSpec("goal_wall_buffer", geodesic.WALL_BUFFER, "Distance (m) the geodesic field of a "
              "goal command keeps from walls, obstacles and blocked map cells (a passage "
              "narrower than twice it is closed to it).", True, 0.001, 100.0,
              f">= {geodesic.buffer_cells(geodesic.NEIGHBOURS):.4g} x goal_cell"),
    ParamSpec("goal_update_every", 0.0, "With moving obstacles: the geodesic field of a goal "
              "command is computed again for the obstacles' positions every this many seconds "
              "of simulated time; 0 = never (they count where they are at t = 0).",
              True, 0.0, 1e6),
    ParamSpec("solver_eps_abs", _DEFAULT_SOLVER.eps_abs, "QP tolerance of the projection, m.",
              False, 1e-15, 1e-9),
    ParamSpec("solver_max_iter", _DEFAULT_SOLVER.max_iter, "QP iterations before the exact "
              "fallback solver.", False, 1, 1000000),
    ParamSpec("solver_exact_vars", _DEFAULT_SOLVER.exact_vars, "Contact clusters of up to this "
              "many variables (2 per agent) are solved exactly by the active-set solver; larger "
              "ones by the interior-point backend, whose answer is refined and certified the "
              "same way (its proved bound is in the diagnostics: up to 3.5e-7 m in a jam of "
              "1000 equal disks at a door).",
              False, 0, 100000),
    ParamSpec("solver_backend", _DEFAULT_SOLVER.backend, "QP solver (through qpsolvers) of "
              "the contact clusters too large for the exact active-set solver: any installed "
              "one (piqp, clarabel, osqp, proxqp, ...).", False,
              constraints="the name of an installed QP solver"),
    ParamSpec("solver_tol", _DEFAULT_SOLVER.tol, "Certified accuracy of each projection, m: "
              "every step's distance to the exact projection is proved below it where rounding "
              "allows (the bound proved is 'bound' in diagnostics); 1e-4 makes jams cheaper.",
              False, 1e-12, 1.0),
    ParamSpec("solver_max_rounds", _DEFAULT_SOLVER.max_rounds, "Rounds of the certified solver "
              "per step before uncertified clusters go to the exact or interior-point solvers.",
              False, 0, 100000),
)

BY_NAME: dict[str, ParamSpec] = {s.name: s for s in SPECS}
LIVE = frozenset(s.name for s in SPECS if s.live)


def defaults() -> dict[str, Any]:
    return {s.name: s.default for s in SPECS}


def descriptor(spec: ParamSpec) -> ParameterDescriptor:
    """The ParameterDescriptor of a spec: type, description, range, constraints."""
    kinds = {bool: ParameterType.PARAMETER_BOOL, int: ParameterType.PARAMETER_INTEGER,
             float: ParameterType.PARAMETER_DOUBLE, str: ParameterType.PARAMETER_STRING}
    extra = [spec.constraints] if spec.constraints else []
    if not spec.live:
        extra.append("fixed at start: restart the node to change it")
    d = ParameterDescriptor(name=spec.name, type=kinds[spec.type],
                            description=spec.description,
                            additional_constraints="; ".join(extra))
    if spec.lo is not None:
        if spec.type is float:
            d.floating_point_range = [FloatingPointRange(from_value=float(spec.lo),
                                                         to_value=float(spec.hi), step=0.0)]
        else:
            d.integer_range = [IntegerRange(from_value=int(spec.lo), to_value=int(spec.hi),
                                            step=1)]
    return d


def _range_text(spec: ParamSpec) -> str:
    return f"[{spec.lo:g}, {spec.hi:g}]"


def check_value(name: str, value: Any) -> str | None:
    """The problem with one value (``"name: problem (fix: ...)"``), or None if it is valid."""
    spec = BY_NAME.get(name)
    if spec is None:
        return None
    want = spec.type
    ok_type = (isinstance(value, want) and not (want is not bool and isinstance(value, bool)))
    if want is float and isinstance(value, int) and not isinstance(value, bool):
        ok_type, value = True, float(value)
    if not ok_type:
        return (f"{name}: must be of type {want.__name__}, got {show(value)} "
                f"({type(value).__name__}) (fix: write it as {spec.default!r} is written)")
    if want in (int, float) and spec.lo is not None:
        fix = f"set {name} to a value in {_range_text(spec)}: {spec.description}"
        if want is float and not math.isfinite(value):
            return f"{name}: must be finite, got {show(value)} (fix: {fix})"
        if not spec.lo <= value <= spec.hi:
            return f"{name}: {show(value)} is outside {_range_text(spec)} (fix: {fix})"
    if name == "noise_sigma" and value != -1.0 and value < 0:
        return (f"{name}: must be -1 (the scene's sigma) or >= 0, got {show(value)} "
                f"(fix: set {name} to -1 or to a sigma >= 0, m/sqrt(s))")
    if name in ("frame_id", "odom_frame_id", "base_frame_id"):
        if not value or value.startswith("/") or any(c.isspace() for c in value):
            return (f"{name}: {value!r} is not a valid frame id "
                    "(fix: non-empty, no spaces, no leading '/', e.g. 'map')")
    if name == "record" and value:
        folder = os.path.dirname(os.path.abspath(os.path.expanduser(value))) or "."
        if not os.path.isdir(folder):
            return f"{name}: folder {folder!r} does not exist (fix: create it or record elsewhere)"
        if os.path.isdir(os.path.expanduser(value)):
            return f"{name}: {value!r} is a folder (fix: give a file path ending in .mcap)"
    if name == "map_topic" and value:
        try:
            validate_topic_name(value)
        except InvalidTopicNameException:
            return (f"{name}: {value!r} is not a valid topic name (fix: letters, digits, '_' "
                    "and '/', e.g. 'map', or '' for no map subscription)")
    if name == "solver_backend":
        try:
            check_backend(value, name)
        except SceneError as err:
            return str(err)
    if name == "scene" and value:
        try:  # a bundled scene's name (sweep scenes) when no such file exists
            path = resolve_scene_path(os.path.expanduser(value))
        except SceneError as err:
            return f"{name}: {err}"
        if not path.is_file():
            return (f"{name}: no file {value!r} (fix: give a scene YAML path, a bundled "
                    "scene's name, or '' for the default)")
    return None


def solver_options(values: Mapping[str, Any]) -> SolverOptions:
    """SolverOptions from the solver_* parameters (raises SceneError naming solver.*)."""
    return SolverOptions.from_values(values["solver_eps_abs"], values["solver_max_iter"],
                                     backend=values["solver_backend"],
                                     exact_vars=values["solver_exact_vars"],
                                     tol=values["solver_tol"],
                                     max_rounds=values["solver_max_rounds"])


def check_goal_grid(values: Mapping[str, Any]) -> str | None:
    """The problem of goal_cell with goal_wall_buffer (a grid step of the geodesic field must
    not cross a thin wall unseen: wall_buffer >= half the longest step), or None."""
    cell, buffer = values["goal_cell"], values["goal_wall_buffer"]
    cells = geodesic.buffer_cells(geodesic.NEIGHBOURS)
    if buffer < cells * cell:
        return (f"goal_cell: {cell:g} m is too coarse for goal_wall_buffer {buffer:g} m (a grid "
                f"step could cross a thin wall unseen) (fix: set goal_cell to at most "
                f"{buffer / cells:.4g} m or goal_wall_buffer to at least {cells * cell:.4g} m)")
    return None


def check_start(values: Mapping[str, Any]) -> list[str]:
    """Problems of a complete start-up parameter set (empty when it is valid)."""
    problems = [p for p in (check_value(k, v) for k, v in values.items()) if p]
    if not any(p.startswith("solver_") for p in problems):
        try:
            solver_options(values)
        except SceneError as err:
            problems.append(str(err).replace("solver.", "solver_"))  # parameter names
    if not any(p.startswith("goal_") for p in problems):
        problems += [p for p in (check_goal_grid(values),) if p]
    return problems


def check_live(changes: Iterable[tuple[str, Any]], current: Mapping[str, Any]
               ) -> SetParametersResult:
    """Accept a set-parameters request only if every change is live-safe and valid."""
    changes = list(changes)
    reasons = []
    for name, value in changes:
        spec = BY_NAME.get(name)
        if spec is None:
            continue  # not ours (use_sim_time, ...): rclpy's own checks apply
        if not spec.live and value != current.get(name):
            reasons.append(f"{name}: cannot change while running (fix: restart the node with "
                           f"the new value)")
            continue
        problem = check_value(name, value)
        if problem:
            reasons.append(problem)
    changed = dict(changes)
    if not reasons and {"goal_cell", "goal_wall_buffer"} & set(changed):
        problem = check_goal_grid({**current, **changed})
        if problem:
            reasons.append(problem)
    return SetParametersResult(successful=not reasons, reason="; ".join(reasons))
