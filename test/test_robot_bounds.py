"""The documented bounds of a robot's values are accepted at exactly their value, and the
bounds a refusal prints can be followed (a printed bound is itself accepted)."""
from __future__ import annotations

import copy
import re
from pathlib import Path

import pytest
from robot_scenes import small_scene, with_robot

from sweep_core import Scene
from sweep_core.cli import main
from sweep_core.errors import SceneError
from sweep_core.model.yaml_files import dump_yaml

#: the bounds docs/robots.md gives, each at exactly its value
DOCUMENTED = [
    {"kinematics.max_acceleration": 1e9},
    {"kinematics.max_angular_acceleration": 1e8},
    {"scan.rate": 100000},
    {"scan.rate": 0.001},
]


@pytest.mark.parametrize("change", DOCUMENTED)
def test_documented_bounds_are_accepted(change: dict) -> None:
    Scene.from_dict(with_robot(change))


def test_refused_increment_prints_a_least_increment_that_is_accepted() -> None:
    full = {"scan.angle_min": -3.14159265, "scan.angle_max": 3.14159265}
    with pytest.raises(SceneError) as err:
        Scene.from_dict(with_robot({**full, "scan.increment": 0.000314159}))
    text = str(err.value)
    assert err.value.field == "robots[0].scan.increment" and "\n" not in text, text
    least = re.search(r"at least ([0-9.e+-]+) rad", text)
    assert least, text
    scene = Scene.from_dict(with_robot({**full, "scan.increment": float(least.group(1))}))
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


def _tiny_robot_scene(radius: float, controller: str = "orca") -> dict:
    """A corridor 6 m wide and a goal-driven robot of the radius."""
    return {
        "name": "tiny_robot",
        "agents": {"positions": [[5.0, 1.0]], "radius": 0.25},
        "drift": {"kind": "goal", "goal": [-1.0, 1.5], "speed": 0.8},
        "walls": [{"kind": "segment", "a": [-2.0, 0.0], "b": [14.0, 0.0]},
                  {"kind": "segment", "a": [-2.0, 6.0], "b": [14.0, 6.0]}],
        "robots": [{"name": "bot", "radius": radius, "pose": [0.5, 3.0, 0.0],
                    "kinematics": {"type": "diff_drive", "max_speed": 0.5},
                    "goal": [11.0, 3.0], "controller": controller}],
    }


def test_too_small_robot_for_its_controller_names_the_radius(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scene = tmp_path / "scene.yaml"
    scene.write_text(dump_yaml(_tiny_robot_scene(0.01)))
    args = ["run", str(scene), "--t-end", "0.05", "--dt", "0.01", "--quiet",
            "--out", str(tmp_path / "out.mcap"), "--overwrite"]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("sweep: error: robots[0].radius: 0.01 m") and "\n" not in err, err
    assert "goal." not in err and "(fix: " in err, err
    least = re.search(r"radius to at least ([0-9.e+-]+) m", err)
    assert least, err
    scene.write_text(dump_yaml(_tiny_robot_scene(float(least.group(1)))))
    assert main(args) == 0, capsys.readouterr().err
    scene.write_text(dump_yaml(_tiny_robot_scene(0.01, "none")))
    assert main(args) == 0, capsys.readouterr().err
