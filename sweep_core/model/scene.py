"""Scenes: the one schema shared by YAML files, dicts, the CLI and the node.

A scene is validated completely when it is built; nothing steps an invalid scene. Units:
metres and seconds. The keys are a public contract, documented in docs/schema.md:

    name, description                      free text (at most 200 and 10 000 characters)
    horizon                                optional end time (s) the scene is meant for
    agents.positions   [[x, y], ...]       centres at t = 0
    agents.spawn       {region, count, radius, seed} instead of positions and radius (spawn.py)
    agents.radius      scalar or list      base radii (> 0)
    agents.radius_law  {kind: constant | linear (rate) | sine (amplitude, period)}
    agents.speed       preferred speed (m/s) used when a goal command arrives (default 1.3)
    agents.groups      [{name, agents: [i, ...] | {range: [a, b]}, drift, speed}]: groups with
                       their own drift and preferred speed (groups.py); the
                       others follow ``drift``
    walls              (layout.py) [{kind: halfplane, normal, offset, velocity?} | {kind: segment, a, b}
                        | {kind: polyline, points: [[x, y], ...], closed?}]
    obstacles          [{kind: circle, center, radius} | {kind: polygon, points: [[x, y], ...]}]
    map                {yaml: PATH} a map_server map whose blocked cells become walls (maps.py)
    drift              see fields.FIELD_KINDS (geodesic, exits: geodesic.py; groups: fields.Groups)
    noise              {sigma: scalar or per-agent list}
    flows              speeds, delays, sinks, sources, journeys, headway (flows.py)

The walls and obstacles are validated by :mod:`sweep_core.model.layout`; the other blocks by
the modules named above.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, replace
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from sweep_core import checks
from sweep_core.errors import CostError, SceneError, show
from sweep_core.model.budget import check_item_counts, check_navigation_cost
from sweep_core.model.drift import field_from_spec, scene_drift
from sweep_core.model.fields import DEFAULT_SPEED, Field
from sweep_core.model.flows import Flows, flows_from_spec
from sweep_core.model.gallery import resolve_scene_path
from sweep_core.model.gaps import gaps
from sweep_core.model.geometry import Geometry
from sweep_core.model.json_text import JSONLimitError, dump_json, load_json, looks_like_json
from sweep_core.model.layout import geometry_from_spec
from sweep_core.model.maps import map_from_spec, read_bounded
from sweep_core.model.outlines import pair_budget
from sweep_core.model.radii import RadiusLaw, radius_law_from_spec
from sweep_core.model.robots import CrowdReaction, Robot, reaction_from_spec, robots_from_spec
from sweep_core.model.spawn import spawn
from sweep_core.model.travel import node_budget
from sweep_core.model.user import check_constraint, constraint_name
from sweep_core.model.yaml_files import (
    MAX_RECORDED_YAML_NODES,
    YAMLError,
    dump_yaml,
    load_yaml,
    yaml_fix,
    yaml_problem,
)

#: overlap (m) tolerated in a given initial configuration (rounding of touching disks)
INITIAL_TOLERANCE = 1e-9

#: largest scene file read (bytes); a scene of 1e5 agents is about 5 MB
MAX_SCENE_BYTES = 256 << 20
#: longest scene name and description (characters)
MAX_NAME, MAX_DESCRIPTION = 200, 10_000

_TOP_KEYS = {"name", "description", "horizon", "agents", "walls", "obstacles", "map", "drift",
             "noise", "constraints", "flows", "robots", "crowd_reaction"}


@dataclass(frozen=True, eq=False)
class Scene:
    """A validated scene.

    positions: (N, 2) centres at t = 0 (m); radius: (N,) base radii (m);
    radius_law: r_i(t) = radius_i + radius_law.offset(t); geometry: walls and obstacles;
    drift: the wished velocity field U; sigma: (N,) noise intensities (m / sqrt(s));
    speed: preferred speed for goal commands (m/s); horizon: intended end time (s) or None;
    spec: the normalised dict this scene was built from (round-trips through YAML).
    """

    name: str
    positions: np.ndarray
    radius: np.ndarray
    radius_law: RadiusLaw
    geometry: Geometry
    drift: Field
    sigma: np.ndarray
    speed: float
    horizon: float | None
    spec: dict
    flows: Flows | None = None
    #: the robots (:mod:`sweep_core.model.robots`) and the crowd's reaction to them
    robots: tuple[Robot, ...] = ()
    reaction: CrowdReaction = CrowdReaction()

    @property
    def n_agents(self) -> int:
        return len(self.positions)

    def radii(self, t: float) -> np.ndarray:
        """Radii r_i(t), shape (N,), m."""
        law = self.radius_law
        return self.radius if law.is_constant else self.radius + law.offset(t)

    def check_horizon(self, t_end: float) -> None:
        """Refuse a run to t_end (s) during which some radius would reach 0 m.

        A sine law is refused whatever t_end when its amplitude is at least the smallest base
        radius (its trough comes within one period); a linear shrink when the smallest radius
        reaches 0 before t_end.
        """
        if self.n_agents == 0:
            return
        law = self.radius_law
        i = int(np.argmin(self.radius))
        r = float(self.radius[i])
        if r + law.min_offset(t_end) > 0:
            return
        when = law.zero_time(r)
        if law.kind == "sine":
            amplitude = float(getattr(law, "amplitude", 0.0))
            raise SceneError(
                "agents.radius_law.amplitude",
                f"{amplitude:g} m is not below the smallest base radius {r:g} m (agent {i}): "
                f"that radius would become <= 0 at t = {when:g} s",
                f"set agents.radius_law.amplitude to less than {r:g} m in absolute value, "
                "or make the radii larger")
        rate = float(getattr(law, "rate", 0.0))
        raise SceneError(
            "agents.radius_law.rate",
            f"{rate:g} m/s shrinks agent {i}'s radius {r:g} m to 0 at t = {when:g} s, "
            f"within the horizon {t_end:g} s",
            f"end the run before t = {when:g} s, set agents.radius_law.rate to more than "
            f"{-r / t_end:g} m/s, or make the radii larger")

    def with_constraints(self, *constraints: Any) -> Scene:
        """This scene with user constraints g(t, q_i) >= r_i(t) added (objects with
        ``value(t, q)`` and ``gradient(t, q)``: :mod:`sweep_core.model.user` states what they
        must satisfy). The initial configuration is checked against them. The spec records
        their names under ``constraints``; such a spec cannot be rebuilt from a file."""
        for k, c in enumerate(constraints):
            check_constraint(c, k)
        user = tuple(self.geometry.user) + tuple(constraints)
        spec = {**copy.deepcopy(self.spec),
                "constraints": [constraint_name(c, k) for k, c in enumerate(user)]}
        scene = replace(self, geometry=replace(self.geometry, user=user), spec=spec)
        _check_initial(scene)
        return scene

    def drift_from_spec(self, spec: dict | None, field: str = "drift") -> Field:
        """A drift spec (a command's, a recording's) built as the scene's own drift is (its
        walls, map, initial positions, agents.speed): a navigation field gets the same floats."""
        grid = map_from_spec(self.spec["map"], "map", None) if self.spec.get("map") else None
        return field_from_spec(spec, self.n_agents, field, geometry=self.geometry, grid=grid,
                               positions=self.positions, speed=self.speed)

    def to_yaml(self) -> str:
        """The normalised scene as YAML text (libyaml's dumper when present)."""
        return dump_yaml(self.spec)

    def to_json(self) -> str:
        """The normalised scene as JSON text, the form a recording carries (read back by
        :meth:`from_yaml_text` and by scene files, an order of magnitude faster than YAML)."""
        return dump_json(self.spec)

    @classmethod
    def from_yaml(cls, path: str | Path) -> Scene:
        """Load and validate a scene file."""
        path = Path(path)
        try:
            text = read_bounded(path, MAX_SCENE_BYTES, "scene",
                                "give the path of a scene YAML file").decode()
        except UnicodeDecodeError as err:
            raise SceneError("scene", f"{str(path)!r} is not UTF-8 text (byte {err.start})",
                             "give the path of a scene YAML file") from err
        return cls.from_yaml_text(text, name=path.stem, source=str(path), base=path.parent)

    @classmethod
    def from_yaml_text(cls, text: str, name: str = "scene", source: str = "the scene",
                       base: Path | None = None, files: bool = True) -> Scene:
        """Parse (libyaml's loader when present) and validate a scene given as YAML text;
        ``source`` names it in errors (a file path, "the recorded scene"); base: the directory
        a relative map path is read from; ``files=False`` (a scene a recording carries) refuses
        a map given as a file path instead of reading it."""
        return cls.from_dict(scene_data(text, source), name=name, base=base, files=files)

    @classmethod
    def from_dict(cls, data: dict, name: str = "scene", base: Path | None = None,
                  files: bool = True) -> Scene:
        """Validate a scene dict (see the module docstring) and build the scene; base: the
        directory relative file names in it (a map) are read from (default: the working
        directory); ``files=False``: no file is read (a map must be in its packed form)."""
        with node_budget(), pair_budget():
            return _build(data, name, base, files)


def scene_data(text: str, source: str = "the scene", recorded: bool = False,
               max_nodes: int | None = None, limit_name: str = "", fix: str = "") -> Any:
    """Parse a scene given as JSON or YAML text into plain data (an empty document gives {}),
    before validation; ``source`` names it in errors. A text whose first character is ``{``
    is read as JSON when it is JSON (:mod:`sweep_core.model.json_text`), else as YAML.
    ``recorded``: the text is a recording's, whose YAML is read up to
    MAX_RECORDED_YAML_NODES nodes (its JSON, as sweep records it, up to MAX_NODES);
    ``max_nodes`` lowers both bounds, ``limit_name`` and ``fix`` say why and what to do.

    Raises:
        CostError: the text holds more nodes than its bound (checked before they are built).
        SceneError: the text is not valid JSON or YAML, or exceeds another parsing limit.
    """
    if looks_like_json(text):
        try:
            data = load_json(text, max_nodes, limit_name, fix)
        except JSONLimitError as err:
            kind = CostError if err.cost else SceneError
            raise kind("scene", f"{source} (JSON) {err.problem}", err.fix) from err
        except ValueError:
            pass  # not JSON: a YAML flow mapping, or an error YAML's loader will place
        else:
            return data
    limit = {"max_nodes": max_nodes, "limit_name": limit_name, "fix": fix}
    if recorded and (max_nodes is None or max_nodes > MAX_RECORDED_YAML_NODES):
        limit = {"max_nodes": MAX_RECORDED_YAML_NODES,
                 "limit_name": "the limit MAX_RECORDED_YAML_NODES",
                 "fix": "write the recording's sweep_ros.scene metadata as JSON, as sweep "
                        "records it (read up to MAX_NODES)"}
    try:
        data = load_yaml(text, **limit)
    except YAMLError as err:
        kind = CostError if getattr(err, "cost", False) else SceneError
        raise kind("scene", f"{source} is not valid YAML: {yaml_problem(err)}",
                   yaml_fix(err)) from err
    return data if data is not None else {}


def _compact(values: np.ndarray, given: Any) -> float | list:
    """A per-agent array back in the form it was given: a scalar or a list."""
    return values.tolist() if np.ndim(given) else float(given)


def _build(data: Any, default_name: str, base: Path | None = None, files: bool = True) -> Scene:
    checks.mapping(data, "scene", allowed=_TOP_KEYS, required={"agents"})
    check_item_counts(data)
    spec: dict = {"name": checks.text(data.get("name", default_name), "name", MAX_NAME)}
    if "description" in data:
        spec["description"] = checks.text(data["description"], "description", MAX_DESCRIPTION)
    horizon = None
    if data.get("horizon") is not None:
        horizon = checks.number(data["horizon"], "horizon", positive=True)
        spec["horizon"] = horizon

    if data.get("constraints"):
        raise SceneError("constraints", f"names Python constraints {show(data['constraints'])} "
                         "that a scene file or a recording cannot rebuild",
                         "build the scene in Python and add them with Scene.with_constraints")
    grid = map_from_spec(data["map"], "map", base, files) if data.get("map") is not None else None
    geometry, walls_spec, obstacles_spec = geometry_from_spec(data, grid)
    spec["walls"], spec["obstacles"] = walls_spec, obstacles_spec
    agents = checks.mapping(data["agents"], "agents",
                            allowed={"positions", "radius", "radius_law", "speed", "spawn",
                                     "groups"})
    if "spawn" in agents:
        if "positions" in agents or "radius" in agents:
            raise SceneError("agents.spawn", "is given with agents.positions or agents.radius",
                             "give either spawn or positions and radius")
        if not files:
            raise CostError("agents.spawn", "is in a recorded scene, which carries its agents' "
                             "positions (the draw is never made again from a recording)",
                             "use a recording made by sweep run or sweep_node")
        positions, radius = spawn(agents["spawn"], "agents.spawn", geometry, grid)
        agents = {**agents, "positions": positions.tolist(), "radius": radius.tolist()}
    checks.mapping(agents, "agents", required={"positions", "radius"})
    raw_pos = agents["positions"]
    positions = (np.empty((0, 2)) if isinstance(raw_pos, list) and not raw_pos
                 else checks.array(raw_pos, "agents.positions", (None, 2), "as [[x, y], ...]",
                                          "write agents.positions as [[x, y], ...], one pair "
                                          "of coordinates (m) per agent"))
    checks.within_bound(positions, "agents.positions", bound=checks.POSITION_BOUND)
    n = len(positions)
    radius = checks.within_bound(checks.per_agent(agents["radius"], n, "agents.radius",
                                                  positive=True), "agents.radius", "radius")
    law = radius_law_from_spec(agents.get("radius_law"))
    speed = checks.speed(agents.get("speed", DEFAULT_SPEED), "agents.speed")
    spec["agents"] = {"positions": positions.tolist(), "radius": _compact(radius, agents["radius"]),
                      "radius_law": law.to_spec(), "speed": speed}

    if grid is not None:
        spec["map"] = grid.to_spec()
        blocked = np.flatnonzero(grid.is_blocked(positions))
        if len(blocked):
            a = int(blocked[0])
            more = f" ({len(blocked)} agents in all)" if len(blocked) > 1 else ""
            raise SceneError("agents.positions", f"agent {a} at [{positions[a, 0]:g}, "
                             f"{positions[a, 1]:g}] is in a blocked (occupied or unknown) cell "
                             f"of the map{more}", "place agents in the map's free cells")

    check_navigation_cost(data, geometry, grid, positions)
    drift, spec["drift"], groups = scene_drift(data.get("drift"), agents.get("groups"), n,
                                               geometry, grid, positions, speed)
    if groups is not None:
        spec["agents"]["groups"] = groups

    noise = checks.mapping(data.get("noise") or {}, "noise", allowed={"sigma"})
    sigma = checks.per_agent(noise.get("sigma", 0.0), n, "noise.sigma", nonnegative=True)
    spec["noise"] = {"sigma": _compact(sigma, noise.get("sigma", 0.0))}

    flows = flows_from_spec(data.get("flows"), n, drift, speed, sigma, geometry, grid,
                            positions, recorded=not files)
    if flows is not None:
        spec["flows"] = flows.spec
    scene = Scene(name=spec["name"], positions=positions, radius=radius, radius_law=law,
                  geometry=geometry, drift=drift, sigma=sigma, speed=speed, horizon=horizon,
                  spec=spec, flows=flows)
    # a sine law's trough counts from t = 0; a linear shrink is checked against each horizon
    scene.check_horizon(horizon if horizon is not None else 0.0)
    _check_initial(scene)
    if data.get("robots") or data.get("crowd_reaction"):  # robots: model/robots.py
        robots, spec["robots"] = robots_from_spec(data.get("robots"), geometry, positions,
                                                  scene.radii(0.0),
                                                  None if grid is None else grid.is_blocked)
        reaction, spec["crowd_reaction"] = reaction_from_spec(data.get("crowd_reaction"))
        if robots and flows is not None and flows.sources:
            raise SceneError("flows.sources", "a scene with robots cannot have sources "
                             "(an entering person is placed without regard to the robots)",
                             "remove the sources or the robots")
        scene = replace(scene, robots=robots, reaction=reaction)
    return scene


def _check_initial(scene: Scene) -> None:
    """Refuse an initial configuration outside Q(0)."""
    q, r = scene.positions, scene.radii(0.0)
    if len(q) < 1:
        return
    g = gaps(scene.geometry, 0.0, q, r)
    if g.worst_pair is not None and g.min_pair < -INITIAL_TOLERANCE:
        d = np.hypot(*(q[g.pair_i] - q[g.pair_j]).T)
        if np.any(d < 1e-12):
            k = int(np.argmin(d))
            a, b = int(g.pair_i[k]), int(g.pair_j[k])
            raise SceneError("agents.positions",
                             f"agents {a} and {b} have coincident centres {show(q[a])}",
                             f"move agent {b} at least r_{a} + r_{b} = {r[a] + r[b]:g} m away "
                             f"from agent {a}")
        i, j, gap = g.worst_pair
        bad = int(np.count_nonzero(g.pair_gap < -INITIAL_TOLERANCE))
        more = f"; {bad} overlapping pairs in all" if bad > 1 else ""
        raise SceneError("agents.positions",
                         f"agents {i} and {j} overlap by {-gap:.3f} m (centres {show(q[i])} and "
                         f"{show(q[j])}, radii {r[i]:g} m and {r[j]:g} m{more})",
                         f"place agents {i} and {j} at least r_{i} + r_{j} = {r[i] + r[j]:g} m "
                         "apart, centre to centre")
    if g.worst_single is not None and g.min_single < -INITIAL_TOLERANCE:
        a, kind, item, gap = g.worst_single
        path = scene.geometry.path(kind, item)
        raise SceneError(path, f"agent {a} at {show(q[a])} (radius {r[a]:g} m) violates "
                         f"{scene.geometry.describe(kind, item)} by {-gap:.3f} m at t = 0",
                         f"move agent {a} to the free side of {path}, at least its radius "
                         f"{r[a]:g} m away from it")


def copy_spec(scene: Scene) -> dict:
    """A deep copy of the scene's normalised dict, safe to modify."""
    return copy.deepcopy(scene.spec)


DEFAULT_SCENE = "room_door.yaml"


def default_scene_path() -> Path:
    """Path of the bundled default scene (a room with a door, 200 agents)."""
    return Path(str(resources.files("sweep_core") / "scenes" / DEFAULT_SCENE))


def load_scene(path: str | None) -> Scene:
    """A scene file, a bundled scene's name when no such file exists (``sweep scenes`` lists
    them), or the bundled default when path is None or empty."""
    return Scene.from_yaml(resolve_scene_path(path) if path else default_scene_path())
