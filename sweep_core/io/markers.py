"""What the viewers draw (the ``/markers`` and ``/walls`` MarkerArray topics), as
:class:`~sweep_core.io.cdr.markers.MarkerBatch` es: shared by ``sweep run``, the ensemble's
recorded runs, the live view and the node (which turns them into rclpy messages or publishes
their CDR bytes), so RViz and Foxglove show the same whichever made them.

* ``/walls`` (latched; again when the walls change, and at the markers' rate while any wall or
  obstacle moves): a CUBE per wall segment (namespace ``walls``, id = the wall's index; the
  pieces of a polyline ``walls[i]``, of a polygon obstacle ``obstacles[i]``, of a map ``map``,
  id = the piece), a long CUBE per half-plane, a CYLINDER per circular obstacle (``obstacles``),
  moving ones at their pose at t.
* ``/markers``: a CYLINDER per person (namespace ``agents``, id = the agent's id, diameter
  2 r(t), coloured by group), and per robot k its footprint (``robots``, a CYLINDER of its
  radius) and heading (``robot_headings``, an ARROW along its yaw, as long as its diameter).

Heights (z) are ``height`` m for people and walls; markers stand on z = 0. Colours are RGBA in
[0, 1]: groups in matplotlib's tab10 order (as ``sweep analyze`` and ``sweep render`` draw
them), agents in no group grey.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from sweep_core.io.cdr.markers import ARROW, CUBE, CYLINDER, MarkerBatch, delete_all
from sweep_core.model import elementary
from sweep_core.model.fields import Groups
from sweep_core.model.geometry import Geometry
from sweep_core.numerics.robots.fleet import Fleet
from sweep_core.numerics.simulator import Simulator, State

MARKERS, WALLS = "/markers", "/walls"
#: the rate (Hz of simulated time) at which ``sweep run`` records ``/markers`` by default
MARKER_RATE_HZ = 10.0
WALL_COLOR = (0.45, 0.45, 0.45, 1.0)
OBSTACLE_COLOR = (0.60, 0.25, 0.20, 1.0)
ROBOT_COLOR = (0.10, 0.10, 0.10, 0.9)
HEADING_COLOR = (1.0, 0.85, 0.0, 1.0)
REST_COLOR = (0.55, 0.55, 0.55, 0.9)
WALL_THICKNESS = 0.05
_TAB10 = ("1f77b4", "d62728", "2ca02c", "ff7f0e", "9467bd", "8c564b", "e377c2", "bcbd22",
          "17becf")
#: RGBA of groups 0, 1, ... (cycled)
GROUP_COLORS = np.array([[int(h[i:i + 2], 16) / 255 for i in (0, 2, 4)] + [0.9]
                         for h in _TAB10])


def markers_every(dt: float, record_every: int, rate_hz: float = MARKER_RATE_HZ) -> int:
    """How many recorded states apart ``/markers`` are recorded at ``rate_hz`` (Hz of simulated
    time) for time step dt (s) and ``record_every``: at least 1 (every recorded state)."""
    return max(1, int(round(1.0 / (rate_hz * dt * record_every))))


def agent_groups(sim: Simulator, state: State | None = None) -> np.ndarray:
    """The group of each present agent ((N,) int, -1 in none): the flows' groups, or the
    members of a ``Groups`` drift of the scene; ``state``: ``sim.state``, when the caller has
    it."""
    if sim.flows is not None:
        return np.asarray(sim.flows.group[sim.flows.ids], dtype=np.intp)
    n = len((sim.state if state is None else state).positions)
    out = np.full(n, -1, dtype=np.intp)
    drift = sim.scene.drift
    if isinstance(drift, Groups):
        for k, idx in enumerate(drift.members):
            out[idx[idx < n]] = k
    return out


def group_colors(groups: np.ndarray) -> np.ndarray:
    """(N, 4) RGBA of agents of the given groups ((N,) int, -1 in none)."""
    g = np.asarray(groups, dtype=np.intp)
    out = GROUP_COLORS[np.maximum(g, 0) % len(GROUP_COLORS)]
    out[g < 0] = REST_COLOR
    return out


#: batches of at most this many agents or robots share their constant columns (colours, ids,
#: scales: read-only arrays kept for the values they were made of) from step to step
_KEPT_UP_TO = 256


def _read_only(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


@lru_cache(maxsize=16)
def _kept_colors(groups: bytes) -> np.ndarray:
    """:func:`group_colors` of the groups whose intp bytes are ``groups``, read-only."""
    return _read_only(group_colors(np.frombuffer(groups, dtype=np.intp)))


@lru_cache(maxsize=16)
def _kept_scale(radii: bytes, height: float) -> np.ndarray:
    """(N, 3) diameters and heights (m) of agents of float64 radii ``radii``, read-only."""
    d = 2.0 * np.frombuffer(radii, dtype=np.float64)
    return _read_only(np.stack([d, d, np.full(len(d), float(height))], axis=1))


@lru_cache(maxsize=16)
def _kept_zeros(n: int) -> np.ndarray:
    return _read_only(np.zeros(n))


def agent_batch(positions: np.ndarray, radii: np.ndarray, ids: np.ndarray, groups: np.ndarray,
                height: float = 1.0) -> MarkerBatch:
    """A CYLINDER per agent: positions (N, 2) m, radii (N,) m, ids (N,), groups (N,). With at
    most :data:`_KEPT_UP_TO` agents, the colours, scales and yaws are read-only arrays shared
    by the batches of the same groups, radii and height."""
    q = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
    n = len(q)
    position = np.empty((n, 3))
    position[:, :2], position[:, 2] = q, height / 2
    if n <= _KEPT_UP_TO and np.ndim(groups) == 1:
        r = np.ascontiguousarray(radii, dtype=np.float64).reshape(n)
        g = np.ascontiguousarray(groups, dtype=np.intp)
        return MarkerBatch("agents", CYLINDER, np.asarray(ids).reshape(n), position,
                           _kept_zeros(n), _kept_scale(r.tobytes(), float(height)),
                           _kept_colors(g.tobytes()))
    d = 2.0 * np.asarray(radii, dtype=np.float64).reshape(n)
    return MarkerBatch("agents", CYLINDER, np.asarray(ids).reshape(n), position, np.zeros(n),
                       np.stack([d, d, np.full(n, float(height))], axis=1),
                       group_colors(groups))


@lru_cache(maxsize=16)
def _robot_columns(radii: tuple[float, ...], height: float
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Read-only ids, footprint and heading scales and colours of robots of radii (m)."""
    k = len(radii)
    return (_read_only(np.arange(k)),
            _read_only(np.array([(2 * r, 2 * r, height) for r in radii], dtype=np.float64
                                ).reshape(k, 3)),
            _read_only(np.array([(2 * r, 0.2 * r, 0.2 * r) for r in radii], dtype=np.float64
                                ).reshape(k, 3)),
            _read_only(np.array([ROBOT_COLOR] * k)), _read_only(np.array([HEADING_COLOR] * k)))


def robot_batches(fleet: Fleet | None, height: float = 1.0) -> list[MarkerBatch]:
    """Each robot's footprint (CYLINDER of its radius) and heading (ARROW along its yaw); the
    ids, scales and colours read-only arrays shared by the batches of the same radii and
    height."""
    if fleet is None or not fleet.names:
        return []
    states = [fleet.state(name) for name in fleet.names]
    k = len(states)
    poses = [tuple(float(v) for v in s.pose) for s in states]
    ids, foot_scale, arrow_scale, foot_color, arrow_color = _robot_columns(
        tuple(float(s.robot.radius) for s in states), float(height))
    foot = np.array([(x, y, height / 2) for x, y, _ in poses], dtype=np.float64).reshape(k, 3)
    arrow = np.array([(x, y, height) for x, y, _ in poses], dtype=np.float64).reshape(k, 3)
    yaw = np.array([p[2] for p in poses], dtype=np.float64)
    return [MarkerBatch("robots", CYLINDER, ids, foot, yaw, foot_scale, foot_color),
            MarkerBatch("robot_headings", ARROW, ids, arrow, yaw, arrow_scale, arrow_color)]


def state_batches(sim: Simulator, groups: np.ndarray | None = None, height: float = 1.0,
                  state: State | None = None) -> list[MarkerBatch]:
    """``/markers`` of a simulator now: its people (``groups``: :func:`agent_groups`, given
    when known) and its robots; ``state``: ``sim.state``, when the caller has it."""
    state = sim.state if state is None else state
    ids = np.arange(len(state.positions)) if state.ids is None else state.ids
    g = agent_groups(sim, state) if groups is None else groups
    return [agent_batch(state.positions, state.radii, ids, g, height),
            *robot_batches(sim.robots, height)]


def scene_extent(geometry: Geometry, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper corners (m) of what a scene contains, for drawing infinite walls."""
    pts = [np.asarray(positions).reshape(-1, 2), geometry.segment_a, geometry.segment_b]
    if len(geometry.circle_center):
        r = geometry.circle_radius[:, None]
        pts += [geometry.circle_center - r, geometry.circle_center + r]
    pts = [p for p in pts if len(p)]
    allp = np.concatenate(pts) if pts else np.zeros((1, 2))
    return allp.min(axis=0) - 1.0, allp.max(axis=0) + 1.0


def _boxes(ns: str, ids: np.ndarray, a: np.ndarray, b: np.ndarray, color: tuple,
           height: float) -> MarkerBatch:
    """A CUBE along each segment a-b ((K, 2) each), WALL_THICKNESS across, ``height`` up."""
    mid, d = (a + b) / 2, b - a
    k = len(a)
    return MarkerBatch(ns, CUBE, ids, np.column_stack([mid, np.full(k, height / 2)]),
                       elementary.atan2_of(d[:, 1], d[:, 0]),
                       np.column_stack([np.hypot(d[:, 0], d[:, 1]), np.full(k, WALL_THICKNESS),
                                        np.full(k, float(height))]),
                       np.tile(color, (k, 1)))


def wall_batches(geometry: Geometry, positions: np.ndarray, t: float, height: float = 1.0,
                 clear: bool = False) -> list[MarkerBatch]:
    """``/walls`` at time t (s) (module docstring); positions (N, 2) m bound the drawing of
    half-planes; ``clear``: a DELETEALL first (a new map can have fewer pieces than the
    last)."""
    geometry = geometry.at(t)
    out = [delete_all("walls")] if clear else []
    poly = np.asarray(geometry.segment_polygon, dtype=np.intp)
    index = np.asarray(geometry.segment_index, dtype=np.intp)
    part = np.asarray(geometry.segment_part, dtype=np.intp)
    kind = np.asarray(geometry.segment_kind)
    names = np.where(poly >= 0, np.char.add(np.char.add("obstacles[", poly.astype(str)), "]"),
                     np.where(kind == "map", "map",
                              np.where(kind != "segment",
                                       np.char.add(np.char.add("walls[", index.astype(str)),
                                                   "]"), "walls")))
    ids = np.where((poly < 0) & (kind == "segment"), index, part)
    for ns in dict.fromkeys(names.tolist()):  # in order of first appearance
        sel = np.flatnonzero(names == ns)
        color = OBSTACLE_COLOR if ns.startswith("obstacles") else WALL_COLOR
        out.append(_boxes(ns, ids[sel], geometry.segment_a[sel], geometry.segment_b[sel],
                          color, height))
    if len(geometry.halfplane_offset):
        lo, hi = scene_extent(geometry, positions)
        centre, reach = (lo + hi) / 2, float(np.hypot(*(hi - lo)))
        n = np.asarray(geometry.halfplane_normal, dtype=np.float64)
        c = geometry.halfplane_offset + geometry.halfplane_velocity * t
        foot = centre + (c - n @ centre)[:, None] * n - n * (WALL_THICKNESS / 2)
        along = np.column_stack([n[:, 1], -n[:, 0]]) * reach
        out.append(_boxes("walls", np.asarray(geometry.halfplane_index), foot - along,
                          foot + along, WALL_COLOR, height))
    if len(geometry.circle_radius):
        k = len(geometry.circle_radius)
        d = 2.0 * np.asarray(geometry.circle_radius, dtype=np.float64)
        out.append(MarkerBatch(
            "obstacles", CYLINDER, np.asarray(geometry.circle_index),
            np.column_stack([geometry.circle_center, np.full(k, height / 2)]), np.zeros(k),
            np.column_stack([d, d, np.full(k, float(height))]), np.tile(OBSTACLE_COLOR, (k, 1))))
    return out


def moving_walls(geometry: Geometry) -> bool:
    """Whether any wall or obstacle of the geometry moves (``/walls`` then follows it)."""
    v = geometry.halfplane_velocity
    return bool(geometry.is_moving or (len(v) and (v != 0).any()))
