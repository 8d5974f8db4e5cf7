"""Groups of agents with their own drift and preferred speed: the scene's ``agents.groups``
and the ``groups`` drift kind, both built as one :class:`~sweep_core.model.fields.Groups`
field.

    agents.groups: [{name: group<k>, agents: [i, ...] | {range: [start, stop]}, drift: {...},
                     speed: m/s}, ...]          the others follow the scene's drift
    drift: {kind: groups, groups: [same], rest: {...}}

``name``: a ROS topic name token ([A-Za-z][A-Za-z0-9_]*), unique (a node can give each group
its own topics). ``speed`` (> 0): the group's preferred speed; see :func:`groups_from_spec`.
"""
from __future__ import annotations

import re
from typing import Any

import numpy as np

from sweep_core import checks
from sweep_core.errors import SceneError, show
from sweep_core.model.fields import (
    DEFAULT_SPEED,
    FIELD_KINDS,
    NAVIGATION_KINDS,
    SPEED_KINDS,
    Field,
    Groups,
    NoDrift,
    plain_field_from_spec,
)
from sweep_core.model.geodesic import navigation_from_spec

#: a group's name: a ROS topic name token
GROUP_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*")


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


def _name(value: Any, field: str, k: int, seen: dict[str, int]) -> str:
    """A group's name: a ROS topic name token, unique among the groups."""
    fix = (f"name the group with a letter followed by letters, digits or underscores, "
           f"e.g. {field}: group{k}")
    if not isinstance(value, str) or GROUP_NAME.fullmatch(value) is None:
        raise SceneError(field, f"{show(value)} is not a valid group name (a ROS topic name "
                         "token: [A-Za-z][A-Za-z0-9_]*)", fix)
    if value in seen:
        raise SceneError(field, f"{show(value)} is the name of group {seen[value]} too",
                         "give each group its own name")
    seen[value] = k
    return value


def groups_from_spec(raw: Any, rest_spec: Any, n_agents: int, field: str, rest_field: str,
                     geometry: Any = None, grid: Any = None,
                     positions: np.ndarray | None = None, speed: float = DEFAULT_SPEED,
                     authored: bool = False) -> Groups:
    """Validate and build a :class:`Groups` field from its list of groups ``raw`` (named
    ``field`` in errors: ``drift.groups`` or ``agents.groups``), each ``{name, agents, drift,
    speed}``, and the others' drift ``rest_spec`` (named ``rest_field``).

    A group's ``speed`` (m/s, > 0; default: its drift's own speed if the drift kind takes
    one, else ``speed``) fills in the speed of a goal, geodesic or exits drift that gives none,
    and is the speed of goal commands for the group. A drift that gives its own speed moves at
    it; with ``authored`` (a scene's ``agents.groups``) a drift speed that differs from the
    group's speed is refused instead (say it once)."""
    if not isinstance(raw, list) or not raw:
        raise SceneError(field, f"must be a non-empty list, got {show(raw)}",
                         f"write {field} as a list of {{name, agents: [...], drift: {{...}}, "
                         "speed}")
    taken: dict[int, int] = {}
    seen: dict[str, int] = {}
    members, fields, names, speeds, given = [], [], [], [], []
    for k, g in enumerate(raw):
        gf = f"{field}[{k}]"
        checks.mapping(g, gf, allowed={"name", "agents", "drift", "speed"},
                       required={"agents", "drift"})
        names.append(_name(g.get("name", f"group{k}"), f"{gf}.name", k, seen))
        idx = _members(g["agents"], n_agents, f"{gf}.agents", taken, k)
        own = (checks.speed(g["speed"], f"{gf}.speed", positive=True,
                             fix=f"set {gf}.speed to the group's preferred speed, a number "
                                 "> 0 (m/s)")
               if g.get("speed") is not None else None)
        sub = g["drift"]
        if isinstance(sub, dict) and sub.get("kind") == "groups":
            raise SceneError(f"{gf}.drift.kind", "is groups inside a group",
                             "give each group a plain drift (goal, geodesic, ...)")
        if isinstance(sub, dict) and sub.get("kind") in SPEED_KINDS:
            if sub.get("speed") is None:
                sub = {**sub, "speed": speed if own is None else own}
            elif authored and own is not None and _differs(sub["speed"], own):
                raise SceneError(f"{gf}.drift.speed", f"{sub['speed']:g} m/s differs from "
                                 f"{gf}.speed {own:g} m/s",
                                 f"give the speed once: drop {gf}.drift.speed (the group's "
                                 "speed fills it in) or make the two equal")
        pos = None if positions is None else positions[idx]
        f = member_field_from_spec(sub, len(idx), f"{gf}.drift", geometry, grid, pos)
        fields.append(f)
        if own is None:
            own = float(getattr(f, "speed", speed))
        speeds.append(own)
        members.append(idx)
        agents = g["agents"]
        given.append({"range": [int(idx[0]), int(idx[-1]) + 1]} if isinstance(agents, dict)
                     else idx.tolist())
    if isinstance(rest_spec, dict) and rest_spec.get("kind") == "groups":
        raise SceneError(f"{rest_field}.kind", "is groups inside groups",
                         f"give {rest_field} a plain drift (goal, geodesic, ...)")
    others = None
    if positions is not None:  # the rest's agents (a navigation field checks their way)
        alone = np.ones(len(positions), dtype=bool)
        alone[list(taken)] = False
        others = positions[alone]
    rest = member_field_from_spec(rest_spec, n_agents, rest_field, geometry, grid, others)
    return Groups(members=tuple(members), fields=tuple(fields), rest=rest, names=tuple(names),
                  speeds=tuple(speeds), given=tuple(given))


def _differs(value: Any, speed: float) -> bool:
    """value is a number other than speed (m/s); anything else is left to the drift's own
    validation."""
    return (isinstance(value, (int, float, np.integer, np.floating))
            and not isinstance(value, bool) and float(value) != speed)


def member_field_from_spec(spec: Any, n_agents: int, field: str = "drift", geometry: Any = None,
                           grid: Any = None, positions: np.ndarray | None = None) -> Field:
    """Build a drift of any kind but ``groups`` from its scene dict (None: no drift): a plain
    kind (:func:`~sweep_core.model.fields.plain_field_from_spec`) or a navigation kind, which
    needs the scene's geometry, its map (or None) and the positions (N, 2) m of the agents it
    drives (:func:`~sweep_core.model.geodesic.navigation_from_spec`)."""
    if spec is None:
        return NoDrift()
    checks.mapping(spec, field)
    kind = checks.kind(spec, field, FIELD_KINDS, default="none")
    if kind == "groups":
        raise SceneError(f"{field}.kind", "is groups inside groups",
                         f"give {field} a plain drift (goal, geodesic, ...)")
    if kind in NAVIGATION_KINDS:
        return navigation_from_spec(spec, field, geometry, grid,
                                    np.empty((0, 2)) if positions is None else positions)
    return plain_field_from_spec(spec, kind, n_agents, field)
