"""Flows: the scene's optional ``flows`` key (per-agent speeds, start delays, sinks, sources,
journeys, the headway speed law), validated into a :class:`Flows`. docs/flows.md is the
user's page; the run-time state (who is present, who left) is
:mod:`sweep_core.numerics.population`.

    flows:
      speeds:   v | [v_0, ...] | {distribution: normal, mean, std, min, max}
                               | {distribution: uniform, min, max}        m/s, > 0
      delays:   same forms, s >= 0 (pre-movement times)
      sinks:    [region, ...]               an agent whose centre is inside one leaves
      sources:  [{region, rate | times, start, count, radius, group, speeds, delays}, ...]
      journeys: [{group, legs: [{goal: [x, y]} | {region: {...}}, ...], arrive_radius,
                  cell, wall_buffer}, ...]
      exit_choice: [{group, exits: [{region} | {goal}, ...], capacity}, ...]   (exit_choice.py)
      headway:  {law: csm, time_gap: T, repulsion: a, repulsion_range: D, lateral: k,
                 fade: k2, length: f, follow: beta, wall_repulsion: a_w, wall_range: D_w}
                                                                    s, -, m, -  (speed_law.py)
              | {law: lanes, time_gap: T, margin: w}                      s, m

Regions: :mod:`sweep_core.model.regions`. Values drawn from a distribution are drawn per run
from the run's seed (:func:`draw`), never stored in the spec.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from sweep_core import checks
from sweep_core.errors import CostError, SceneError, show
from sweep_core.model.exit_choice import ExitChoice, exit_choice_from_spec
from sweep_core.model.fields import Field, Groups
from sweep_core.model.flow_checks import check_source_ways, check_sources
from sweep_core.model.journeys import Journey, journey_from_spec, members
from sweep_core.model.regions import Region, region_from_spec
from sweep_core.model.speed_law import (
    DEFAULT_LAW,
    DEFAULT_REPULSION_RANGE,
    DEFAULT_WALL_RANGE,
    headway_from_spec,
)

#: most agents one source may emit
MAX_SOURCE_COUNT = 100_000
#: memory of the sources' schedules, bytes per agent a source will emit (its entry time, a
#: float64): with MAX_SOURCES sources of MAX_SOURCE_COUNT, 51 MB. Measured increase of the
#: peak resident memory building and stepping a scene of 64 sources of 1e4 / 1e5 agents: 5
#: / 52 MB over one of 64 sources of one agent (test/test_estimates.py checks it)
SCHEDULE_BYTES_PER_AGENT = 8
#: most sinks: every step tests each sink in Python, about 15 us a sink (measured: 256 sinks
#: 4 ms a step, 1e5 sinks 1.4 s a step)
MAX_SINKS = 256
#: most sources: a source whose due agents wait tries to place one every step, about 0.3 ms
#: a source (measured: 256 such sources 76 ms a step, 1e4 sources more than 1.5 s a step);
#: 64 keep that near 20 ms. With MAX_SOURCE_COUNT each, the entering agents' ids stay below
#: 2^24, exact in the float32 ``id`` field of /agents
MAX_SOURCES = 64
#: the largest preferred speed (m/s): :data:`sweep_core.checks.MAX_SPEED`, every speed's bound
MAX_SPEED = checks.MAX_SPEED
_DISTRIBUTIONS: dict[str, set[str]] = {"normal": {"mean", "std", "min", "max"},
                                        "uniform": {"min", "max"}}


@dataclass(frozen=True)
class Draw:
    """Per-agent values: given (``values``, one per agent or one for all) or drawn from a
    normal distribution clipped to [low, high] or a uniform one on [low, high]."""

    values: np.ndarray | None
    distribution: str | None = None
    mean: float = 0.0
    std: float = 0.0
    low: float = 0.0
    high: float = 0.0

    def to_spec(self) -> Any:
        if self.values is not None:
            return self.values.tolist() if self.values.ndim else float(self.values)
        out: dict = {"distribution": self.distribution, "min": self.low, "max": self.high}
        if self.distribution == "normal":
            out.update(mean=self.mean, std=self.std)
        return out


def draw(d: Draw, rng: np.random.Generator, n: int) -> np.ndarray:
    """n values (n,) of d: the given ones (a scalar broadcast), or n draws from rng."""
    if d.values is not None:
        return (np.full(n, float(d.values)) if d.values.ndim == 0
                else np.asarray(d.values, dtype=np.float64)[:n].copy())
    if d.distribution == "uniform":
        return d.low + rng.random(n) * (d.high - d.low)
    return np.clip(d.mean + d.std * rng.standard_normal(n), d.low, d.high)


def draw_from_spec(value: Any, field: str, n: int | None, *, positive: bool,
                   bounded: bool = True) -> Draw:
    """A speeds or delays value: a number, a list of n numbers (n None: a list is refused),
    or a distribution; positive: values > 0 and, when ``bounded``, at most MAX_SPEED
    (speeds), else >= 0 (delays)."""
    d = _draw_from_spec(value, field, n, positive=positive)
    top = float(np.max(d.values)) if d.values is not None else d.high
    if positive and bounded and top > MAX_SPEED:
        where = (f"{field}.max" if d.values is None else
                 f"{field}[{int(np.argmax(d.values))}]" if d.values.ndim else field)
        checks.speed(top, where, positive=True,
                     fix=f"give preferred speeds of at most {MAX_SPEED:g} m/s")
    return d


def _draw_from_spec(value: Any, field: str, n: int | None, *, positive: bool) -> Draw:
    bound = "> 0" if positive else ">= 0"
    unit = "m/s" if positive else "s"
    if isinstance(value, dict):
        checks.mapping(value, field, required={"distribution"},
                       allowed={"distribution", "mean", "std", "min", "max"})
        dist = value["distribution"]
        if not isinstance(dist, str) or dist not in _DISTRIBUTIONS:
            raise SceneError(f"{field}.distribution", f"unknown distribution {show(dist)}",
                             f"use one of {sorted(_DISTRIBUTIONS)}")
        need = _DISTRIBUTIONS[dist]
        checks.mapping(value, field, required={"distribution"} | need,
                       allowed={"distribution"} | need)
        lo = checks.number(value["min"], f"{field}.min", positive=positive,
                           nonnegative=not positive)
        hi = checks.number(value["max"], f"{field}.max", positive=positive,
                           nonnegative=not positive)
        if hi < lo:
            raise SceneError(f"{field}.max", f"{hi:g} {unit} is below min {lo:g} {unit}",
                             f"set {field}.max to at least {field}.min")
        if dist == "uniform":
            return Draw(None, "uniform", low=lo, high=hi)
        mean = checks.number(value["mean"], f"{field}.mean")
        std = checks.number(value["std"], f"{field}.std", nonnegative=True)
        if not lo <= mean <= hi:
            raise SceneError(f"{field}.mean", f"{mean:g} {unit} is outside [min, max] = "
                             f"[{lo:g}, {hi:g}]", f"set {field}.mean between min and max")
        return Draw(None, "normal", mean=mean, std=std, low=lo, high=hi)
    if isinstance(value, list):
        if n is None:
            raise SceneError(field, f"is a list {show(value)} but these agents are not known "
                             "in advance", f"give {field} one number {bound} ({unit}) or a "
                             "distribution {distribution: uniform, min, max}")
        arr = checks.per_agent(value, n, field, positive=positive, nonnegative=not positive)
        return Draw(arr)
    x = checks.number(value, field, positive=positive, nonnegative=not positive,
                      fix=f"give {field} a number {bound} ({unit}), a list of one per agent, "
                          "or {distribution: normal, mean, std, min, max}")
    return Draw(np.array(x))


@dataclass(frozen=True, eq=False)
class Source:
    """Agents entering in ``region``: at ``times`` (s, sorted), ``count`` of them; radii
    uniform in [r_low, r_high] (m); ``group`` (index in the scene's groups, -1: none);
    speeds and delays (None: the group's speed, no delay)."""

    region: Region
    times: np.ndarray
    r_low: float
    r_high: float
    group: int
    speeds: Draw | None
    delays: Draw | None
    spec: dict


@dataclass(frozen=True, eq=False)
class Flows:
    """The validated ``flows`` key (module docstring); ``spec`` its normalised dict.
    ``group_speed[k]`` (k = -1: agents in no group, last entry) the speed s_k (m/s) the
    drift of group k moves at, which a per-agent speed v0 rescales (U v0 / s_k)."""

    speeds: Draw | None
    delays: Draw | None
    sinks: tuple[Region, ...]
    sources: tuple[Source, ...]
    journeys: tuple[Journey, ...]
    time_gap: float | None
    margin: float
    group_speed: np.ndarray
    spec: dict
    law: str = DEFAULT_LAW
    repulsion: float = 0.0
    repulsion_range: float = DEFAULT_REPULSION_RANGE
    exit_choices: tuple[ExitChoice, ...] = ()
    lateral: float = 1.0
    fade: float = -1.0
    length: float = 1.0
    follow: float = 0.0
    wall_repulsion: float = 0.0
    wall_range: float = DEFAULT_WALL_RANGE

    @property
    def changes_population(self) -> bool:
        return bool(self.sinks or self.sources)

    @property
    def entering(self) -> int:
        """Most agents the sources can add (the sum of their counts)."""
        return sum(len(s.times) for s in self.sources)


def _group(value: Any, field: str, names: tuple[str, ...]) -> int:
    if value is None:
        return -1
    if value not in names:
        raise SceneError(field, f"{show(value)} is not a group of the scene (its groups: "
                         f"{', '.join(names) or 'none'})",
                         "name one of agents.groups, or omit it for the agents in no group")
    return names.index(value)


def _source(value: Any, field: str, names: tuple[str, ...], recorded: bool) -> Source:
    checks.mapping(value, field, required={"region"},
                   allowed={"region", "rate", "times", "start", "count", "radius", "group",
                            "speeds", "delays"})
    region = region_from_spec(value["region"], f"{field}.region")
    spec: dict = {"region": region.spec}
    if ("rate" in value) == ("times" in value):
        raise SceneError(field, f"gives {'both' if 'rate' in value else 'neither'} rate and "
                         "times", f"give {field}.rate (agents/s) with {field}.count, or "
                         f"{field}.times: [t0, t1, ...] (s)")
    if "rate" in value:
        rate = checks.number(value["rate"], f"{field}.rate", positive=True)
        if "count" not in value:
            raise SceneError(f"{field}.count", "is missing (a rate needs a count)",
                             f"set {field}.count to the number of agents the source emits")
        count = checks.integer(value["count"], f"{field}.count", low=1)
        if count > MAX_SOURCE_COUNT:
            raise CostError(f"{field}.count", f"{count} is above {MAX_SOURCE_COUNT}",
                             f"set {field}.count to at most {MAX_SOURCE_COUNT}")
        start = checks.number(value.get("start", 0.0), f"{field}.start", nonnegative=True)
        times = start + np.arange(count) / rate
        spec.update(rate=rate, count=count, start=start)
    else:
        if "start" in value or "count" in value:
            raise SceneError(field, "gives start or count with times",
                             "give the times alone (each entry is one agent)")
        raw = value["times"]
        if not isinstance(raw, list) or not raw or len(raw) > MAX_SOURCE_COUNT:
            raise (CostError if isinstance(raw, list) and raw else SceneError)(
            f"{field}.times", f"must be a non-empty list of at most "
                             f"{MAX_SOURCE_COUNT} times, got {show(raw)}",
                             f"write {field}.times as [t0, t1, ...] (s)")
        times = np.array([checks.number(t, f"{field}.times[{k}]", nonnegative=True)
                          for k, t in enumerate(raw)])
        if np.any(np.diff(times) < 0):
            raise SceneError(f"{field}.times", f"{show(times)} is not sorted",
                             f"sort {field}.times in increasing order")
        spec["times"] = times.tolist()
    r = value.get("radius", 0.2)
    if isinstance(r, list):
        if len(r) != 2:
            raise SceneError(f"{field}.radius", f"must be R or [R_min, R_max], got {show(r)}",
                             f"set {field}.radius to a radius (m) or a range [R_min, R_max]")
        lo = checks.length(r[0], f"{field}.radius[0]", positive=True)
        hi = checks.length(r[1], f"{field}.radius[1]", positive=True)
        if hi < lo:
            raise SceneError(f"{field}.radius", f"{show(r)} is decreasing",
                             f"give {field}.radius as [R_min, R_max] with R_min <= R_max")
        spec["radius"] = [lo, hi]
    else:
        lo = hi = checks.length(r, f"{field}.radius", positive=True)
        spec["radius"] = lo
    group = _group(value.get("group"), f"{field}.group", names)
    if group >= 0:
        spec["group"] = names[group]
    speeds = (draw_from_spec(value["speeds"], f"{field}.speeds", None, positive=True,
                             bounded=not recorded)
              if value.get("speeds") is not None else None)
    delays = (draw_from_spec(value["delays"], f"{field}.delays", None, positive=False)
              if value.get("delays") is not None else None)
    for key, d in (("speeds", speeds), ("delays", delays)):
        if d is not None:
            spec[key] = d.to_spec()
    return Source(region, times, lo, hi, group, speeds, delays, spec)


def flows_from_spec(raw: Any, n_agents: int, drift: Field, speed: float, sigma: np.ndarray,
                    geometry: Any, grid: Any, positions: np.ndarray | None = None,
                    recorded: bool = False) -> Flows | None:
    """Validate the ``flows`` key (None: absent) of a scene of ``n_agents`` initial agents with
    its drift (a Groups field gives the group names and speeds), agents.speed (m/s) and noise
    intensities sigma (N,); ``positions`` (N, 2) m, when given, are checked to have a way to
    their journey's first target. ``recorded``: the scene of a recording, which ran, checked
    as it was when recorded: the bounds on speeds and the speed law's repulsion, the sources'
    room and sinks and the journeys' ways are not applied to it. The bounds on what it costs
    to rebuild (counts of sinks, sources and each source's agents) are applied to every
    scene: a recording's metadata is data, and may claim anything."""
    if raw is None:
        return None
    checks.mapping(raw, "flows", allowed={"speeds", "delays", "sinks", "sources", "journeys",
                                          "exit_choice", "headway"})
    names: tuple[str, ...] = drift.names if isinstance(drift, Groups) else ()
    if isinstance(drift, Groups):
        gspeed = np.array(list(drift.speeds) + [float(getattr(drift.rest, "speed", speed))])
    else:
        gspeed = np.array([float(getattr(drift, "speed", speed))])
    spec: dict = {}
    speeds = delays = None
    if raw.get("speeds") is not None:
        speeds = draw_from_spec(raw["speeds"], "flows.speeds", n_agents, positive=True,
                                bounded=not recorded)
        spec["speeds"] = speeds.to_spec()
    if raw.get("delays") is not None:
        delays = draw_from_spec(raw["delays"], "flows.delays", n_agents, positive=False)
        spec["delays"] = delays.to_spec()
    sinks = []
    for k, s in enumerate(_listed(raw, "sinks", MAX_SINKS)):
        sinks.append(region_from_spec(s, f"flows.sinks[{k}]"))
    spec["sinks"] = [s.spec for s in sinks]
    sources = [_source(s, f"flows.sources[{k}]", names, recorded)
               for k, s in enumerate(_listed(raw, "sources", MAX_SOURCES))]
    spec["sources"] = [s.spec for s in sources]
    if not recorded:
        check_sources(sources, sinks, geometry, grid)
    journeys: list[Journey] = []
    seen: dict[int, int] = {}
    for k, j in enumerate(_listed(raw, "journeys")):
        g = _group(j.get("group") if isinstance(j, dict) else None, f"flows.journeys[{k}].group",
                   names)
        if g in seen:
            raise SceneError(f"flows.journeys[{k}].group", f"gives {_who(j)} a second journey"
                             f" (journeys[{seen[g]}] is its first)",
                             "give each group one journey")
        seen[g] = k
        first = members(drift, g, n_agents, None if recorded else positions)
        journeys.append(journey_from_spec(j, f"flows.journeys[{k}]", g, names, float(gspeed[g]),
                                          geometry, grid, first))
    spec["journeys"] = [j.spec for j in journeys]
    choices: list[ExitChoice] = []
    for k, c in enumerate(_listed(raw, "exit_choice")):
        field = f"flows.exit_choice[{k}]"
        g = _group(c.get("group") if isinstance(c, dict) else None, f"{field}.group", names)
        if g in seen:
            raise SceneError(f"{field}.group", f"gives {_who(c)} an exit choice and a journey",
                             "give a group a journey or an exit choice")
        if any(o.group == g for o in choices):
            raise SceneError(f"{field}.group", f"gives {_who(c)} a second exit choice",
                             "give each group one exit choice")
        choices.append(exit_choice_from_spec(c, field, g, names[g] if g >= 0 else None,
                                             float(gspeed[g]), geometry, grid,
                                             members(drift, g, n_agents,
                                                     None if recorded else positions)))
    if choices:
        spec["exit_choice"] = [c.spec for c in choices]
    if not recorded and sources:
        check_source_ways(sources, _first_ways(drift, names, journeys, choices))
    law = headway_from_spec(raw.get("headway"), bounded=not recorded)
    if law is not None:
        spec["headway"] = law
    given = (law or {}).get  # the law's parameter, or its neutral value without a law
    out = Flows(speeds, delays, tuple(sinks), tuple(sources), tuple(journeys),
                None if law is None else law["time_gap"], given("margin", 0.0), gspeed, spec,
                given("law", DEFAULT_LAW), given("repulsion", 0.0),
                given("repulsion_range", DEFAULT_REPULSION_RANGE), tuple(choices),
                given("lateral", 1.0), given("fade", -1.0), given("length", 1.0),
                given("follow", 0.0), given("wall_repulsion", 0.0),
                given("wall_range", DEFAULT_WALL_RANGE))
    if out.changes_population:
        _check_changing(out, drift, sigma)
    return out


def _first_ways(drift: Field, names: tuple[str, ...], journeys: list[Journey],
                choices: list[ExitChoice]) -> dict[int, tuple[str, list]]:
    """Per group (-1: agents in no group), what its agents head for first and the navigation
    fields that lead there: its journey's first leg, its exit choice's exits, or its drift's
    geodesic field (none for a straight goal)."""
    from sweep_core.model.geodesic import navigation_fields  # built on fields

    ways: dict[int, tuple[str, list]] = {
        g: ("the drift's goal" if g < 0 else f"group {names[g]}'s goal", [f])
        for g, f in navigation_fields(drift)}
    for k, j in enumerate(journeys):
        ways[j.group] = (f"flows.journeys[{k}].legs[0]", [j.fields[0]])
    for k, c in enumerate(choices):
        ways[c.group] = (f"any of flows.exit_choice[{k}].exits", list(c.fields))
    return ways


def _listed(raw: dict, key: str, most: int | None = None) -> list:
    """flows.KEY, a list (empty when absent) of at most ``most`` items."""
    out = checks.items(raw.get(key), f"flows.{key}",
                       f"write flows.{key} as a list, one '- ...' per item")
    if most is not None and len(out) > most:
        raise CostError(f"flows.{key}", f"has {len(out)} items, more than {most}",
                         f"give at most {most} (a region may be a polygon: join neighbouring "
                         "ones)")
    return out


def _check_changing(flows: Flows, drift: Field, sigma: np.ndarray) -> None:
    """Refuse what cannot follow a changing set of agents: per-agent drifts, noise lists."""
    fields = (list(drift.fields) + [drift.rest]) if isinstance(drift, Groups) else [drift]
    for f in fields:
        if f.kind == "per_agent":
            raise SceneError("drift", "is per_agent, one velocity per agent, while "
                             "flows.sinks or flows.sources change the agents",
                             "give a drift that depends on position (goal, geodesic, ...)")
    if flows.sources and len(sigma) and not np.all(sigma == sigma[0]):
        raise SceneError("noise.sigma", "is a list, one per agent, while flows.sources adds "
                         "agents", "give noise.sigma one value for all agents")
    if not flows.sources:
        return
    if not all(math.isfinite(float(t)) for s in flows.sources for t in s.times[-1:]):
        raise SceneError("flows.sources", "has a time that is not finite",
                         "give finite times (s)")


def _who(item: Any) -> str:
    """Whom a journey or an exit choice is for: its group, or the agents in no group."""
    group = item.get("group") if isinstance(item, dict) else None
    return "the agents in no group" if group is None else f"group {show(group)}"
