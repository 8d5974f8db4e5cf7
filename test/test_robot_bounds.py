"""The documented bounds of a robot's values are accepted at exactly their value, and the
bounds a refusal prints can be followed (a printed bound is itself accepted)."""
from __future__ import annotations

import copy
import re

import pytest
from robot_scenes import small_scene

from sweep_core import Scene
from sweep_core.errors import SceneError


def _with(change: dict) -> dict:
    """small_scene() with ``change`` ({dotted key under robots[0]: value}) applied."""
    data = copy.deepcopy(small_scene())
    robot = data["robots"][0]
    for key, value in change.items():
        *path, last = key.split(".")
        node = robot
        for part in path:
            node = node.setdefault(part, {})
        node[last] = value
    return data


#: the bounds docs/robots.md gives, each at exactly its value
DOCUMENTED = [
    {"kinematics.max_acceleration": 1e9},
    {"kinematics.max_angular_acceleration": 1e8},
    {"scan.rate": 100000},
    {"scan.rate": 0.001},
]


@pytest.mark.parametrize("change", DOCUMENTED)
def test_documented_bounds_are_accepted(change: dict) -> None:
    Scene.from_dict(_with(change))


def test_refused_increment_prints_a_least_increment_that_is_accepted() -> None:
    full = {"scan.angle_min": -3.14159265, "scan.angle_max": 3.14159265}
    with pytest.raises(SceneError) as err:
        Scene.from_dict(_with({**full, "scan.increment": 0.000314159}))
    text = str(err.value)
    assert err.value.field == "robots[0].scan.increment" and "\n" not in text, text
    least = re.search(r"at least ([0-9.e+-]+) rad", text)
    assert least, text
    scene = Scene.from_dict(_with({**full, "scan.increment": float(least.group(1))}))
    assert scene.robots[0].scan is not None and scene.robots[0].scan.beams <= 20_000


@pytest.mark.parametrize("horizon", [1e155, 1e300, 100.5])
def test_too_long_reaction_horizon_is_refused(horizon: float) -> None:
    data = copy.deepcopy(small_scene())
    data["crowd_reaction"] = {"kind": "avoid", "horizon": horizon}
    with pytest.raises(SceneError) as err:
        Scene.from_dict(data)
    text = str(err.value)
    assert err.value.field == "crowd_reaction.horizon" and "\n" not in text, text
    assert "at most 100 s" in text, text


@pytest.mark.parametrize("key, value", [("horizon", 100.0), ("radius", 1e4),
                                        ("strength", 1e4)])
def test_reaction_bounds_are_accepted(key: str, value: float) -> None:
    data = copy.deepcopy(small_scene())
    data["crowd_reaction"] = {"kind": "avoid", key: value}
    Scene.from_dict(data)


@pytest.mark.parametrize("key, value", [("radius", 1e300), ("strength", 1e300)])
def test_reaction_radius_and_strength_are_bounded(key: str, value: float) -> None:
    data = copy.deepcopy(small_scene())
    data["crowd_reaction"] = {"kind": "avoid", key: value}
    with pytest.raises(SceneError) as err:
        Scene.from_dict(data)
    assert err.value.field == f"crowd_reaction.{key}", str(err.value)
