"""Hostile robot inputs: kinematic limits, weights and scan values at the extremes of float64
(refused at load with one line naming the field, the value and the fix; exit status 2 from
`sweep run`), the gymnasium environment's None action and disabled robot, and a recording
whose robots' odometry was tampered with (replay must not call it identical)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from mcap_copies import rewrite
from robot_scenes import small_scene, with_robot

from sweep_core import Scene
from sweep_core.cli import main
from sweep_core.errors import SceneError
from sweep_core.io import cdr
from sweep_core.model.yaml_files import dump_yaml

#: (change under robots[0], the field named, words of the message); each raised a traceback,
#: loaded silently, or failed only later in a step on the old code
CASES = [
    ({"scan.increment": 5e-324}, "robots[0].scan.increment", ["e-324", "at least"]),
    ({"scan.increment": 7.0}, "robots[0].scan.increment", ["7", "2 pi"]),
    ({"scan.rate": 5e-324}, "robots[0].scan.rate", ["e-324", "[0.001, 100000] Hz"]),
    ({"scan.rate": 1e-300}, "robots[0].scan.rate", ["1e-300", "[0.001, 100000] Hz"]),
    ({"scan.rate": 1e300}, "robots[0].scan.rate", ["1e+300", "[0.001, 100000] Hz"]),
    ({"scan.noise_std": 1e300}, "robots[0].scan.noise_std", ["1e+300", "range_max"]),
    ({"kinematics.max_angular_speed": 1.7e308}, "robots[0].kinematics.max_angular_speed",
     ["1.7e+308", "at most 1000 rad/s"]),
    ({"kinematics.max_angular_acceleration": 1.7e308},
     "robots[0].kinematics.max_angular_acceleration", ["1.7e+308", "at most 1e+08 rad/s^2"]),
    ({"kinematics.max_acceleration": 1e300}, "robots[0].kinematics.max_acceleration",
     ["1e+300", "at most 1e+09 m/s^2"]),
    ({"kinematics.max_speed": 1e300}, "robots[0].kinematics.max_speed", ["1e+300", "m/s"]),
    ({"weight": 1e-16}, "robots[0].weight", ["1e-16", "[1e-06, 1e+06]"]),
    ({"weight": 5e-324}, "robots[0].weight", ["e-324", "[1e-06, 1e+06]"]),
    ({"weight": 1e300}, "robots[0].weight", ["1e+300", "or inf"]),
]


@pytest.mark.parametrize("change, field, words", CASES)
def test_robot_extremes_refused_at_load(change: dict, field: str, words: list[str]) -> None:
    with pytest.raises(SceneError) as err:
        Scene.from_dict(with_robot(change))
    text = str(err.value)
    assert err.value.field == field and "\n" not in text and "(fix: " in text, text
    for word in words:
        assert word in text, text


@pytest.mark.parametrize("change, field, words", CASES[:4] + CASES[6:8])
def test_robot_extremes_refused_by_sweep_run(capsys: pytest.CaptureFixture[str],
                                             tmp_path: Path, change: dict, field: str,
                                             words: list[str]) -> None:
    scene = tmp_path / "scene.yaml"
    scene.write_text(dump_yaml(with_robot(change)))
    out = tmp_path / "out.mcap"
    rc = main(["run", str(scene), "--t-end", "0.2", "--dt", "0.05", "--out", str(out),
               "--quiet"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and err.startswith("sweep: error: ") and "\n" not in err, err
    assert field in err, err
    assert not out.exists()


def test_env_action_space_is_bounded_and_none_is_refused_by_name() -> None:
    envs = pytest.importorskip("sweep_core.envs")
    env = envs.CrowdNavEnv(small_scene(), max_steps=5)
    env.reset(seed=0)
    with pytest.raises(SceneError) as err:
        env.step(None)
    assert err.value.field == "action" and "None" in str(err.value) and \
        "nan" not in str(err.value), str(err.value)
    assert np.all(np.isfinite(env.action_space.high))
    # the largest omega of the action space turns the robot, its yaw wrapped
    for _ in range(3):
        obs = env.step(env.action_space.high)[0]
    assert -np.pi < obs["odom"][2] <= np.pi


def test_env_with_its_robot_disabled_is_one_line_scene_error() -> None:
    envs = pytest.importorskip("sweep_core.envs")
    with pytest.raises(SceneError) as err:
        envs.CrowdNavEnv(with_robot({"enabled": False}))
    assert err.value.field == "robots[0].enabled" and "\n" not in str(err.value)


def _shift_odometry(src: Path, dst: Path, dx: float) -> int:
    """``src`` copied to ``dst`` with every /NAME/odom pose moved by dx (m) along x; the count
    of messages rewritten."""
    def shift(topic: str, data: bytes) -> bytes | None:
        if not topic.endswith("/odom"):
            return None
        od = cdr.decode_odometry(data)
        pose = (float(od.position[0]) + dx, float(od.position[1]), od.yaw)
        twist = (float(od.linear[0]), float(od.linear[1]), float(od.angular[2]))
        return cdr.encode_odometry(od.stamp_ns, od.frame_id, od.child_frame_id, pose, twist)

    return rewrite(src, dst, shift, library="test tamper")


def test_replay_compares_the_robots_odometry(tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    from sweep_core.analysis.replay import format_replay, replay

    scene = tmp_path / "scene.yaml"
    scene.write_text(dump_yaml(small_scene()))
    out = tmp_path / "run.mcap"
    assert main(["run", str(scene), "--t-end", "1", "--dt", "0.05", "--out", str(out),
                 "--quiet"]) == 0
    assert replay(out).identical
    tampered = tmp_path / "tampered.mcap"
    assert _shift_odometry(out, tampered, 1.0) == 21
    res = replay(tampered)
    assert not res.identical and "robot bot's odometry differs" in format_replay(res)
    assert res.divergence.step == 0
