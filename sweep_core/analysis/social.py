"""Social-navigation metrics of each robot of a recording (``sweep analyze``), from the recording
alone: the robot's ``/NAME/odom`` and ``/NAME/contacts``, the people's ``/poses`` and
``/agents`` and the scene in the metadata (each robot's radius and goal). Definitions, units and
sources: docs/social_metrics.md.

:class:`SocialMetrics` collects, frame by frame, per robot: its pose and velocity, the clearance
to the nearest person (surface to surface), the smallest time to collision and its contacts;
:func:`episode_metrics` turns those series into the metrics (vectorised over the frames; each
frame is vectorised over robots and people).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sweep_core.analysis.encounters import clearance as clearance  # re-exported
from sweep_core.analysis.encounters import jerk as jerk
from sweep_core.analysis.encounters import nearest as nearest
from sweep_core.analysis.encounters import time_to_collision as time_to_collision
from sweep_core.analysis.encounters import wrap as wrap
from sweep_core.analysis.frames import Frame
from sweep_core.analysis.run import RunMeta
from sweep_core.errors import SweepError
from sweep_core.io import cdr
from sweep_core.io.recording import read_recording, scan_recording
from sweep_core.model.geodesic import CELL, NEIGHBOURS, buffer_cells, navigation_from_spec
from sweep_core.model.maps import map_from_spec
from sweep_core.model.scene import Scene

#: Hall's proxemic zones on the clearance to the nearest person (m): [low, high)
ZONES = (("intimate", 0.0, 0.45), ("personal", 0.45, 1.2), ("social", 1.2, 3.6),
         ("public", 3.6, math.inf))
#: a clearance below this (m) counts as discomfort (CrowdNav's discomfort distance)
DISCOMFORT = 0.2
#: goal radius (m) when neither the scene nor the command line gives one (the scene's default)
DEFAULT_GOAL_RADIUS = 0.5
#: a clearance at most this (m) is a contact (the analysis' tolerance on true constraints)
CONTACT_TOL = 1e-6


@dataclass
class RobotSpec:
    """What the recorded scene says about one robot: ``name``, disk ``radius`` (m), ``goal``
    (2,) m or None, ``goal_radius`` (m) and the ``time_limit`` of an episode (s from the first
    frame, None: the whole recording)."""

    name: str
    radius: float
    goal: np.ndarray | None
    goal_radius: float
    time_limit: float | None = None


@dataclass
class Series:
    """One robot's per-frame series, all of length M (frames): ``t`` (s from the first frame),
    ``pose`` (M, 3) x, y (m), yaw (rad), ``vel`` (M, 2) m/s in the map frame, ``clearance``
    (m, to the nearest person; inf without people), ``ttc`` (s), ``contacts`` (people in contact),
    ``impulse`` (sum of |impulse| over them) and ``impulse_max`` (largest |impulse| of one);
    ``touched`` the ids of the people in contact, one array per frame."""

    t: np.ndarray
    pose: np.ndarray
    vel: np.ndarray
    clearance: np.ndarray
    ttc: np.ndarray
    contacts: np.ndarray
    impulse: np.ndarray
    impulse_max: np.ndarray
    touched: list[np.ndarray] = field(default_factory=list)


def _first(mask: np.ndarray) -> int | None:
    k = int(np.argmax(mask)) if len(mask) else 0
    return k if len(mask) and mask[k] else None


def _none_if_inf(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def spl(success: bool, length: float, geodesic: float | None) -> float | None:
    """Success weighted by path length (Anderson et al. 2018) of one episode: S l / max(p, l)
    with S = 1 on success (else 0), l the shortest distance (m, None: unknown) and p the path
    length (m); 1 on success when l = 0 (started at the goal)."""
    if geodesic is None:
        return None
    if not success:
        return 0.0
    return 1.0 if geodesic <= 0 else float(geodesic / max(length, geodesic))


def episode_end(spec: RobotSpec, s: Series) -> tuple[int, bool]:
    """The index of the episode's last frame, and whether the goal was reached there: the
    first frame within ``goal_radius`` of the goal and within the time limit, else the last
    frame within the time limit (0 when none is)."""
    limit = math.inf if spec.time_limit is None else spec.time_limit
    within = s.t <= limit + 1e-9
    if spec.goal is not None:
        dist = np.hypot(*(s.pose[:, :2] - spec.goal).T)
        k = _first((dist <= spec.goal_radius) & within)
        if k is not None:
            return k, True
    return max(int(np.count_nonzero(within)) - 1, 0), False


def episode_metrics(spec: RobotSpec, s: Series, geodesic: float | None) -> dict[str, Any]:
    """The metrics of one robot's episode (docs/social_metrics.md), JSON-ready.

    The episode runs from the first frame to the first frame within ``goal_radius`` of the goal
    (reached), else to the last frame within the time limit. ``geodesic`` is the shortest
    distance (m) from the start to the goal round the walls, None if unknown.
    """
    end, reached = episode_end(spec, s)
    reached_at = end if reached else None
    e = slice(0, end + 1)
    xy, t = s.pose[e, :2], s.t[e]
    steps = np.hypot(*np.diff(xy, axis=0).T)
    length = float(steps.sum())
    cl = s.clearance[e]
    people = np.isfinite(cl)
    touched = s.touched[e] if s.touched else []
    ids = np.concatenate(touched) if touched else np.zeros(0)
    # a contact event: a person in contact at a frame who was not at the previous one
    events = sum(int(np.setdiff1d(now, before).size)
                 for before, now in zip([np.zeros(0)] + touched[:-1], touched))
    collided = bool(np.any(s.contacts[e] > 0) or np.any(cl <= CONTACT_TOL))
    frames = len(cl)
    zones = {name: float(np.count_nonzero((cl >= lo) & (cl < hi))) / frames
             for name, lo, hi in ZONES}
    zones["public"] += float(np.count_nonzero(~people)) / frames
    success = reached_at is not None and not collided
    t_goal = float(s.t[reached_at]) if reached_at is not None else None
    yaw = s.pose[e, 2]
    turn = float(np.abs(wrap(np.diff(yaw))).sum())
    jk = np.hypot(*jerk(t, xy).T)
    out: dict[str, Any] = {
        "radius_m": spec.radius,
        "goal": None if spec.goal is None else [float(v) for v in spec.goal],
        "goal_radius_m": spec.goal_radius,
        "time_limit_s": spec.time_limit,
        "frames": frames,
        "success": success,
        "reached_goal": reached_at is not None,
        "collided": collided,
        "time_to_goal_s": t_goal,
        "path_length_m": length,
        "geodesic_m": geodesic,
        "path_length_ratio": (length / geodesic if geodesic and reached_at is not None
                              else None),
        "spl": spl(success, length, geodesic),
        "clearance": {
            "min_m": _none_if_inf(float(cl.min())) if frames else None,
            "mean_m": float(cl[people].mean()) if people.any() else None,
        },
        "zones": zones,
        "discomfort_frequency": float(np.count_nonzero(cl < DISCOMFORT)) / frames,
        "contact": {
            "frames": int(np.count_nonzero(s.contacts[e] > 0)),
            "events": events,
            "people": int(np.unique(ids).size),
            "impulse_total": float(s.impulse[e].sum()),
            "impulse_max": float(s.impulse_max[e].max()) if frames else 0.0,
        },
        "min_ttc_s": _none_if_inf(float(s.ttc[e].min())) if frames else None,
        "heading_change_rad": turn,
        "heading_change_per_m": turn / length if length > 0 else None,
        "jerk": {
            "mean_m_per_s3": float(jk.mean()) if jk.size else None,
            "max_m_per_s3": float(jk.max()) if jk.size else None,
        },
    }
    return out


def goal_field(scene: Scene, goal: np.ndarray, radius: float, start: np.ndarray) -> Any:
    """The engine's geodesic field (:mod:`sweep_core.model.geodesic`) towards ``goal`` round
    the scene's walls, obstacles and map for a disk of ``radius`` m (wall_buffer = the radius,
    at least the grid's minimum), checked to reach ``start`` (2,); its ``travel_distance`` is
    the shortest distance (m; metrication error at most +2.75 %). Raises SweepError when it
    cannot be built."""
    buffer = max(float(radius), buffer_cells(NEIGHBOURS) * CELL)
    spec = {"kind": "geodesic", "goal": [float(goal[0]), float(goal[1])], "speed": 1.0,
            "wall_buffer": buffer}
    grid = (map_from_spec(scene.spec["map"], "map", None, files=False)
            if scene.spec.get("map") else None)
    return navigation_from_spec(spec, "robots.goal", scene.geometry, grid,
                                np.asarray(start, dtype=np.float64).reshape(1, 2))


def geodesic_distance(scene: Scene, start: np.ndarray, goal: np.ndarray, radius: float
                      ) -> tuple[float | None, str | None]:
    """The shortest distance (m) from ``start`` to ``goal`` round the scene's walls, obstacles
    and map for a disk of ``radius`` m by :func:`goal_field`, or (None, why) when the field
    cannot be built or does not reach the start."""
    try:
        nav = goal_field(scene, goal, radius, start)
    except SweepError as err:
        return None, str(err)
    d = float(nav.travel_distance(np.asarray(start, dtype=np.float64).reshape(1, 2))[0])
    return (d, None) if math.isfinite(d) else (None, "the goal is not reachable from the start")


def robot_specs(scene: Scene | None, goal_radius: float | None = None,
                time_limit: float | None = None) -> list[RobotSpec]:
    """The robots of a recorded scene (its ``robots:`` list: name, radius, goal,
    goal_radius), with ``goal_radius`` overriding the scene's when given; ``time_limit`` (s)
    None: the whole recording."""
    raw = scene.spec.get("robots") if scene is not None else None
    out = []
    for r in raw or []:
        goal = r.get("goal")
        out.append(RobotSpec(
            name=str(r["name"]), radius=float(r["radius"]),
            goal=None if goal is None else np.asarray(goal, dtype=np.float64)[:2],
            goal_radius=float(goal_radius if goal_radius is not None
                               else r.get("goal_radius", DEFAULT_GOAL_RADIUS)),
            time_limit=None if time_limit is None else float(time_limit)))
    return out


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
        self.t0: int | None = None

    def add(self, fr: Frame, segment: int, step: int) -> None:
        """One frame (of step ``step``): people at ``fr.positions`` with the scene's radii at
        that step (the float32 ``/agents`` radii without a scene), their velocities from
        ``fr.agents``; frames after the first reset (``segment`` > 0) are not part of the
        episode."""
        if segment > 0:
            return
        scene, dt = self.meta.scene, self.meta.dt
        if scene is not None and scene.n_agents == len(fr.positions):
            radii = scene.radii(step * dt if dt is not None and step >= 0 else fr.stamp_ns / 1e9)
        elif fr.agents is not None:
            radii = fr.agents["radius"].astype(np.float64)
        else:
            return
        if self.t0 is None:
            self.t0 = fr.log_ns
        t = (fr.log_ns - self.t0) / 1e9
        q = fr.positions
        v = (np.column_stack([fr.agents["vx"], fr.agents["vy"]]).astype(np.float64)
             if fr.agents is not None else np.full(q.shape, np.nan))
        for k, spec in enumerate(self.specs):
            state = self.odom[k].get(fr.log_ns)
            if state is None:
                continue
            x, y, yaw, vx, vy = state
            near, ttc = nearest(np.array([x, y]), np.array([vx, vy]), spec.radius, q, radii, v)
            ids, imp = self.touch[k].get(fr.log_ns, (np.zeros(0), np.zeros(0)))
            self.rows[k].append((k, t, x, y, yaw, vx, vy, near, ttc, len(ids),
                                 float(imp.sum()), float(imp.max()) if len(imp) else 0.0))
            self.touched[k].append(ids)

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
                geo, why = geodesic_distance(scene, s.pose[0, :2], spec.goal, spec.radius)
                if why:
                    self.problems.append(f"{self.meta.path}: robot {spec.name}: no geodesic "
                                         f"distance to its goal ({why})")
            out[spec.name] = episode_metrics(spec, s, geo)
        return out

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
    for name, v in (("--goal-radius", goal_radius), ("--time-limit", time_limit)):
        if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float))
                              or not (v > 0 and math.isfinite(v))):
            raise SweepError(f"{name}: must be a positive number, got {v!r}")
    specs = robot_specs(meta.scene, goal_radius, time_limit)
    return SocialMetrics(meta, specs) if specs else None
