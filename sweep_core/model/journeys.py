"""Journeys (the scene's optional ``flows.journeys``): an ordered list of targets per group,
each leg a geodesic field round the walls to its target (docs/flows.md), validated into a
:class:`Journey`; :mod:`sweep_core.model.flows` calls :func:`journey_from_spec`.

    journeys: [{group, legs: [{goal: [x, y]} | {region: {...}}, ...], arrive_radius,
                cell, wall_buffer}, ...]

The group's initial agents must have a way to the first leg's target, and each goal point a
way to the next leg's target (a leg that ends at a region is left anywhere along its edge:
not checked).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from sweep_core import checks
from sweep_core.errors import SceneError, show
from sweep_core.model.fields import Field, Groups
from sweep_core.model.regions import Region, target_from_spec
from sweep_core.model.travel import reaches

#: most legs of a journey
MAX_LEGS = 64


@dataclass(frozen=True, eq=False)
class Journey:
    """A group's legs (-1: the agents in no group): ``fields[k]`` leads to ``targets[k]`` (a
    Region or a goal point (2,)), reached when the centre is within ``arrive_radius`` m of it
    (inside a region counts as 0 m; a geodesic field slows to a halt at a region's edge, so
    the radius is needed for regions too)."""

    group: int
    fields: tuple[Field, ...]
    targets: tuple[Region | np.ndarray, ...]
    arrive_radius: float
    spec: dict

    def reached(self, leg: int, q: np.ndarray) -> np.ndarray:
        """(M,) bool: centres q (M, 2) reached target ``leg``."""
        tg = self.targets[leg]
        if isinstance(tg, Region):  # the field slows to a halt at the region's edge
            return tg.distance(q) <= self.arrive_radius
        d = q - tg
        return np.hypot(d[:, 0], d[:, 1]) <= self.arrive_radius


def members(drift: Field, group: int, n: int, positions: np.ndarray | None) -> np.ndarray:
    """The positions (M, 2) m of the initial agents of ``group`` (-1: those in no group);
    none when ``positions`` is None."""
    if positions is None:
        return np.empty((0, 2))
    if not isinstance(drift, Groups):
        return positions if group < 0 else np.empty((0, 2))
    mine = np.zeros(n, dtype=bool)
    if group >= 0:
        mine[drift.members[group]] = True
    else:
        mine[:] = True
        for idx in drift.members:
            mine[idx] = False
    return positions[mine]


def journey_from_spec(value: Any, field: str, group: int, names: tuple[str, ...],
                      speed: float, geometry: Any, grid: Any, first: np.ndarray) -> Journey:
    """One entry of ``flows.journeys`` (``field`` names it) for the group ``group`` (already
    checked; -1: the agents in no group, ``names`` the scene's groups), whose drift moves at
    ``speed`` m/s; ``first`` (M, 2) m: the centres that must have a way to its first target
    (the group's initial agents)."""
    from sweep_core.model.geodesic import navigation_from_spec  # built on fields

    checks.mapping(value, field, required={"legs"},
                   allowed={"group", "legs", "arrive_radius", "cell", "wall_buffer"})
    legs = value["legs"]
    if not isinstance(legs, list) or not legs or len(legs) > MAX_LEGS:
        raise SceneError(f"{field}.legs", f"must be a non-empty list of at most {MAX_LEGS} "
                         f"targets, got {show(legs)}",
                         f"write {field}.legs as [{{goal: [x, y]}}, {{region: {{...}}}}, ...]")
    arrive = checks.length(value.get("arrive_radius", 0.5), f"{field}.arrive_radius",
                           positive=True)
    extra = {k: value[k] for k in ("cell", "wall_buffer") if k in value}
    fields, targets, legs_spec = [], [], []
    for k, leg in enumerate(legs):
        lf = f"{field}.legs[{k}]"
        tg, one = target_from_spec(leg, lf)
        legs_spec.append(one)
        targets.append(tg)
        f = navigation_from_spec({"kind": "geodesic", **one, "speed": speed, **extra}, lf,
                                 geometry, grid, np.empty((0, 2)))
        start = first if k == 0 else leg_start(targets[k - 1])
        ok = reaches(start, f.x, f.y, f.free, f.travel)
        if not np.all(ok):
            a = int(np.flatnonzero(~ok)[0])
            who = (f"the group's agent {a} at" if k == 0 else "the previous leg's goal")
            raise SceneError(lf, f"{who} {show(start[a])} has no way to the goal round the "
                             f"walls (keeping {field}.wall_buffer from them)",
                             f"open a passage, lower {field}.wall_buffer, or move the target")
        fields.append(f)
    spec = {**({"group": names[group]} if group >= 0 else {}), "legs": legs_spec,
            "arrive_radius": arrive, **extra}
    return Journey(group, tuple(fields), tuple(targets), arrive, spec)


def leg_start(target: Region | np.ndarray) -> np.ndarray:
    """Where the agents start a leg (M, 2) m: the previous leg's goal point (a region's agents
    stop anywhere along its edge: not checked)."""
    return np.empty((0, 2)) if isinstance(target, Region) else target.reshape(1, 2)
