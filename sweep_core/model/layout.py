"""The walls and obstacles of a scene: its ``walls`` and ``obstacles`` lists (and the boundary
walls of its map's blocked cells) validated and built into a :class:`Geometry`, with their
normalised specs. Units: metres, seconds (a moving obstacle's velocity in m/s)."""
from __future__ import annotations

from typing import Any

import numpy as np

from sweep_core import checks
from sweep_core.errors import SceneError, show
from sweep_core.model.geometry import Geometry
from sweep_core.model.maps import OccupancyMap
from sweep_core.model.outlines import chain_points

__all__ = ["geometry_from_spec"]

_LIST_FIX = "write {} as a list of mappings, one '- kind: ...' per item"


def geometry_from_spec(data: dict, grid: OccupancyMap | None = None
                       ) -> tuple[Geometry, list, list]:
    """The scene dict's ``walls`` and ``obstacles`` (and the boundary walls of ``grid``'s
    blocked cells) validated and built: the :class:`Geometry`, and the normalised walls and
    obstacles specs. Raises SceneError naming the field, the value and the fix."""
    hp_n, hp_c, hp_v, hp_i, cc, cr, c_i = ([] for _ in range(7))
    # the segments, one entry per chain: (starts (k, 2), ends (k, 2), item index, polygon
    # index, kind, motion row), laid out in order at the end
    chains: list[tuple[np.ndarray, np.ndarray, int, int, str, int]] = []
    walls_spec, obstacles_spec = [], []

    def add_chain(points: np.ndarray, closed: bool, index: int, kind: str, polygon: int,
                  row: int = -1) -> None:
        ends = np.roll(points, -1, axis=0) if closed else points[1:]
        chains.append((points[: len(ends)], ends, index, polygon, kind, row))

    walls = checks.items(data.get("walls"), "walls", _LIST_FIX.format("walls"))
    for k, wall in enumerate(walls):
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
            if abs(velocity) > checks.MAX_SPEED:
                raise SceneError(f"{field}.velocity", f"{show(velocity)} m/s is above "
                                 f"{checks.MAX_SPEED:g} m/s in magnitude, where a step of 1 s "
                                 "would leave the scene's coordinate bound",
                                 f"set {field}.velocity within ±{checks.MAX_SPEED:g} m/s")
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
        v = checks.velocities(checks.vec2(obs.get("velocity", [0.0, 0.0]),
                                          f"{field}.velocity")[None], f"{field}.velocity")[0]
        w = checks.number(obs.get("angular_velocity", 0.0), f"{field}.angular_velocity")
        pivot = checks.point(obs["pivot"], f"{field}.pivot") if "pivot" in obs else centre
        mv_v.append(v)
        mv_w.append(w)
        mv_p.append(pivot)
        return len(mv_w) - 1, {"velocity": v.tolist(), "angular_velocity": w,
                               "pivot": pivot.tolist()}

    moving = {"velocity", "angular_velocity", "pivot"}
    obstacles = checks.items(data.get("obstacles"), "obstacles", _LIST_FIX.format("obstacles"))
    for k, obs in enumerate(obstacles):
        field = f"obstacles[{k}]"
        checks.mapping(obs, field)
        if checks.kind(obs, field, ("circle", "polygon")) == "polygon":
            checks.mapping(obs, field, allowed={"kind", "points"} | moving, required={"points"})
            points = chain_points(obs["points"], f"{field}.points", True, 3)
            row, keys = motion(obs, field, points.mean(axis=0))
            add_chain(points, True, k, "polygon", k, row)
            obstacles_spec.append({"kind": "polygon", "points": points.tolist(), **keys})
            continue
        # the key is spelt either way (centre, as the prose of the docs; center, as before)
        if "centre" in obs and "center" in obs:
            raise SceneError(field, "has both centre and center (one key, spelt two ways)",
                             "keep one of them")
        key = "centre" if "centre" in obs else "center"
        checks.mapping(obs, field, allowed={"kind", key, "radius"} | moving,
                       required={key, "radius"})
        center = checks.point(obs[key], f"{field}.{key}")
        radius = checks.length(obs["radius"], f"{field}.radius", nonnegative=True)
        cc.append(center)
        cr.append(radius)
        c_i.append(k)
        row, keys = motion(obs, field, center)
        c_m.append(row)
        obstacles_spec.append({"kind": "circle", "center": center.tolist(), "radius": radius,
                               **keys})

    if grid is not None:
        starts, ends = grid.segments()
        chains.append((np.asarray(starts, dtype=np.float64).reshape(-1, 2),
                       np.asarray(ends, dtype=np.float64).reshape(-1, 2), -1, -1, "map", -1))

    def arr(x: Any, shape: tuple) -> np.ndarray:
        return np.array(x, dtype=np.float64).reshape(shape)

    counts = [len(c[0]) for c in chains]

    def each(j: int) -> np.ndarray:  # chain j's value repeated on its segments, (S,) int
        return np.repeat(np.array([c[j] for c in chains], dtype=np.intp), counts)

    sa = np.concatenate([c[0] for c in chains]) if chains else np.zeros((0, 2))
    sb = np.concatenate([c[1] for c in chains]) if chains else np.zeros((0, 2))
    s_i, s_poly, s_m = each(2), each(3), each(5)
    s_part = np.concatenate([np.arange(n, dtype=np.intp) for n in counts]) if chains \
        else np.zeros(0, dtype=np.intp)
    s_kind = [kind for c, n in zip(chains, counts) for kind in [c[4]] * n]
    geom = Geometry(arr(hp_n, (-1, 2)), arr(hp_c, (-1,)), arr(hp_v, (-1,)), arr(sa, (-1, 2)),
                    arr(sb, (-1, 2)), arr(cc, (-1, 2)), arr(cr, (-1,)),
                    np.array(hp_i, dtype=np.intp), s_i, np.array(c_i, dtype=np.intp), s_poly,
                    s_part, tuple(s_kind), arr(mv_v, (-1, 2)), arr(mv_w, (-1,)),
                    arr(mv_p, (-1, 2)), s_m,
                    np.array(c_m, dtype=np.intp))
    return geom, walls_spec, obstacles_spec
