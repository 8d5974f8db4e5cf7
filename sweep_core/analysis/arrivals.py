"""Arrivals for ``sweep analyze``: when each agent reached the goal of the drift in effect,
which exit it reached, and the figures per exit and per group.

An agent heads for the targets of its own drift: the scene's (or a command's) ``goal``,
``geodesic`` or ``exits`` drift, or in a ``groups`` drift (``agents.groups`` or ``{kind:
groups}``) its group's drift (the rest: ``rest``). It has arrived at the first recorded frame
in which its centre is within the arrival radius (``--arrive-radius``, default the drift's
``slow_radius``, where it starts to slow down) of a goal point or of a goal region (a
geodesic field halts agents at a region's edge, so they may never be strictly inside it);
for ``exits``, at the first exit (in the spec's order) that holds then. Exits are labelled as
in the spec, ``exits[k]``, and with the group's name in a group, ``NAME/exits[k]``.

Per exit (when an ``exits`` drift was in effect): ``agents`` heading there at t = 0 (the exit
the scene's travel-time field sends each agent's start to; None for an exits drift given by a
command), ``arrived`` there, the first, 50 %, 90 % and last of their arrival times (over the
agents that arrived there), and ``evacuation_s``: the last arrival there once every agent that
follows an exits drift has arrived somewhere (None: not all arrived). Per group: ``agents`` in
the group, ``arrived``, first, 50 % and 90 % (times at which that share of the group had
arrived), last, and ``evacuation_s``, the time its last agent arrived (None: not all arrived).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from sweep_core.errors import SweepError
from sweep_core.model.fields import Field, Groups
from sweep_core.model.geodesic import Exits, Target, navigation_targets

#: drift kinds with a goal to arrive at
GOAL_KINDS = ("goal", "geodesic", "exits")


def arrive_radius_for(arrive_radius: float | None, scene: Any) -> float | None:
    """``--arrive-radius`` (m) checked: a positive number, and given only when the recorded
    ``scene`` (a Scene or None) measures arrivals by distance. With sinks or sources an arrival
    is leaving at a sink, and with journeys or exit choices arrivals are not reported, so a
    radius would be ignored: it is refused (SweepError naming the value and the fix)."""
    if arrive_radius is None:
        return None
    if not (arrive_radius > 0 and math.isfinite(arrive_radius)):
        raise SweepError(f"--arrive-radius: must be a positive number of metres, "
                         f"got {arrive_radius!r}")
    flows = getattr(scene, "flows", None)
    if flows is not None and (flows.changes_population or flows.journeys
                              or flows.exit_choices):
        why = ("has sinks or sources: an arrival is an agent leaving at a sink, timed by the "
               "frames, with no radius" if flows.changes_population else "has journeys or "
               "exit choices: agents head elsewhere than their drift's goal and arrivals are "
               "not reported")
        raise SweepError(f"--arrive-radius {arrive_radius:g}: the scene {why} "
                         "(fix: leave out --arrive-radius)")
    return arrive_radius


def time_for(times: np.ndarray, n_agents: int, fraction: float) -> float | None:
    """Time at which ceil(fraction N) agents have a finite time (None if never)."""
    need = max(1, math.ceil(fraction * n_agents - 1e-9))
    done = np.sort(times[np.isfinite(times)])
    return float(done[need - 1]) if len(done) >= need else None


def stats(values: np.ndarray, how: Any) -> float | None:
    """how(values) over the finite values, or None if there are none."""
    ok = values[np.isfinite(values)]
    return float(how(ok)) if len(ok) else None


@dataclass(frozen=True)
class Heading:
    """Agents ``agents`` (indices; None: every agent) head for ``targets``: (label, target,
    arrival radius m) each; ``exits``: the targets are the exits of an exits drift."""

    agents: np.ndarray | None
    targets: tuple[tuple[str, Target, float], ...]
    exits: bool


def _heading(spec: dict, agents: np.ndarray | None, prefix: str,
             arrive_radius: float | None) -> Heading | None:
    kind = spec.get("kind")
    if kind not in GOAL_KINDS:
        return None
    radius = (arrive_radius if arrive_radius is not None
              else float(spec.get("slow_radius", 0.5)))
    if kind == "goal":
        goal = np.asarray(spec["goal"], dtype=np.float64)
        named = [("goal", Target(goal[None], False, {"goal": goal.tolist()}))]
    else:
        named = navigation_targets(spec)
    return Heading(agents, tuple((prefix + label, t, radius) for label, t in named),
                   kind == "exits")


def headings(spec: dict, n_agents: int, arrive_radius: float | None = None) -> list[Heading]:
    """What each of the n_agents heads for under the drift ``spec`` (a ``Field.to_spec()``)."""
    if spec.get("kind") != "groups":
        h = _heading(spec, None, "", arrive_radius)
        return [] if h is None else [h]
    out = []
    alone = np.ones(n_agents, dtype=bool)
    for k, g in enumerate(spec["groups"]):
        idx = members(g["agents"])
        alone[idx] = False
        h = _heading(g.get("drift") or {}, idx, f"{g.get('name', f'group{k}')}/",
                     arrive_radius)
        if h is not None:
            out.append(h)
    h = _heading(spec.get("rest") or {}, np.flatnonzero(alone), "", arrive_radius)
    return out if h is None else out + [h]


def members(agents: Any) -> np.ndarray:
    """A group's normalised ``agents`` (a list, or {range: [a, b]}) as indices."""
    if isinstance(agents, dict):
        a, b = agents["range"]
        return np.arange(int(a), int(b))
    return np.asarray(agents, dtype=np.intp)


def start_exits(drift: Field, q: np.ndarray) -> dict[str, int]:
    """Agents per exit label that the scene's own drift sends from positions q (N, 2)."""
    parts: list[tuple[str, Field, np.ndarray]] = []
    if isinstance(drift, Groups):
        alone = np.ones(len(q), dtype=bool)
        for name, idx, f in zip(drift.names, drift.members, drift.fields):
            alone[idx] = False
            parts.append((f"{name}/", f, idx))
        parts.append(("", drift.rest, np.flatnonzero(alone)))
    else:
        parts.append(("", drift, np.arange(len(q))))
    out: dict[str, int] = {}
    for prefix, f, idx in parts:
        if isinstance(f, Exits) and len(idx):
            counts = np.bincount(f.target_of(q[idx]), minlength=len(f.spec["exits"]))
            out.update({f"{prefix}exits[{k}]": int(c) for k, c in enumerate(counts)})
    return out


class ArrivalTracker:
    """Arrival time and exit of every agent, frame by frame (see the module docstring)."""

    def __init__(self, n_agents: int, arrive_radius: float | None,
                 start: dict[str, int] | None = None) -> None:
        self.n, self.arrive_radius = n_agents, arrive_radius
        self.arrival = np.full(n_agents, np.nan)
        #: index into ``labels`` of the exit each agent reached (-1: none, or not an exit)
        self.exit = np.full(n_agents, -1, dtype=np.intp)
        self.labels: list[str] = []
        self.start = start or {}
        #: agents that followed an exits drift at some frame
        self.exit_followers = np.zeros(n_agents, dtype=bool)
        self.groups: dict[str, np.ndarray] = {}
        self.radii: set[float] = set()
        self.seen = False
        self._plans: dict[int, tuple[dict, list[Heading]]] = {}

    def _plan(self, spec: dict) -> list[Heading]:
        key = id(spec)
        if key not in self._plans:  # the schedule hands out the same dict for each spec
            self._plans[key] = (spec, headings(spec, self.n, self.arrive_radius))
            if spec.get("kind") == "groups":
                for k, g in enumerate(spec["groups"]):
                    self.groups.setdefault(g.get("name", f"group{k}"), members(g["agents"]))
        return self._plans[key][1]

    def add(self, spec: dict, q: np.ndarray, t: float) -> bool:
        """Marks the agents that have arrived in the frame q (N, 2) at t (s) under the drift
        ``spec``; False if no agent heads for a goal under it."""
        plan = self._plan(spec)
        if not plan:
            return False
        self.seen = True
        for h in plan:
            idx = np.arange(self.n) if h.agents is None else h.agents
            if h.exits:  # every exit is listed, reached or not, in the spec's order
                self.exit_followers[idx] = True
                self.labels += [lb for lb, _, _ in h.targets if lb not in self.labels]
            todo = idx[np.isnan(self.arrival[idx])]
            for label, target, radius in h.targets:
                self.radii.add(radius)
                if not len(todo):
                    break
                # within radius of a region too: the field slows agents to a halt at its
                # edge (within a grid cell), so "inside" may take for ever
                hit = target.nearest(q[todo])[0] <= radius
                now = todo[hit]
                self.arrival[now] = t
                if h.exits:
                    self.exit[now] = self.labels.index(label)
                todo = todo[~hit]
        return True

    def summary(self, n: int) -> dict:
        """The arrivals of ``n`` agents in all: the radii, how many arrived and when (first,
        mean, 50 %, 90 %, all)."""
        radii, arrival = sorted(self.radii), self.arrival
        return {
            "radius_m": radii[0] if len(radii) == 1 else radii,
            "arrived": int(np.count_nonzero(np.isfinite(arrival))),
            "t_first_s": stats(arrival, np.min),
            "t_mean_s": stats(arrival, np.mean),
            "t_50_s": time_for(arrival, n, 0.5),
            "t_90_s": time_for(arrival, n, 0.9),
            "t_all_s": time_for(arrival, n, 1.0),
            "precision": "float64 (/poses); first recorded frame within the radius of the "
                         "goal (point or region) in effect (default radius: the goal's "
                         "slow_radius)",
        }

    def per_exit(self) -> dict | None:
        """Figures per exit label (None if no exits drift was in effect)."""
        if not self.labels:
            return None
        out_all = bool(np.all(np.isfinite(self.arrival[self.exit_followers])))
        out = {}
        for k, label in enumerate(self.labels):
            times = self.arrival[self.exit == k]
            last = stats(times, np.max)
            out[label] = {
                "agents": self.start.get(label),
                "arrived": len(times),
                "t_first_s": stats(times, np.min),
                "t_50_s": time_for(times, len(times), 0.5) if len(times) else None,
                "t_90_s": time_for(times, len(times), 0.9) if len(times) else None,
                "t_last_s": last,
                "evacuation_s": last if out_all else None,
            }
        return out

    def per_group(self) -> dict | None:
        """Figures per group name (None without groups)."""
        if not self.groups:
            return None
        out = {}
        for name, idx in self.groups.items():
            times = self.arrival[idx]
            out[name] = {
                "agents": len(idx),
                "arrived": int(np.count_nonzero(np.isfinite(times))),
                "t_first_s": stats(times, np.min),
                "t_50_s": time_for(times, len(idx), 0.5),
                "t_90_s": time_for(times, len(idx), 0.9),
                "t_last_s": stats(times, np.max),
                "evacuation_s": time_for(times, len(idx), 1.0),
            }
        return out
