"""One run of ``sweep bench social`` (a worker's task): a robot scene with every
robot's controller replaced, simulated in process from a seed until the first robot's goal is
reached or the time limit, its episode turned into the social-navigation metrics of
:func:`sweep_core.analysis.social.episode_metrics` and the contacts split by cause
(:mod:`sweep_core.analysis.causes`)."""
from __future__ import annotations

import copy
import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from sweep_core.analysis.causes import ContactLog
from sweep_core.analysis.social import (
    RobotSpec,
    Series,
    clearance,
    episode_metrics,
    geodesic_distance,
)
from sweep_core.model import elementary
from sweep_core.model.scene import Scene, load_scene
from sweep_core.numerics.simulator import Simulator

#: the columns of a run's row (``runs.csv``)
RUN_COLUMNS = ("scene", "controller", "seed", "reached", "success", "success_no_contact",
               "robot_contacts", "person_contacts", "robot_impulse_m_per_s",
               "person_impulse_m_per_s", "time_to_goal_s", "time_ratio", "path_length_ratio",
               "clearance_min_m", "clearance_mean_m", "intimate", "personal", "social",
               "public", "discomfort", "sim_s", "wall_s")


@dataclass(frozen=True)
class Run:
    """One run: ``scene`` (a bundled scene's name or a scene file's path), ``controller`` name,
    ``seed``, step ``dt`` (s) and time limit ``t_end`` (s; None: the scene's horizon, else
    30 s)."""

    scene: str
    controller: str
    seed: int
    dt: float
    t_end: float | None


def with_controller(scene: Scene, controller: str) -> Scene:
    """The scene with every robot's ``controller`` set to the named one: the scene's own
    parameters when it names that controller, else the controller's defaults."""
    spec = copy.deepcopy(scene.spec)
    for r in spec.get("robots") or []:
        own = r.get("controller")
        kind = own.get("kind") if isinstance(own, dict) else own
        if kind != controller:
            r["controller"] = controller
    return Scene.from_dict(spec)


def simulate(run: Run) -> dict[str, Any]:
    """The metrics row of one run (the first robot of the scene)."""
    start = time.perf_counter()
    scene = with_controller(load_scene(run.scene), run.controller)
    t_end = run.t_end if run.t_end is not None else (scene.horizon or 30.0)
    sim = Simulator(scene, dt=run.dt, seed=run.seed)
    assert sim.robots is not None
    robot = scene.robots[0]
    st = sim.robots.state(robot.name)
    log = ContactLog()
    rows: list[tuple[float, ...]] = []
    touched: list[np.ndarray] = []
    steps = int(round(t_end / run.dt))

    def record() -> None:
        x, y, yaw = st.pose
        vx, vy, _ = st.twist
        s, c = elementary.sincos(yaw)
        q, r = sim.positions, sim.radii
        near = (float(clearance(np.array([[x, y]]), np.array([robot.radius]), q, r)[0].min())
                if len(q) else math.inf)
        imp = np.hypot(*st.contact_impulse.T) if len(st.contact_ids) else np.zeros(0)
        rows.append((sim.t, x, y, yaw, c * vx - s * vy, s * vx + c * vy, near,
                     float(len(st.contact_ids)), float(imp.sum()),
                     float(imp.max()) if len(imp) else 0.0))
        touched.append(st.contact_ids.copy())

    record()
    for _ in range(steps):
        before = st.pose
        sim.step(1)
        log.add(st.contact_ids, st.contact_impulse,
                np.array(st.pose[:2]) - np.array(before[:2]), run.dt)
        record()
        if st.goal_reached:
            break
    a = np.array(rows, dtype=np.float64)
    series = Series(t=a[:, 0], pose=a[:, 1:4], vel=a[:, 4:6], clearance=a[:, 6],
                    ttc=np.full(len(a), math.inf), contacts=a[:, 7], impulse=a[:, 8],
                    impulse_max=a[:, 9], touched=touched)
    goal = None if robot.goal is None else np.array(robot.goal)
    spec = RobotSpec(robot.name, robot.radius, goal, robot.goal_radius, t_end)
    geo = None
    if goal is not None:
        geo, _ = geodesic_distance(scene, np.array(robot.pose[:2]), goal, robot.radius)
    m = episode_metrics(spec, series, geo)
    straight = (math.hypot(robot.goal[0] - robot.pose[0], robot.goal[1] - robot.pose[1])
                if robot.goal is not None else math.nan)
    return {
        "scene": run.scene, "controller": run.controller, "seed": run.seed,
        "reached": m["reached_goal"],
        "success": m["reached_goal"] and log.robot_events == 0,
        "success_no_contact": m["success"],
        "robot_contacts": log.robot_events, "person_contacts": log.person_events,
        "robot_impulse_m_per_s": log.robot_impulse,
        "person_impulse_m_per_s": log.person_impulse,
        "time_to_goal_s": m["time_to_goal_s"],
        "time_ratio": (m["time_to_goal_s"] * robot.max_speed / straight
                       if m["time_to_goal_s"] is not None and straight > 0 else None),
        "path_length_ratio": m["path_length_ratio"],
        "clearance_min_m": m["clearance"]["min_m"],
        "clearance_mean_m": m["clearance"]["mean_m"],
        "intimate": m["zones"]["intimate"], "personal": m["zones"]["personal"],
        "social": m["zones"]["social"], "public": m["zones"]["public"],
        "discomfort": m["discomfort_frequency"],
        "sim_s": sim.t, "wall_s": time.perf_counter() - start,
    }
