"""The robots of a recording for ``sweep analyze``: their odometry and contacts read once
(``/NAME/odom``, ``/NAME/contacts``), each frame's people (``/poses``, ``/agents``, radii from
the scene) turned into each robot's :class:`~sweep_core.analysis.social.Series`
(:class:`SocialMetrics`), and the metrics of :mod:`sweep_core.analysis.social` from them.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from sweep_core.analysis.frames import Frame
from sweep_core.analysis.roster import Roster
from sweep_core.analysis.run import RunMeta, Schedule, scene_with_map
from sweep_core.analysis.social import (
    RobotSpec,
    Series,
    episode_end,
    episode_metrics,
    geodesic_distance,
    nearest,
    robot_specs,
)
from sweep_core.checks import COORDINATE_BOUND
from sweep_core.errors import SweepError
from sweep_core.io import cdr
from sweep_core.io.recording import read_recording, scan_recording


class SocialMetrics:
    """Collects each robot's series frame by frame (:meth:`add`, called by ``analyze`` for
    every frame of the recording) and gives the metrics (:meth:`summary`) and the per-frame
    table (:meth:`table`). The robots' odometry and contacts are read from the recording once,
    when this is built (a few numbers per robot and step)."""

    COLUMNS = ("robot", "t_s", "x_m", "y_m", "yaw_rad", "vx_m_per_s", "vy_m_per_s",
               "clearance_m", "ttc_s", "contacts", "impulse")

    def __init__(self, meta: RunMeta, specs: list[RobotSpec]) -> None:
        self.meta, self.specs = meta, specs
        self.problems: list[str] = []
        self.odom, self.touch = read_robot_topics(meta, [s.name for s in specs], self.problems)
        self.rows: list[list[tuple]] = [[] for _ in specs]
        self.touched: list[list[np.ndarray]] = [[] for _ in specs]
        self.steps: list[list[int]] = [[] for _ in specs]  # each row's step
        self.t0: int | None = None
        #: per robot, the log time (ns) of its first placement by the node (initialpose) in the
        #: first segment: its episode ends there (a placement is not motion), None: never placed
        self.placed_ns: list[int | None] = [
            min((p.log_time_ns for p in meta.robot_poses
                 if p.segment == 0 and p.spec.get("robot") == s.name), default=None)
            for s in specs]
        for s, ns in zip(specs, self.placed_ns, strict=True):
            if ns is not None:
                self.problems.append(
                    f"{meta.path}: robot {s.name} was placed by the node (initialpose) at "
                    f"t = {ns / 1e9:g} s: its episode is measured up to there")
        #: the people by id (float64 radii from the scene) when its flows' sinks take some
        self.roster = (Roster(meta.scene, meta.path)
                       if meta.scene is not None and meta.scene.flows is not None else None)

    def add(self, fr: Frame, segment: int, step: int, velocities: np.ndarray) -> None:
        """One frame (of step ``step``): people at ``fr.positions`` with the scene's radii at
        that step (with flows: of the agents present, by their ``/agents`` ids; the float32
        ``/agents`` radii without a scene) and ``velocities`` (N, 2)
        m/s, their displacements over the speed window (:mod:`sweep_core.analysis.speed`;
        NaN: none); frames after the first reset (``segment`` > 0), and a robot's frames
        after its first placement, are not part of the episode."""
        if segment > 0:
            return
        scene, dt = self.meta.scene, self.meta.dt
        t_sim = step * dt if dt is not None and step >= 0 else fr.stamp_ns / 1e9
        if self.roster is not None and fr.agents is not None:  # by id: some may have left
            ids = self.roster.ids(fr.agents, len(fr.positions), t_sim)
            radii = self.roster.radii(ids, fr.agents, t_sim)
        elif scene is not None and scene.n_agents == len(fr.positions):
            radii = scene.radii(t_sim)
        elif fr.agents is not None:
            radii = fr.agents["radius"].astype(np.float64)
        else:
            return
        if self.t0 is None:
            self.t0 = fr.log_ns
        t = (fr.log_ns - self.t0) / 1e9
        q, v = fr.positions, velocities
        for k, spec in enumerate(self.specs):
            state = self.odom[k].get(fr.log_ns)
            placed = self.placed_ns[k]
            if state is None or (placed is not None and fr.log_ns > placed):
                continue
            x, y, yaw, vx, vy = state
            near, ttc = nearest(np.array([x, y]), np.array([vx, vy]), spec.radius, q, radii, v)
            ids, imp = self.touch[k].get(fr.log_ns, (np.zeros(0), np.zeros(0)))
            self.rows[k].append((k, t, x, y, yaw, vx, vy, near, ttc, len(ids),
                                 float(imp.sum()), float(imp.max()) if len(imp) else 0.0))
            self.touched[k].append(ids)
            self.steps[k].append(step)

    def series(self, k: int) -> Series:
        """Robot k's series so far."""
        a = np.array(self.rows[k], dtype=np.float64).reshape(-1, len(self.COLUMNS) + 1)
        return Series(t=a[:, 1], pose=a[:, 2:5], vel=a[:, 5:7], clearance=a[:, 7],
                      ttc=a[:, 8], contacts=a[:, 9], impulse=a[:, 10], impulse_max=a[:, 11],
                      touched=self.touched[k])

    def summary(self) -> dict[str, Any]:
        """Per robot name: :func:`episode_metrics` (None for a robot with no odometry)."""
        out: dict[str, Any] = {}
        scene = self.meta.scene
        for k, spec in enumerate(self.specs):
            s = self.series(k)
            if len(s.t) == 0:
                self.problems.append(f"{self.meta.path}: robot {spec.name}: no odometry "
                                     "recorded with the frames; no metrics")
                out[spec.name] = None
                continue
            geo = None
            if spec.goal is not None and scene is not None:
                geo, why = geodesic_distance(self._scene_at(k, spec, s), s.pose[0, :2],
                                             spec.goal, spec.radius)
                if why:
                    self.problems.append(f"{self.meta.path}: robot {spec.name}: no geodesic "
                                         f"distance to its goal ({why})")
            out[spec.name] = episode_metrics(spec, s, geo)
        return out

    def _scene_at(self, k: int, spec: RobotSpec, s: Series) -> Any:
        """The scene with the map in effect at the end of robot k's episode: the last map the
        node took from its map topic by then (``map_NNNNNN``), else the scene's own."""
        end = self.steps[k][episode_end(spec, s)[0]]
        packed = Schedule(self.meta).map_at(0, end) if end >= 0 else None
        return self.meta.scene if packed is None else scene_with_map(self.meta.scene, packed)

    def table(self) -> np.ndarray:
        """(rows, len(COLUMNS)): every robot's frames of its episode, robot by robot."""
        parts = []
        for k, spec in enumerate(self.specs):
            s = self.series(k)
            n = episode_end(spec, s)[0] + 1 if len(s.t) else 0
            parts.append(np.array(self.rows[k], dtype=np.float64
                                  ).reshape(-1, len(self.COLUMNS) + 1)[:n, :-1])
        return (np.concatenate(parts) if parts
                else np.zeros((0, len(self.COLUMNS))))


def _topic(channels: dict[str, Any], name: str, leaf: str, msgtype: str) -> str | None:
    """``/NAME/LEAF``, or the shortest recorded topic ending so (a namespaced node)."""
    want = f"/{name}/{leaf}"
    cands = [t for t, c in channels.items() if t.endswith(want) and c.msgtype == msgtype]
    return min(cands, key=len) if cands else None


def odom_state(data: bytes) -> tuple[float, float, float, float, float]:
    """A CDR ``nav_msgs/msg/Odometry`` as (x, y, yaw, vx, vy): position (m) and yaw (rad) in
    its frame (odom, which the robot's map -> odom keeps equal to map), the linear velocity
    turned from the robot's frame (its twist's frame, REP 105) into that frame (m/s)."""
    od = cdr.decode_odometry(data)
    yaw = cdr.quaternion_yaw(od.orientation)
    c, s = math.cos(yaw), math.sin(yaw)
    u, w = float(od.linear[0]), float(od.linear[1])
    return (float(od.position[0]), float(od.position[1]), yaw, c * u - s * w, s * u + c * w)


def read_robot_topics(meta: RunMeta, names: list[str], problems: list[str]
                      ) -> tuple[list[dict[int, tuple]], list[dict[int, tuple]]]:
    """Per robot: its odometry by log time (ns) as (x, y, yaw, vx, vy) (m, rad, m/s in the map
    frame) and its contacts by log time as (ids (K,), |impulse| (K,)). A message that cannot be
    decoded is skipped and counted in ``problems``."""
    channels = scan_recording(meta.path).channels
    odom_topics = {_topic(channels, n, "odom", cdr.ODOMETRY): k for k, n in enumerate(names)}
    touch_topics = {_topic(channels, n, "contacts", cdr.POINT_CLOUD2): k
                    for k, n in enumerate(names)}
    odom_topics.pop(None, None)
    touch_topics.pop(None, None)
    odom: list[dict[int, tuple]] = [{} for _ in names]
    touch: list[dict[int, tuple]] = [{} for _ in names]
    bad = 0
    reader = read_recording(meta.path, [t for t in (*odom_topics, *touch_topics) if t])
    try:
        for msg in reader:
            try:
                if msg.topic in odom_topics:
                    odom[odom_topics[msg.topic]][msg.log_time_ns] = odom_state(msg.data)
                else:
                    f = cdr.decode_point_cloud2(msg.data).fields
                    imp = np.hypot(f["impulse_x"].astype(np.float64),
                                   f["impulse_y"].astype(np.float64))
                    touch[touch_topics[msg.topic]][msg.log_time_ns] = (
                        f["id"].astype(np.int64), imp)
            except (ValueError, KeyError):
                bad += 1
    finally:
        reader.close()
    if bad:
        problems.append(f"{meta.path}: {bad} robot odometry or contact messages skipped: "
                        "they cannot be decoded")
    return odom, touch


def for_run(meta: RunMeta, goal_radius: float | None = None,
            time_limit: float | None = None) -> SocialMetrics | None:
    """The collector of a recording's robots, None when its scene has none."""
    for name, v, unit, example in (("--goal-radius", goal_radius, "metres", "0.5"),
                                   ("--time-limit", time_limit, "seconds", "30")):
        if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float))
                              or not (v > 0 and math.isfinite(v))):
            raise SweepError(f"{name}: must be a positive number of {unit}, got {v!r} (fix: "
                             f"e.g. {name} {example}, or leave it out for the scene's)")
    if goal_radius is not None and goal_radius > COORDINATE_BOUND:  # a scene's own bound
        raise SweepError(f"--goal-radius: {goal_radius!r} m is beyond the bound "
                         f"{COORDINATE_BOUND:g} m of a scene's goal_radius (fix: "
                         f"--goal-radius {COORDINATE_BOUND:g} or less)")
    specs = robot_specs(meta.scene, goal_radius, time_limit)
    unused = [(n, v) for n, v in (("--goal-radius", goal_radius), ("--time-limit", time_limit))
              if v is not None]
    if not specs and unused:  # options of a robot's episode, which would change nothing
        raise SweepError(f"{unused[0][0]} {unused[0][1]:g}: the recording's scene has no robot, "
                         "and the option only sets a robot's goal radius or episode (fix: "
                         "leave it out; the crowd's metrics cover the whole recording)")
    return SocialMetrics(meta, specs) if specs else None
