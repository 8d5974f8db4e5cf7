"""Wished-velocity fields U(t, q): the drift of the sweeping process.

Every field maps positions q, shape (N, 2) in metres, to velocities, shape (N, 2) in m/s, and
is Lipschitz in q (the well-posedness assumption of the model, reference §3). ``max_speed``
bounds |U| (m/s) and feeds the constraint cutoff.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

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
        d = self.goal - q
        dist = np.sqrt(np.einsum("ij,ij->i", d, d))
        return d * (self.speed / np.maximum(dist, self.slow_radius))[:, None]

    def to_spec(self) -> dict:
        return {"kind": self.kind, "goal": self.goal.tolist(), "speed": self.speed,
                "slow_radius": self.slow_radius}


@dataclass(frozen=True)
class Linear(Field):
    """U(q_i) = A q_i + offset."""

    matrix: np.ndarray
    offset: np.ndarray
    kind = "linear"

    def __call__(self, t: float, q: np.ndarray) -> np.ndarray:
        return q @ self.matrix.T + self.offset

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
    Lipschitz, hence so is the whole (agent by agent)."""

    members: tuple[np.ndarray, ...]
    fields: tuple[Field, ...]
    rest: Field
    spec: dict
    kind = "groups"

    def __call__(self, t: float, q: np.ndarray) -> np.ndarray:
        out = self.rest(t, q)
        for idx, f in zip(self.members, self.fields):
            out[idx] = f(t, q[idx])
        return out

    @property
    def is_zero(self) -> bool:
        return self.rest.is_zero and all(f.is_zero for f in self.fields)

    def to_spec(self) -> dict:
        return {"kind": self.kind, "groups": [
            {"agents": g["agents"], "drift": f.to_spec()} for g, f in zip(self.spec["groups"],
                                                                         self.fields)],
                "rest": self.rest.to_spec()}


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
    x = checks.array(x, f"{field}.x", (None,), "", f"write {field}.x as a list of numbers (m)")
    y = checks.array(y, f"{field}.y", (None,), "", f"write {field}.y as a list of numbers (m)")
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


def field_from_spec(spec: dict | None, n_agents: int, field: str = "drift",
                    geometry: Any = None, grid: Any = None,
                    positions: np.ndarray | None = None) -> Field:
    """Build a drift field from its scene dict (see the README's scene schema). The
    navigation kinds (geodesic, exits) need the scene's geometry (a
    :class:`~sweep_core.model.geometry.Geometry`), its map (an
    :class:`~sweep_core.model.maps.OccupancyMap` or None) and the agents' positions (N, 2) m."""
    if spec is None:
        return NoDrift()
    checks.mapping(spec, field)
    kind = checks.kind(spec, field, FIELD_KINDS, default="none")
    if kind == "groups":
        return _groups(spec, n_agents, field, geometry, grid, positions)
    if kind in NAVIGATION_KINDS:
        from sweep_core.model.geodesic import navigation_from_spec  # it builds on Field

        return navigation_from_spec(spec, field, geometry, grid,
                                    np.empty((0, 2)) if positions is None else positions)
    checks.mapping(spec, field, allowed={"kind"} | _KEYS[kind] | _OPTIONAL.get(kind, set()),
                   required=_KEYS[kind])
    if kind == "uniform":
        return Uniform(velocity=checks.vec2(spec["velocity"], f"{field}.velocity"))
    if kind == "goal":
        return Goal(goal=checks.vec2(spec["goal"], f"{field}.goal"),
                    speed=checks.number(spec["speed"], f"{field}.speed", nonnegative=True),
                    slow_radius=checks.number(spec.get("slow_radius", 0.5), f"{field}.slow_radius",
                                              positive=True))
    if kind == "linear":
        return Linear(matrix=checks.array(spec["matrix"], f"{field}.matrix", (2, 2),
                                          "as [[a, b], [c, d]]",
                                          f"write {field}.matrix as [[a, b], [c, d]] (1/s)"),
                      offset=checks.vec2(spec.get("offset", [0.0, 0.0]), f"{field}.offset"))
    if kind == "per_agent":
        return PerAgent(velocities=checks.array(
            spec["velocities"], f"{field}.velocities", (n_agents, 2), "(one [vx, vy] per agent)",
            f"give {field}.velocities one [vx, vy] (m/s) for each of the {n_agents} agents"))
    if kind == "grid":
        return grid_field(spec["x"], spec["y"], spec["vx"], spec["vy"], field)
    return NoDrift()


def _members(value: Any, n_agents: int, field: str, taken: dict[int, int], k: int
             ) -> np.ndarray:
    """A group's agents: a list of indices or {range: [start, stop]} (stop excluded)."""
    fix = (f"write {field} as a list of agent indices [0, 1, ...] or as {{range: [start, "
           f"stop]}} (agents start .. stop - 1), among the {n_agents} agents")
    if isinstance(value, dict):
        checks.mapping(value, field, allowed={"range"}, required={"range"})
        r = value["range"]
        if not isinstance(r, list) or len(r) != 2:
            raise SceneError(f"{field}.range", f"must be [start, stop], got {show(r)}", fix)
        a = checks.integer(r[0], f"{field}.range[0]", low=0, fix=fix)
        b = checks.integer(r[1], f"{field}.range[1]", low=0, fix=fix)
        if b <= a:
            raise SceneError(f"{field}.range", f"{show([a, b])} holds no agent", fix)
        idx = np.arange(a, b)
    elif isinstance(value, list) and value:
        idx = np.array([checks.integer(v, f"{field}[{j}]", low=0, fix=fix)
                        for j, v in enumerate(value)], dtype=np.intp)
    else:
        raise SceneError(field, f"must be a non-empty list or a range, got {show(value)}", fix)
    over = idx[idx >= n_agents]
    if len(over):
        raise SceneError(field, f"names agent {int(over[0])} but the scene has {n_agents} "
                         "agents (indices from 0)", fix)
    for i in idx.tolist():
        if i in taken:
            raise SceneError(field, f"puts agent {i} in a second group (it is in group "
                             f"{taken[i]} already)", "put each agent in one group at most")
        taken[i] = k
    return idx


def _groups(spec: dict, n_agents: int, field: str, geometry: Any, grid: Any,
            positions: np.ndarray | None) -> Groups:
    """``{kind: groups, groups: [{agents, drift}, ...], rest: drift}`` (see :class:`Groups`)."""
    checks.mapping(spec, field, allowed={"kind", "groups", "rest"}, required={"groups"})
    raw = spec["groups"]
    if not isinstance(raw, list) or not raw:
        raise SceneError(f"{field}.groups", f"must be a non-empty list, got {show(raw)}",
                         f"write {field}.groups as a list of {{agents: [...], drift: {{...}}}}")
    taken: dict[int, int] = {}
    members, fields, given = [], [], []
    for k, g in enumerate(raw):
        gf = f"{field}.groups[{k}]"
        checks.mapping(g, gf, allowed={"agents", "drift"}, required={"agents", "drift"})
        idx = _members(g["agents"], n_agents, f"{gf}.agents", taken, k)
        sub = g["drift"]
        if isinstance(sub, dict) and sub.get("kind") == "groups":
            raise SceneError(f"{gf}.drift.kind", "is groups inside a group",
                             "give each group a plain drift (goal, geodesic, ...)")
        pos = None if positions is None else positions[idx]
        fields.append(field_from_spec(sub, len(idx), f"{gf}.drift", geometry, grid, pos))
        members.append(idx)
        agents = g["agents"]
        given.append({"agents": {"range": [int(idx[0]), int(idx[-1]) + 1]}
                      if isinstance(agents, dict) else idx.tolist()})
    rest_spec = spec.get("rest")
    if isinstance(rest_spec, dict) and rest_spec.get("kind") == "groups":
        raise SceneError(f"{field}.rest.kind", "is groups inside groups",
                         "give the rest a plain drift (goal, geodesic, ...)")
    others = None
    if positions is not None:  # the rest's agents (a navigation field checks their way)
        alone = np.ones(len(positions), dtype=bool)
        alone[list(taken)] = False
        others = positions[alone]
    rest = field_from_spec(rest_spec, n_agents, f"{field}.rest", geometry, grid, others)
    return Groups(members=tuple(members), fields=tuple(fields), rest=rest,
                  spec={"groups": given})
