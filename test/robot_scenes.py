"""Small scenes with a robot shared by the robot tests (environment, metrics)."""
import copy


def small_scene(sigma: float = 0.1, holonomic: bool = False) -> dict:
    """A 6 m x 3 m corridor, two people walking west, a robot heading east (few scan beams)."""
    return {
        "name": "small_crowdnav",
        "agents": {"positions": [[3.5, 1.0], [4.5, 2.0]], "radius": 0.25},
        "drift": {"kind": "goal", "goal": [-1.0, 1.5], "speed": 0.8},
        "noise": {"sigma": sigma},
        "walls": [{"kind": "segment", "a": [-2.0, 0.0], "b": [8.0, 0.0]},
                  {"kind": "segment", "a": [-2.0, 3.0], "b": [8.0, 3.0]}],
        "robots": [{
            "name": "bot", "radius": 0.3, "pose": [0.5, 1.5, 0.0],
            "kinematics": {"type": "holonomic" if holonomic else "diff_drive",
                           "max_speed": 1.0, "max_angular_speed": 1.5,
                           "max_acceleration": 10.0, "max_angular_acceleration": 10.0},
            "goal": [5.0, 1.5], "goal_radius": 0.3,
            "scan": {"range_min": 0.05, "range_max": 5.0, "angle_min": -1.0, "angle_max": 1.0,
                     "increment": 0.25, "rate": 10.0, "noise_std": 0.01}}],
    }


def with_robot(change: dict) -> dict:
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
