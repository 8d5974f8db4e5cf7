"""Exit choice (the scene's optional ``flows.exit_choice``): a group's agents choose among
several exits by estimated time, and re-choose at every step.

    flows:
      exit_choice:
        - group: NAME            # omitted: the agents in no group
          exits: [{region: {...}} | {goal: [x, y]}, ...]      2 to MAX_EXITS
          capacity: C | [C_0, ...]                            1/s, > 0 (default 1.2)
          cell, wall_buffer                                    as for the geodesic drift

Each exit k gets a geodesic field round the walls (its travel distance T_k, m). Agent i's
estimated time by exit k is

    E_ik = T_k(q_i) / v_i + n_ik / C_k,

its walk at its preferred speed v_i (m/s) plus the wait behind the n_ik agents assigned to
exit k before it, at the exit's flow C_k (1/s). Agents are assigned one after the other in
order of their least walking time min_k T_k / v_i (ties by id), each to the exit of least
E_ik (ties: the lower index), so the nearest agents take their nearest exit and the ones
behind turn to another exit once the queue makes it quicker
(:func:`sweep_core.numerics.exit_choice.assign`). The assignment depends on the positions
alone, so a run replays bit for bit. The default capacity, 1.2 per second, is the flow of a
1 m door with the default speed law (docs/validation.md, the bottleneck).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from sweep_core import checks
from sweep_core.errors import SceneError, show
from sweep_core.model.fields import Field
from sweep_core.model.regions import target_from_spec
from sweep_core.model.travel import reaches

#: most exits of one choice
MAX_EXITS = 16
#: an exit's flow (1/s) when the scene gives none
DEFAULT_CAPACITY = 1.2


@dataclass(frozen=True, eq=False)
class ExitChoice:
    """A group's choice among exits (module docstring): ``group`` (-1: the agents in no
    group), ``fields[k]`` the geodesic field to exit k (``travel_distance`` gives T_k),
    ``capacity`` (K,) 1/s, ``spec`` the normalised dict."""

    group: int
    fields: tuple[Field, ...]
    capacity: np.ndarray
    spec: dict


def exit_choice_from_spec(value: Any, field: str, group: int, group_name: str | None,
                          speed: float, geometry: Any, grid: Any,
                          first: np.ndarray | None = None) -> ExitChoice:
    """One entry of ``flows.exit_choice`` (``field`` names it) for the group ``group``
    (already checked), whose drift moves at ``speed`` m/s; ``first`` (M, 2) m: the group's
    initial agents, each of which must have a way to some exit."""
    from sweep_core.model.geodesic import navigation_from_spec  # built on fields

    checks.mapping(value, field, required={"exits"},
                   allowed={"group", "exits", "capacity", "cell", "wall_buffer"})
    raw = value["exits"]
    if not isinstance(raw, list) or not 2 <= len(raw) <= MAX_EXITS:
        raise SceneError(f"{field}.exits", f"must be a list of 2 to {MAX_EXITS} exits, got "
                         f"{show(raw)}", f"write {field}.exits as [{{region: {{...}}}}, "
                         "{goal: [x, y]}, ...], one item per exit")
    cap = value.get("capacity", DEFAULT_CAPACITY)
    fix = (f"give {field}.capacity the flow of each exit (1/s, > 0): one number or one per "
           f"exit ({len(raw)} exits)")
    if isinstance(cap, list):
        capacity = checks.array(cap, f"{field}.capacity", (len(raw),), "(one per exit)", fix)
        if np.any(capacity <= 0):
            k = int(np.argmin(capacity))
            raise SceneError(f"{field}.capacity[{k}]", f"must be > 0, got {show(capacity[k])}",
                             fix)
    else:
        capacity = np.full(len(raw), checks.number(cap, f"{field}.capacity", positive=True,
                                                   fix=fix))
    extra = {k: value[k] for k in ("cell", "wall_buffer") if k in value}
    fields, exits = [], []
    for k, e in enumerate(raw):
        ef = f"{field}.exits[{k}]"
        _, one = target_from_spec(e, ef)
        exits.append(one)
        fields.append(navigation_from_spec({"kind": "geodesic", **one, "speed": speed, **extra},
                                           ef, geometry, grid, np.empty((0, 2))))
    if first is not None and len(first):
        ok = np.zeros(len(first), dtype=bool)
        for f in fields:
            ok |= reaches(first, f.x, f.y, f.free, f.travel)
        if not np.all(ok):
            a = int(np.flatnonzero(~ok)[0])
            raise SceneError(f"{field}.exits", f"the group's agent {a} at {show(first[a])} has "
                             "no way to any of the exits round the walls",
                             f"open a passage, lower {field}.wall_buffer, or add an exit it can "
                             "reach")
    spec = {**({"group": group_name} if group_name is not None else {}), "exits": exits,
            "capacity": capacity.tolist(), **extra}
    return ExitChoice(group, tuple(fields), np.asarray(capacity, dtype=np.float64), spec)
