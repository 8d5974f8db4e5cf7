"""Social-navigation metrics of a robot's episode (definitions, units and sources:
docs/social_metrics.md): the clearance to people (surface to surface), the time to collision
of disks at constant velocity, jerk, and :func:`episode_metrics`, which turns a robot's
per-frame :class:`Series` into the metrics (vectorised over the frames; each frame is
vectorised over the people). ``sweep analyze`` builds the series from a recording
(:mod:`sweep_core.analysis.robots`), the Gymnasium environment from the engine's states.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sweep_core.errors import SweepError
from sweep_core.model.geodesic import CELL, NEIGHBOURS, buffer_cells, navigation_from_spec
from sweep_core.model.maps import map_from_spec
from sweep_core.model.scene import Scene
from sweep_core.numerics.robots.social_kernels import nearest_pass

#: Hall's proxemic zones on the clearance to the nearest person (m): [low, high)
ZONES = (("intimate", 0.0, 0.45), ("personal", 0.45, 1.2), ("social", 1.2, 3.6),
         ("public", 3.6, math.inf))
#: a clearance below this (m) counts as discomfort (CrowdNav's discomfort distance)
DISCOMFORT = 0.2
#: goal radius (m) when neither the scene nor the command line gives one (the scene's default)
DEFAULT_GOAL_RADIUS = 0.5
#: a clearance at most this (m) is a contact (the analysis' tolerance on true constraints)
CONTACT_TOL = 1e-6


def clearance(robot: np.ndarray, robot_radius: np.ndarray, people: np.ndarray,
              radii: np.ndarray) -> np.ndarray:
    """(R, N) m: surface-to-surface distance between R robots (positions (R, 2), radii (R,))
    and N people (positions (N, 2), radii (N,))."""
    d = robot[:, None, :] - people[None, :, :]
    return np.hypot(d[..., 0], d[..., 1]) - robot_radius[:, None] - radii[None, :]


def time_to_collision(rel_pos: np.ndarray, rel_vel: np.ndarray, reach: np.ndarray
                      ) -> np.ndarray:
    """Time (s) until two disks moving at constant velocity first touch, elementwise.

    Args:
        rel_pos: (..., 2) m, one centre minus the other.
        rel_vel: (..., 2) m/s, the first's velocity minus the other's.
        reach: (...) m, the sum of the radii.

    Returns:
        (...) s: 0 where they already touch or overlap, inf where they never touch (moving
        apart, parallel, or passing clear), else the smallest tau > 0 with
        |rel_pos + tau rel_vel| = reach.
    """
    pw = np.einsum("...c,...c->...", rel_pos, rel_vel)
    ww = np.einsum("...c,...c->...", rel_vel, rel_vel)
    c = np.einsum("...c,...c->...", rel_pos, rel_pos) - reach * reach
    disc = pw * pw - ww * c
    approaching = (pw < 0) & (disc >= 0) & (ww > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        # the smaller root in the form that does not cancel: c / (-pw + sqrt(disc))
        tau = np.where(approaching, c / (-pw + np.sqrt(np.where(approaching, disc, 0.0))),
                       np.inf)
    return np.where(c <= 0, 0.0, tau)


def nearest(position: np.ndarray, velocity: np.ndarray, radius: float, people: np.ndarray,
            radii: np.ndarray, velocities: np.ndarray) -> tuple[float, float]:
    """One robot at one instant: the clearance (m) to the nearest of the people and the
    smallest time to collision (s) with any of them (:func:`time_to_collision`); inf, inf
    without people. ``position`` (2,) m, ``velocity`` (2,) m/s, ``people`` (N, 2) m,
    ``radii`` (N,) m, ``velocities`` (N, 2) m/s (NaN: unknown, that person left out of the
    time to collision; NaN when no velocity is known)."""
    if len(people) == 0:
        return math.inf, math.inf
    out = np.empty(3)
    nearest_pass(float(position[0]), float(position[1]), float(velocity[0]),
                 float(velocity[1]), float(radius), np.ascontiguousarray(people, dtype=np.float64),
                 np.ascontiguousarray(radii, dtype=np.float64),
                 np.ascontiguousarray(velocities, dtype=np.float64), out)
    return float(out[0]), float(out[1]) if out[2] > 0 else math.nan


def wrap(angle: np.ndarray) -> np.ndarray:
    """Angles (rad) wrapped to [-pi, pi)."""
    return (angle + np.pi) % (2.0 * np.pi) - np.pi


def jerk(t: np.ndarray, p: np.ndarray) -> np.ndarray:
    """(M - 3, 2) m/s^3: the third derivative of positions p (M, 2) at times t (M,) s by
    divided differences (exact for cubic motion, any spacing); empty below 4 samples."""
    if len(t) < 4:
        return np.zeros((0, 2))
    d1 = np.diff(p, axis=0) / np.diff(t)[:, None]
    d2 = np.diff(d1, axis=0) / (t[2:] - t[:-2])[:, None]
    d3 = np.diff(d2, axis=0) / (t[3:] - t[:-3])[:, None]
    return 6.0 * d3  # divided differences carry 1/k!


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
    ids = (np.concatenate(touched) if touched else np.zeros(0)).astype(np.int64)
    # a contact event: a person in contact at a frame who was not at the previous one
    at = np.repeat(np.arange(len(touched)), [len(k) for k in touched])
    key = ids * (len(touched) + 1) + at
    events = int(np.count_nonzero(~np.isin(key - 1, key)))
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
