"""Scenes: the one schema shared by YAML files, dicts, the CLI and the node.

A scene is validated completely when it is built; nothing steps an invalid scene. Units:
metres and seconds. The keys are a public contract, documented in the README:

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
    walls              [{kind: halfplane, normal, offset, velocity?} | {kind: segment, a, b}
                        | {kind: polyline, points: [[x, y], ...], closed?}]
    obstacles          [{kind: circle, center, radius} | {kind: polygon, points: [[x, y], ...]}]
    map                {yaml: PATH} a map_server map whose blocked cells become walls (maps.py)
    drift              see fields.FIELD_KINDS (geodesic, exits: geodesic.py; groups: fields.Groups)
    noise              {sigma: scalar or per-agent list}

Longer than 420 lines because it is the one validation of the whole schema (agents, walls,
obstacles, map, drift, noise, the initial configuration), each key checked beside the
normalised form it takes in ``spec``.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, replace
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from sweep_core import checks
from sweep_core.errors import SceneError, show
from sweep_core.model.fields import DEFAULT_SPEED, Field, field_from_spec
from sweep_core.model.geometry import Geometry, gaps
from sweep_core.model.groups import scene_drift
from sweep_core.model.maps import OccupancyMap, map_from_spec, read_bounded
from sweep_core.model.outlines import chain_points
from sweep_core.model.radii import RadiusLaw, radius_law_from_spec
from sweep_core.model.robots import CrowdReaction, Robot, reaction_from_spec, robots_from_spec
from sweep_core.model.spawn import spawn
from sweep_core.model.user import check_constraint, constraint_name
from sweep_core.model.yaml_files import YAMLError, dump_yaml, load_yaml, yaml_fix, yaml_problem

#: overlap (m) tolerated in a given initial configuration (rounding of touching disks)
INITIAL_TOLERANCE = 1e-9

#: largest scene file read (bytes); a scene of 1e5 agents is about 5 MB
MAX_SCENE_BYTES = 256 << 20
#: longest scene name and description (characters)
MAX_NAME, MAX_DESCRIPTION = 200, 10_000

_TOP_KEYS = {"name", "description", "horizon", "agents", "walls", "obstacles", "map", "drift",
             "noise", "constraints", "robots", "crowd_reaction"}


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
        try:
            data = load_yaml(text)
        except YAMLError as err:
            raise SceneError("scene", f"{source} is not valid YAML: {yaml_problem(err)}",
                             yaml_fix(err)) from err
        return cls.from_dict(data if data is not None else {}, name=name, base=base, files=files)

    @classmethod
    def from_dict(cls, data: dict, name: str = "scene", base: Path | None = None,
                  files: bool = True) -> Scene:
        """Validate a scene dict (see the module docstring) and build the scene; base: the
        directory relative file names in it (a map) are read from (default: the working
        directory); ``files=False``: no file is read (a map must be in its packed form)."""
        return _build(data, name, base, files)


def _list(value: Any, field: str) -> list:
    if value is None:
        return []
    if not isinstance(value, list):
        raise SceneError(field, f"must be a list, got {type(value).__name__} {show(value)}",
                         f"write {field} as a list of mappings, one '- kind: ...' per item")
    return value


def _compact(values: np.ndarray, given: Any) -> float | list:
    """A per-agent array back in the form it was given: a scalar or a list."""
    return values.tolist() if np.ndim(given) else float(given)


def _build(data: Any, default_name: str, base: Path | None = None, files: bool = True) -> Scene:
    checks.mapping(data, "scene", allowed=_TOP_KEYS, required={"agents"})
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
    geometry, walls_spec, obstacles_spec = _geometry(data, grid)
    spec["walls"], spec["obstacles"] = walls_spec, obstacles_spec
    agents = checks.mapping(data["agents"], "agents",
                            allowed={"positions", "radius", "radius_law", "speed", "spawn",
                                     "groups"})
    if "spawn" in agents:
        if "positions" in agents or "radius" in agents:
            raise SceneError("agents.spawn", "is given with agents.positions or agents.radius",
                             "give either spawn or positions and radius")
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
    speed = checks.number(agents.get("speed", DEFAULT_SPEED), "agents.speed", nonnegative=True)
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

    drift, spec["drift"], groups = scene_drift(data.get("drift"), agents.get("groups"), n,
                                               geometry, grid, positions, speed)
    if groups is not None:
        spec["agents"]["groups"] = groups

    noise = checks.mapping(data.get("noise") or {}, "noise", allowed={"sigma"})
    sigma = checks.per_agent(noise.get("sigma", 0.0), n, "noise.sigma", nonnegative=True)
    spec["noise"] = {"sigma": _compact(sigma, noise.get("sigma", 0.0))}

    scene = Scene(name=spec["name"], positions=positions, radius=radius, radius_law=law,
                  geometry=geometry, drift=drift, sigma=sigma, speed=speed, horizon=horizon,
                  spec=spec)
    # a sine law's trough counts from t = 0; a linear shrink is checked against each horizon
    scene.check_horizon(horizon if horizon is not None else 0.0)
    _check_initial(scene)
    if data.get("robots") or data.get("crowd_reaction"):  # robots: model/robots.py
        robots, spec["robots"] = robots_from_spec(data.get("robots"), geometry, positions,
                                                  scene.radii(0.0),
                                                  None if grid is None else grid.is_blocked)
        reaction, spec["crowd_reaction"] = reaction_from_spec(data.get("crowd_reaction"))
        scene = replace(scene, robots=robots, reaction=reaction)
    return scene


def _geometry(data: dict, grid: OccupancyMap | None = None) -> tuple[Geometry, list, list]:
    hp_n, hp_c, hp_v, hp_i, sa, sb, s_i, cc, cr, c_i = ([] for _ in range(10))
    s_poly: list[int] = []
    s_part: list[int] = []
    s_kind: list[str] = []
    s_m: list[int] = []
    walls_spec, obstacles_spec = [], []

    def add_chain(points: np.ndarray, closed: bool, index: int, kind: str, polygon: int) -> None:
        ends = np.roll(points, -1, axis=0) if closed else points[1:]
        for part, (a, b) in enumerate(zip(points[: len(ends)], ends)):
            sa.append(a)
            sb.append(b)
            s_i.append(index)
            s_poly.append(polygon)
            s_part.append(part)
            s_kind.append(kind)
            s_m.append(-1)

    for k, wall in enumerate(_list(data.get("walls"), "walls")):
        field = f"walls[{k}]"
        checks.mapping(wall, field)
        kind = checks.kind(wall, field, ("halfplane", "segment", "polyline"))
        if kind == "polyline":
            checks.mapping(wall, field, allowed={"kind", "points", "closed"}, required={"points"})
            closed = wall.get("closed", False)
            if not isinstance(closed, bool):
                raise SceneError(f"{field}.closed", f"must be true or false, got {closed!r}",
                                 "write closed: true for a room outline, false for an open chain")
            points = chain_points(wall["points"], f"{field}.points", closed,
                                  3 if closed else 2)
            add_chain(points, closed, k, "polyline", -1)
            walls_spec.append({"kind": kind, "points": points.tolist(), "closed": closed})
            continue
        if kind == "halfplane":
            checks.mapping(wall, field, allowed={"kind", "normal", "offset", "velocity"},
                           required={"normal", "offset"})
            normal = checks.vec2(wall["normal"], f"{field}.normal")
            norm = float(np.hypot(*normal))
            if norm < 1e-12:
                raise SceneError(f"{field}.normal", f"is the zero vector {show(normal)}",
                                 "give the direction pointing into the free side, e.g. [1, 0]")
            offset = checks.length(wall["offset"], f"{field}.offset", what="offset")
            velocity = checks.number(wall.get("velocity", 0.0), f"{field}.velocity")
            hp_n.append(normal / norm)
            hp_c.append(offset)
            hp_v.append(velocity)
            hp_i.append(k)
            walls_spec.append({"kind": kind, "normal": (normal / norm).tolist(), "offset": offset,
                               "velocity": velocity})
        else:
            checks.mapping(wall, field, allowed={"kind", "a", "b"}, required={"a", "b"})
            a, b = checks.point(wall["a"], f"{field}.a"), checks.point(wall["b"], f"{field}.b")
            if np.hypot(*(b - a)) < 1e-12:
                raise SceneError(field, f"has a == b = {show(a)} (a segment of zero length)",
                                 "for a round obstacle use obstacles: [{kind: circle, ...}]")
            add_chain(np.array([a, b]), False, k, "segment", -1)
            walls_spec.append({"kind": kind, "a": a.tolist(), "b": b.tolist()})
    mv_v: list[np.ndarray] = []
    mv_w: list[float] = []
    mv_p: list[np.ndarray] = []
    c_m: list[int] = []

    def motion(obs: dict, field: str, centre: np.ndarray) -> tuple[int, dict]:
        """The obstacle's rigid motion row (-1: static) and its normalised keys."""
        if not any(key in obs for key in ("velocity", "angular_velocity", "pivot")):
            return -1, {}
        v = checks.vec2(obs.get("velocity", [0.0, 0.0]), f"{field}.velocity")
        w = checks.number(obs.get("angular_velocity", 0.0), f"{field}.angular_velocity")
        pivot = checks.point(obs["pivot"], f"{field}.pivot") if "pivot" in obs else centre
        mv_v.append(v)
        mv_w.append(w)
        mv_p.append(pivot)
        return len(mv_w) - 1, {"velocity": v.tolist(), "angular_velocity": w,
                               "pivot": pivot.tolist()}

    moving = {"velocity", "angular_velocity", "pivot"}
    for k, obs in enumerate(_list(data.get("obstacles"), "obstacles")):
        field = f"obstacles[{k}]"
        checks.mapping(obs, field)
        if checks.kind(obs, field, ("circle", "polygon")) == "polygon":
            checks.mapping(obs, field, allowed={"kind", "points"} | moving, required={"points"})
            points = chain_points(obs["points"], f"{field}.points", True, 3)
            first = len(sa)
            add_chain(points, True, k, "polygon", k)
            row, keys = motion(obs, field, points.mean(axis=0))
            s_m[first:] = [row] * (len(sa) - first)
            obstacles_spec.append({"kind": "polygon", "points": points.tolist(), **keys})
            continue
        checks.mapping(obs, field, allowed={"kind", "center", "radius"} | moving,
                       required={"center", "radius"})
        center = checks.point(obs["center"], f"{field}.center")
        radius = checks.length(obs["radius"], f"{field}.radius", nonnegative=True)
        cc.append(center)
        cr.append(radius)
        c_i.append(k)
        row, keys = motion(obs, field, center)
        c_m.append(row)
        obstacles_spec.append({"kind": "circle", "center": center.tolist(), "radius": radius,
                               **keys})

    if grid is not None:
        for part, (a, b) in enumerate(zip(*grid.segments())):
            sa.append(a)
            sb.append(b)
            s_i.append(-1)
            s_poly.append(-1)
            s_part.append(part)
            s_kind.append("map")
            s_m.append(-1)

    def arr(x: list, shape: tuple) -> np.ndarray:
        return np.array(x, dtype=np.float64).reshape(shape)

    geom = Geometry(arr(hp_n, (-1, 2)), arr(hp_c, (-1,)), arr(hp_v, (-1,)), arr(sa, (-1, 2)),
                    arr(sb, (-1, 2)), arr(cc, (-1, 2)), arr(cr, (-1,)),
                    np.array(hp_i, dtype=np.intp), np.array(s_i, dtype=np.intp),
                    np.array(c_i, dtype=np.intp), np.array(s_poly, dtype=np.intp),
                    np.array(s_part, dtype=np.intp), tuple(s_kind),
                    arr(mv_v, (-1, 2)), arr(mv_w, (-1,)), arr(mv_p, (-1, 2)),
                    np.array(s_m, dtype=np.intp),
                    np.array(c_m, dtype=np.intp))
    return geom, walls_spec, obstacles_spec


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
    """A scene file, or the bundled default when path is None or empty."""
    return Scene.from_yaml(path or default_scene_path())
