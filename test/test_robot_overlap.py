"""A robot disk's overlap with walls and obstacles (:func:`sweep_core.model.robots.overlap`),
whose common case is one compiled pass, gives the answer and message of the full
:func:`~sweep_core.model.gaps.gaps` summary on random disks (fixed seeds): clear, touching
within 1e-9 m, overlapping; half-planes, segments, polylines, circles, a polygon (inside and
outside) and a moving circle."""
from __future__ import annotations

import numpy as np
import pytest

from sweep_core.model.gaps import gaps
from sweep_core.model.robots import Robot, overlap
from sweep_core.model.scene import Scene

WALLS = {
    "agents": {"positions": [[1.0, 1.0]], "radius": 0.2},
    "walls": [{"kind": "halfplane", "normal": [0.0, 1.0], "offset": -1.0},
              {"kind": "segment", "a": [-3.0, 5.0], "b": [4.0, 6.0]},
              {"kind": "polyline", "points": [[6, -2], [7, 3], [9, 4]]}],
    "obstacles": [{"kind": "circle", "center": [2.0, 3.0], "radius": 0.7},
                  {"kind": "circle", "center": [0.0, 2.0], "radius": 0.4,
                   "velocity": [0.5, -0.2]},
                  {"kind": "polygon", "points": [[-4, -0.5], [-2, -0.5], [-3, 1.5]]}]}


def reference(robot: Robot, xy: np.ndarray, scene: Scene, t: float, tol: float = 1e-9) -> str:
    """overlap()'s wall and obstacle answer from the full gaps summary (the numpy path)."""
    c = np.array([[float(xy[0]), float(xy[1])]])
    g = gaps(scene.geometry, t, c, np.array([robot.radius]))
    if g.worst_single is not None and g.min_single < -tol:
        _, kind, item, gap = g.worst_single
        return (f"robot {robot.name} at {c[0].tolist()} (radius {robot.radius:g} m) overlaps "
                f"{scene.geometry.describe(kind, item)} by {-gap:.3g} m")
    return ""


@pytest.mark.parametrize("seed", [0, 1])
def test_overlap_with_geometry_equals_the_gaps_summary(seed: int) -> None:
    scene = Scene.from_dict(WALLS)
    rng = np.random.default_rng(seed)
    robot_scene = Scene.from_dict({**WALLS, "agents": {"positions": [[1.0, -0.5]],
                                                        "radius": 0.2},
                                   "robots": [{"name": "r", "radius": 0.3,
                                               "pose": [5.0, 0.5, 0.0]}]})
    robot = robot_scene.robots[0]
    empty, no_r = np.empty((0, 2)), np.empty(0)
    counts = {"clear": 0, "overlap": 0, "edge": 0}
    for _ in range(600):
        t = float(rng.uniform(0.0, 4.0))
        xy = rng.uniform([-5.0, -2.0], [10.0, 7.0])
        got = overlap(robot, xy, scene.geometry, empty, no_r, [], None, t)
        want = reference(robot, xy, scene, t)
        assert got.split(" overlaps ")[-1] == want.split(" overlaps ")[-1]
        assert bool(got) == bool(want)
        counts["overlap" if want else "clear"] += 1
    # disks touching the segment y = 5 + (x + 3) / 7 within +-2e-9 m of tol's edge
    for _ in range(200):
        x = float(rng.uniform(-2.5, 3.5))
        y_wall = 5.0 + (x + 3.0) / 7.0
        normal = np.array([-1.0, 7.0]) / np.hypot(1.0, 7.0)
        xy = np.array([x, y_wall]) - normal * (robot.radius + float(rng.uniform(-2e-9, 2e-9)))
        got = overlap(robot, xy, scene.geometry, empty, no_r, [], None, 0.0)
        want = reference(robot, xy, scene, 0.0)
        assert bool(got) == bool(want)
        assert got.split(" overlaps ")[-1] == want.split(" overlaps ")[-1]
        counts["edge"] += bool(want)
    assert counts["clear"] > 100 and counts["overlap"] > 50 and 0 < counts["edge"] < 200
