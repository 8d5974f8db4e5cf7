"""Refusals about robots said in the scene's own terms: a controller's refusal of a robot's goal
(``goal_refusal``), and what new walls would do to the robots where they are
(``geometry_problem``, for ``Simulator.set_scene`` and the node's maps)."""
from __future__ import annotations

import math
import re
from typing import Any

import numpy as np

from sweep_core.errors import SceneError, show
from sweep_core.model.geodesic import CELL, NEIGHBOURS, buffer_cells, navigation_from_spec
from sweep_core.model.maps import map_from_spec
from sweep_core.model.robots import overlap
from sweep_core.model.scene import Scene

_GOAL_FIELD = re.compile(r"robots\[(\d+)\]\.goal(\.[a-z_]+)?")
#: the clearance the goal field keeps from walls beyond the robot's radius (m): its
#: wall_buffer is radius + _MARGIN (control.goal_field)
_MARGIN = 0.1


def goal_refusal(scene: Scene, err: SceneError) -> SceneError:
    """A controller's refusal of a robot's goal (its navigation field's field names, such as
    ``robots[0].goal.wall_buffer``, are no keys of the scene) said in the scene's own keys:
    field ``robots[K].goal`` (K the robot's place in the scene's ``robots`` list), the robot
    named, the fix in terms of the goal, the radius or the controller. Other errors are
    returned unchanged."""
    m = _GOAL_FIELD.match(err.field)
    if m is None or int(m.group(1)) >= len(scene.robots):
        return err
    robot = scene.robots[int(m.group(1))]
    names = [r.get("name") for r in scene.spec.get("robots") or []]
    k = names.index(robot.name) if robot.name in names else int(m.group(1))
    field = f"robots[{k}]"
    key = m.group(2) or ""
    if key == ".cell":  # radius + _MARGIN below the grid's least wall_buffer
        least = buffer_cells(NEIGHBOURS) * CELL - _MARGIN
        fix_radius = math.ceil(least * 1e4) / 1e4
        return SceneError(f"{field}.radius", f"{show(robot.radius)} m is too small for robot "
                          f"{robot.name}'s controller {robot.controller}: its plan keeps the "
                          f"radius + {_MARGIN:g} m from walls on a {CELL:g} m grid, which needs "
                          f"at least {least + _MARGIN:.4g} m so that no grid step crosses a thin "
                          "wall unseen",
                          f"set {field}.radius to at least {fix_radius:g} m, or set "
                          f"{field}.controller: none and command the robot yourself")
    problem = re.sub(r"\bagents? \d+", f"robot {robot.name}", err.problem)
    problem = re.sub(r"(\brobots\[\d+\]\.goal\.)?wall_buffer", "the clearance", problem)
    if key == ".wall_buffer":
        fix = (f"give robot {robot.name} more room, or a smaller {field}.radius")
    else:
        fix = (f"move {field}.goal into free space that robot {robot.name} can reach from "
               f"{field}.pose, or open a way for it wider than twice the clearance")
    return SceneError(f"{field}.goal", f"robot {robot.name}'s goal {show(list(robot.goal or ()))} "
                      f"for its controller {robot.controller}: {problem}", fix)


def scene_map(scene: Scene) -> Any:
    """``scene``'s map as its occupancy grid (:func:`~sweep_core.model.maps.map_from_spec`),
    None without one."""
    return map_from_spec(scene.spec["map"], "map", None) if scene.spec.get("map") else None


def geometry_problem(states: list[Any], scene: Scene, t: float) -> str:
    """What a robot's current disk (``states``: the fleet's ``RobotState`` objects) would
    overlap in ``scene``'s walls, obstacles and blocked map cells at time t, or, for a robot
    with a goal it has not reached, that they would leave it no way there (a geodesic field
    round them for its disk, as ``pursuit`` plans); '' when nothing."""
    grid = scene_map(scene)
    blocked = None if grid is None else grid.is_blocked
    for st in states:
        problem = overlap(st.robot, st.pose[:2], scene.geometry, np.empty((0, 2)),
                          np.empty(0), [], blocked, t)
        if problem:
            return problem
    for st in states:  # enclosed: no way left to its goal
        problem = no_way(st.robot, st.pose[:2], scene, grid)
        if problem:
            return problem
    return ""


def no_way(robot: Any, xy: Any, scene: Scene, grid: Any = None) -> str:
    """That ``robot`` at ``xy`` (m) would have no way to its goal round ``scene``'s walls,
    obstacles and the blocked cells of ``grid`` (its map, None without one) for its disk (a
    geodesic field, as ``pursuit`` plans); '' when it has one, has no goal or is within its
    goal radius."""
    goal = robot.goal
    if goal is None or math.hypot(xy[0] - goal[0], xy[1] - goal[1]) <= robot.goal_radius:
        return ""
    spec = {"kind": "geodesic", "goal": list(goal), "speed": 1.0,
            "wall_buffer": max(robot.radius, buffer_cells(NEIGHBOURS) * CELL)}
    try:
        navigation_from_spec(spec, "goal", scene.geometry, grid,
                             np.array([[float(xy[0]), float(xy[1])]]))
    except SceneError:
        return (f"robot {robot.name} at {show([float(xy[0]), float(xy[1])])} would have no way "
                f"to its goal {show(list(goal))} for its disk (radius {robot.radius:g} m)")
    return ""
