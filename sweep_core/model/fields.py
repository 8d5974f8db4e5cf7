"""Wished-velocity fields U(t, q): the drift of the sweeping process.

Every field maps positions q, shape (N, 2) in metres, to velocities, shape (N, 2) in m/s, and
is Lipschitz in q (the well-posedness assumption of the model, reference §3). ``max_speed``
bounds |U| (m/s) and feeds the constraint cutoff.
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass, replace
from typing import Any

import numba
import numpy as np

from sweep_core import checks
from sweep_core.errors import SceneError, show


class Field:
    """Base class. Subclasses implement ``__call__`` and ``to_spec``."""

    kind = "none"

    def __call__(self, t: float, q: np.ndarray) -> np.ndarray:
        return np.zeros_like(q)

    @property
    def is_zero(self) -> bool:
        return False

    def to_spec(self) -> dict:
        return {"kind": self.kind}


class NoDrift(Field):
    kind = "none"

    @property
    def is_zero(self) -> bool:
        return True


@dataclass(frozen=True)
class Uniform(Field):
    """U = velocity for every agent."""

    velocity: np.ndarray
    kind = "uniform"

    def __call__(self, t: float, q: np.ndarray) -> np.ndarray:
        return np.broadcast_to(self.velocity, q.shape).copy()

    @property
    def is_zero(self) -> bool:
        return not np.any(self.velocity)

    def to_spec(self) -> dict:
        return {"kind": self.kind, "velocity": self.velocity.tolist()}


@dataclass(frozen=True)
class Goal(Field):
    """U = speed (g - q) / max(|g - q|, slow_radius): full speed towards the goal, slowing
    down linearly inside ``slow_radius`` (m) so the field is Lipschitz (constant 2 speed / slow_radius)."""

    goal: np.ndarray
    speed: float
    slow_radius: float = 0.5
    kind = "goal"

    def __call__(self, t: float, q: np.ndarray) -> np.ndarray:
        q = np.ascontiguousarray(q, dtype=np.float64)
        out = np.empty(q.shape)
        towards_goal(float(self.goal[0]), float(self.goal[1]), float(self.speed),
                     float(self.slow_radius), q, out)
        return out

    def to_spec(self) -> dict:
        return {"kind": self.kind, "goal": self.goal.tolist(), "speed": self.speed,
                "slow_radius": self.slow_radius}


@numba.njit(cache=True, nogil=True)
def towards_goal(gx: float, gy: float, speed: float, slow: float, q: np.ndarray,
                 out: np.ndarray) -> None:  # pragma: no cover - compiled
    """:class:`Goal`'s field into out (N, 2) m/s at q (N, 2) m, in numpy's order of operations
    (d = g - q, |d| as einsum's x then y, speed / np.maximum(|d|, slow) (NaN propagated), d
    times it)."""
    for i in range(q.shape[0]):
        dx, dy = gx - q[i, 0], gy - q[i, 1]
        dist = math.sqrt(dx * dx + dy * dy)
        f = speed / (dist if (dist >= slow or dist != dist) else slow)
        out[i, 0] = dx * f
        out[i, 1] = dy * f


@dataclass(frozen=True)
class Linear(Field):
    """U(q_i) = A q_i + offset."""

    matrix: np.ndarray
    offset: np.ndarray
    kind = "linear"

    def __call__(self, t: float, q: np.ndarray) -> np.ndarray:
        # written out, not through BLAS (whose kernels round differently on different CPUs)
        m = self.matrix
        return np.stack([q[:, 0] * m[0, 0] + q[:, 1] * m[0, 1],
                         q[:, 0] * m[1, 0] + q[:, 1] * m[1, 1]], axis=1) + self.offset

    def to_spec(self) -> dict:
        return {"kind": self.kind, "matrix": self.matrix.tolist(), "offset": self.offset.tolist()}


@dataclass(frozen=True)
class PerAgent(Field):
    """A constant velocity per agent, shape (N, 2)."""

    velocities: np.ndarray
    kind = "per_agent"

    def __call__(self, t: float, q: np.ndarray) -> np.ndarray:
        return self.velocities.copy()

    @property
    def is_zero(self) -> bool:
        return not np.any(self.velocities)

    def to_spec(self) -> dict:
        return {"kind": self.kind, "velocities": self.velocities.tolist()}


@dataclass(frozen=True)
class Grid(Field):
    """A sampled field on a regular grid, bilinearly interpolated.

    ``x`` (W,) and ``y`` (H,) are strictly increasing, evenly spaced node coordinates (m);
    ``vx``, ``vy`` have shape (H, W) (row = y index). Outside the grid the field takes the
    value at the nearest point of the grid (coordinates are clamped), so it stays Lipschitz.
    """

    x: np.ndarray
    y: np.ndarray
    vx: np.ndarray
    vy: np.ndarray
    kind = "grid"

    def __call__(self, t: float, q: np.ndarray) -> np.ndarray:
        fx, ix = grid_cell(self.x, q[:, 0])
        fy, iy = grid_cell(self.y, q[:, 1])
        out = np.empty_like(q)
        for c, v in enumerate((self.vx, self.vy)):
            v00, v01 = v[iy, ix], v[iy, ix + 1]
            v10, v11 = v[iy + 1, ix], v[iy + 1, ix + 1]
            out[:, c] = (1 - fy) * ((1 - fx) * v00 + fx * v01) + fy * ((1 - fx) * v10 + fx * v11)
        return out

    def to_spec(self) -> dict:
        return {"kind": self.kind, "x": self.x.tolist(), "y": self.y.tolist(),
                "vx": self.vx.tolist(), "vy": self.vy.tolist()}


@dataclass(frozen=True, eq=False)
class Groups(Field):
    """Groups of agents with their own drift: agents ``members[k]`` (indices) follow
    ``fields[k]`` (evaluated at their positions only, so a per_agent field gives one velocity
    per member); agents in no group follow ``rest``. Each member field is bounded and
    Lipschitz, hence so is the whole (agent by agent).

    ``names[k]``: the group's name (a ROS topic name token, [A-Za-z][A-Za-z0-9_]*, unique);
    ``speeds[k]``: its preferred speed (m/s), the speed a goal command for the group uses;
    ``given[k]``: its agents as the spec gave them (a list of indices or {range: [a, b]})."""

    members: tuple[np.ndarray, ...]
    fields: tuple[Field, ...]
    rest: Field
    names: tuple[str, ...]
    speeds: tuple[float, ...]
    given: tuple[Any, ...]
    kind = "groups"

    def __call__(self, t: float, q: np.ndarray) -> np.ndarray:
        out = self.rest(t, q)
        for idx, f in zip(self.members, self.fields):
            out[idx] = f(t, q[idx])
        return out

    @property
    def is_zero(self) -> bool:
        return self.rest.is_zero and all(f.is_zero for f in self.fields)

    def index(self, name: str) -> int:
        """The index of the group called ``name`` (SceneError naming the groups if none)."""
        if name in self.names:
            return self.names.index(name)
        raise SceneError("group", f"{show(name)} is not a group of the scene (its groups: "
                         f"{', '.join(self.names)})", "name one of the scene's groups")

    def with_member_drift(self, k: int, field: Field) -> Groups:
        """A copy in which group k (0-based) follows ``field`` (any field but groups, built
        for its members: a per_agent field has one row per member); the names, members,
        speeds and the rest are kept, and :meth:`to_spec` records the new drift (so a
        recording of it replays)."""
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not (
                0 <= k < len(self.fields)):
            raise SceneError("group", f"{show(k)} is not a group index (the scene has "
                             f"{len(self.fields)} groups: {', '.join(self.names)})",
                             f"give a group index from 0 to {len(self.fields) - 1}")
        if not isinstance(field, Field) or isinstance(field, Groups):
            what = field.kind if isinstance(field, Field) else type(field).__name__
            raise SceneError(f"groups[{int(k)}].drift", f"must be a plain sweep_core Field, "
                             f"got {what}", "give the group a goal, geodesic, uniform, ... field")
        fields = list(self.fields)
        fields[int(k)] = field
        return replace(self, fields=tuple(fields))

    def group_specs(self) -> list[dict]:
        """The groups as normalised scene dicts: [{name, agents, drift, speed}, ...]."""
        return [{"name": name, "agents": copy.deepcopy(given), "drift": f.to_spec(),
                 "speed": speed}
                for name, given, f, speed in zip(self.names, self.given, self.fields,
                                                  self.speeds)]

    def to_spec(self) -> dict:
        return {"kind": self.kind, "groups": self.group_specs(), "rest": self.rest.to_spec()}


def grid_cell(nodes: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cell index and fraction of coordinates s on sorted nodes, clamped to the grid."""
    if nodes.size == 1:
        return np.zeros_like(s), np.zeros(s.shape, dtype=np.intp)
    s = np.clip(s, nodes[0], nodes[-1])
    i = np.clip(np.searchsorted(nodes, s, side="right") - 1, 0, nodes.size - 2)
    return (s - nodes[i]) / (nodes[i + 1] - nodes[i]), i


def grid_field(x: np.ndarray, y: np.ndarray, vx: np.ndarray, vy: np.ndarray,
               field: str = "drift") -> Grid:
    """Validate and build a :class:`Grid` field (see its docstring for shapes)."""
    x = checks.within_bound(checks.array(x, f"{field}.x", (None,), "",
                                         f"write {field}.x as a list of numbers (m)"), f"{field}.x")
    y = checks.within_bound(checks.array(y, f"{field}.y", (None,), "",
                                         f"write {field}.y as a list of numbers (m)"), f"{field}.y")
    for name, nodes in (("x", x), ("y", y)):
        if nodes.size < 1:
            raise SceneError(f"{field}.{name}", "is empty []",
                             f"give at least one node in {field}.{name}")
        if nodes.size > 1:
            step = np.diff(nodes)
            if np.any(step <= 0):
                k = int(np.argmax(step <= 0))
                raise SceneError(f"{field}.{name}",
                                 f"must be strictly increasing, got {show(nodes)} (node {k + 1} "
                                 f"= {nodes[k + 1]:g} after {nodes[k]:g})",
                                 f"sort {field}.{name} and drop repeated nodes")
            if np.max(np.abs(step - step[0])) > 1e-6 * abs(step[0]):
                raise SceneError(f"{field}.{name}",
                                 f"is an irregular grid {show(nodes)}: spacings from "
                                 f"{float(step.min()):g} to {float(step.max()):g}",
                                 "resample onto evenly spaced nodes")
    rows = f"give {y.size} rows (one per y node) of {x.size} numbers (one per x node), m/s"
    vx = checks.array(vx, f"{field}.vx", (y.size, x.size), "(rows along y, columns along x)",
                      rows)
    vy = checks.array(vy, f"{field}.vy", (y.size, x.size), "(rows along y, columns along x)",
                      rows)
    if x.size == 1:  # degenerate axis: duplicate so interpolation is well defined
        x, vx, vy = np.array([x[0], x[0] + 1.0]), np.repeat(vx, 2, 1), np.repeat(vy, 2, 1)
    if y.size == 1:
        y, vx, vy = np.array([y[0], y[0] + 1.0]), np.repeat(vx, 2, 0), np.repeat(vy, 2, 0)
    return Grid(x=x, y=y, vx=vx, vy=vy)


_KEYS = {
    "none": set(),
    "uniform": {"velocity"},
    "goal": {"goal", "speed"},
    "linear": {"matrix"},
    "per_agent": {"velocities"},
    "grid": {"x", "y", "vx", "vy"},
}
_OPTIONAL = {"goal": {"slow_radius"}, "linear": {"offset"}}
#: navigation fields, built against the scene's geometry (:mod:`sweep_core.model.geodesic`)
NAVIGATION_KINDS = ("geodesic", "exits")
FIELD_KINDS = tuple(_KEYS) + NAVIGATION_KINDS + ("groups",)
#: the plain kinds (built here)
PLAIN_KINDS = tuple(_KEYS)
#: the kinds that take a speed: a group's speed fills it in when the group's drift omits it
SPEED_KINDS = ("goal",) + NAVIGATION_KINDS
#: preferred speed (m/s) of agents and groups when the scene gives none
DEFAULT_SPEED = 1.3


def plain_field_from_spec(spec: dict, kind: str, n_agents: int, field: str = "drift") -> Field:
    """Build a field of a plain ``kind`` (none, uniform, goal, linear, per_agent, grid) from
    its scene dict ``spec`` (a mapping whose kind has been read); the navigation kinds are
    built by :mod:`sweep_core.model.geodesic`, the groups and the dispatch over every kind by
    :func:`sweep_core.model.drift.field_from_spec`. n_agents: the agents it drives (a
    per_agent field gives one velocity per agent)."""
    checks.mapping(spec, field, allowed={"kind"} | _KEYS[kind] | _OPTIONAL.get(kind, set()),
                   required=_KEYS[kind])
    if kind == "uniform":
        velocity = checks.vec2(spec["velocity"], f"{field}.velocity")
        return Uniform(velocity=checks.velocities(velocity[None], f"{field}.velocity")[0])
    if kind == "goal":
        return Goal(goal=checks.point(spec["goal"], f"{field}.goal"),
                    speed=checks.speed(spec["speed"], f"{field}.speed"),
                    slow_radius=checks.number(spec.get("slow_radius", 0.5), f"{field}.slow_radius",
                                              positive=True))
    if kind == "linear":
        return Linear(matrix=checks.array(spec["matrix"], f"{field}.matrix", (2, 2),
                                          "as [[a, b], [c, d]]",
                                          f"write {field}.matrix as [[a, b], [c, d]] (1/s)"),
                      offset=checks.vec2(spec.get("offset", [0.0, 0.0]), f"{field}.offset"))
    if kind == "per_agent":
        return PerAgent(velocities=checks.velocities(checks.array(
            spec["velocities"], f"{field}.velocities", (n_agents, 2), "(one [vx, vy] per agent)",
            f"give {field}.velocities one [vx, vy] (m/s) for each of the {n_agents} agents"),
            f"{field}.velocities", each=True))
    if kind == "grid":
        return grid_field(spec["x"], spec["y"], spec["vx"], spec["vy"], field)
    return NoDrift()
