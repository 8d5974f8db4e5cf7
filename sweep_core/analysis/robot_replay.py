"""The robots' applied commands of a recording, for :mod:`sweep_core.analysis.replay`: every
``/NAME/cmd_vel`` message (the command applied during the step that ends at its stamp) by
segment and step, re-applied as recorded (no clipping: they were clipped when applied); and
the node's placements of a robot (initialpose, metadata ``robot_pose_NNNNNN``: ``placement``
{robot, pose}), made again before the step they were made before."""
from __future__ import annotations

from sweep_core.analysis.run import RunMeta
from sweep_core.errors import RecordingError
from sweep_core.io import cdr
from sweep_core.io.recording.reader import read_recording
from sweep_core.io.robot_topics import topic

Commands = dict[tuple[int, int], dict[str, tuple[float, float, float]]]


def recorded_commands(meta: RunMeta) -> Commands:
    """(segment, step) -> {robot name: (vx, vy, omega)} of every recorded ``/NAME/cmd_vel``;
    empty for a scene without robots."""
    scene = meta.scene
    if scene is None or not scene.robots:
        return {}
    topics = {topic(r.name, "cmd_vel"): r.name for r in scene.robots}
    out: Commands = {}
    for msg in read_recording(meta.path, topics):
        try:
            twist = cdr.decode_twist_stamped(msg.data)
        except ValueError as err:
            raise RecordingError(f"{meta.path}: {msg.where()}: {err}") from None
        key = (meta.segment_of(msg.log_time_ns), meta.step_of(twist.stamp_ns))
        out.setdefault(key, {})[topics[msg.topic]] = (
            float(twist.linear[0]), float(twist.linear[1]), float(twist.angular[2]))
    return out


def drive_by_recording(sim: object) -> None:
    """The simulator's robots driven by the recorded commands alone (no controller)."""
    robots = getattr(sim, "robots", None)
    if robots is not None:
        robots.controllers.clear()


def apply_commands(sim: object, commands: Commands, segment: int, step: int) -> None:
    """Hold the commands recorded for the step that ends at ``step`` (the simulator is at
    ``step - 1``), as recorded."""
    robots = getattr(sim, "robots", None)
    if robots is None:
        return
    for name, twist in commands.get((segment, step), {}).items():
        robots.command(name, twist, clip=False)


def place_recorded(sim: object, placement: dict) -> None:
    """Puts a robot where the node placed it (``placement``: {"robot": name, "pose": [x, y,
    yaw]}), between two steps as the node did; RecordingError if the record is malformed."""
    robots = getattr(sim, "robots", None)
    try:
        name, pose = str(placement["robot"]), [float(v) for v in placement["pose"]]
    except (KeyError, TypeError, ValueError):
        raise RecordingError(f"robot_pose record {placement!r} has no robot and pose [x, y, "
                             "yaw]") from None
    if robots is None:
        raise RecordingError(f"robot_pose record for {name!r} in a run without robots")
    robots.place(name, pose, sim.t, sim.positions, sim.radii)  # type: ignore
