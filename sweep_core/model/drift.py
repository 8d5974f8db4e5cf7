"""A drift from its scene dict, any kind (:func:`field_from_spec`), and a scene's drift with
its ``agents.groups`` (:func:`scene_drift`). The modules it builds on import one way:
:mod:`~sweep_core.model.fields` (the plain kinds) <- :mod:`~sweep_core.model.geodesic` (the
navigation kinds) <- :mod:`~sweep_core.model.groups` (groups of agents) <- this module."""
from __future__ import annotations

from typing import Any

import numpy as np

from sweep_core import checks
from sweep_core.errors import SceneError
from sweep_core.model.fields import DEFAULT_SPEED, FIELD_KINDS, Field, NoDrift
from sweep_core.model.groups import groups_from_spec, member_field_from_spec


def field_from_spec(spec: dict | None, n_agents: int, field: str = "drift",
                    geometry: Any = None, grid: Any = None,
                    positions: np.ndarray | None = None,
                    speed: float = DEFAULT_SPEED) -> Field:
    """Build a drift field from its scene dict (see docs/schema.md). The
    navigation kinds (geodesic, exits) need the scene's geometry (a
    :class:`~sweep_core.model.geometry.Geometry`), its map (an
    :class:`~sweep_core.model.maps.OccupancyMap` or None) and the agents' positions (N, 2) m.
    speed: the preferred speed (m/s) of a group that gives none (the scene's agents.speed)."""
    if spec is None:
        return NoDrift()
    checks.mapping(spec, field)
    kind = checks.kind(spec, field, FIELD_KINDS, default="none")
    if kind == "groups":
        checks.mapping(spec, field, allowed={"kind", "groups", "rest"}, required={"groups"})
        return groups_from_spec(spec["groups"], spec.get("rest"), n_agents, f"{field}.groups",
                                f"{field}.rest", geometry, grid, positions, speed)
    return member_field_from_spec(spec, n_agents, field, geometry, grid, positions)


def scene_drift(raw: Any, groups: Any, n_agents: int, geometry: Any, grid: Any,
                positions: np.ndarray, speed: float) -> tuple[Field, dict, list | None]:
    """A scene's drift: its ``drift`` (``raw``), or with ``agents.groups`` (``groups``, None if
    absent) the groups' drifts and ``raw`` for the agents in no group; speed: agents.speed
    (m/s), the default group speed. Returns the field and the normalised ``drift`` and
    ``agents.groups`` (None without groups) of the scene's spec."""
    if groups is None:
        f = field_from_spec(raw, n_agents, geometry=geometry, grid=grid, positions=positions,
                            speed=speed)
        return f, f.to_spec(), None
    if isinstance(raw, dict) and raw.get("kind") == "groups":
        raise SceneError("agents.groups", "is given with drift: {kind: groups}",
                         "give the groups in one place: agents.groups (each with its drift), "
                         "and in drift the drift of the agents in no group")
    g = groups_from_spec(groups, raw, n_agents, "agents.groups", "drift", geometry, grid,
                         positions, speed, authored=True)
    return g, g.rest.to_spec(), g.group_specs()
