"""The robots' applied commands of a recording, for :mod:`sweep_core.analysis.replay`: every
``/NAME/cmd_vel`` message (the command applied during the step that ends at its stamp) by
segment and step, re-applied as recorded (no clipping: they were clipped when applied); and
the node's placements of a robot (initialpose, metadata ``robot_pose_NNNNNN``: ``placement``
{robot, pose}), made again before the step they were made before; and the recorded
``/NAME/odom``, which the replay compares with the robots' replayed poses bit for bit."""
from __future__ import annotations

import math
import struct
from collections.abc import Callable, Iterator
from typing import Any

from sweep_core.analysis.run import RunMeta
from sweep_core.errors import RecordingError
from sweep_core.io import cdr
from sweep_core.io.recording.reader import read_recording
from sweep_core.io.robot_topics import topic

Commands = dict[tuple[int, int], dict[str, tuple[float, float, float]]]
#: (segment, step) -> {robot name: (x, y, qz, qw)} of the recorded odometry
Odometry = dict[tuple[int, int], dict[str, tuple[float, float, float, float]]]


def _robot_messages(meta: RunMeta, kind: str, decode: Callable[[bytes], Any],
                    lost: list[int] | None = None
                    ) -> Iterator[tuple[tuple[int, int], str, Any]]:
    """((segment, step), robot name, decoded message) of every recorded ``/NAME/<kind>`` in
    file order (none for a scene without robots); a message that cannot be decoded is a
    RecordingError naming where it is. ``lost`` gets the log time (ns) from which a skipped
    chunk may have held such messages, if one was skipped."""
    scene = meta.scene
    if scene is None or not scene.robots:
        return
    topics = {topic(r.name, kind): r.name for r in scene.robots}
    reader = read_recording(meta.path, topics)
    for msg in reader:
        try:
            decoded = decode(msg.data)
        except ValueError as err:
            raise RecordingError(f"{meta.path}: {msg.where()}: {err}") from None
        key = (meta.segment_of(msg.log_time_ns), meta.step_of(decoded.stamp_ns))
        yield key, topics[msg.topic], decoded
    if lost is not None and reader.lost_from_ns is not None:
        lost.append(reader.lost_from_ns)


def recorded_commands(meta: RunMeta, lost: list[int] | None = None) -> Commands:
    """(segment, step) -> {robot name: (vx, vy, omega)} of every recorded ``/NAME/cmd_vel``;
    empty for a scene without robots. ``lost`` gets the log time (ns) from which an
    unreadable chunk may have held commands, if one was skipped."""
    out: Commands = {}
    for key, name, twist in _robot_messages(meta, "cmd_vel", cdr.decode_twist_stamped, lost):
        out.setdefault(key, {})[name] = (
            float(twist.linear[0]), float(twist.linear[1]), float(twist.angular[2]))
    return out


def recorded_odometry(meta: RunMeta) -> Odometry:
    """(segment, step) -> {robot name: (x, y, qz, qw)} of the first recorded ``/NAME/odom`` of
    each step (m and the yaw's quaternion); empty for a scene without robots."""
    out: Odometry = {}
    for key, name, odom in _robot_messages(meta, "odom", cdr.decode_odometry):
        # the first at a step: the pose the step produced (the node publishes the state again
        # after placing a robot between two steps; the placement shows in the next step)
        out.setdefault(key, {}).setdefault(name, (
            float(odom.position[0]), float(odom.position[1]), float(odom.orientation[2]),
            float(odom.orientation[3])))
    return out


def odometry_difference(sim: object, recorded: dict[str, tuple[float, float, float, float]]
                        ) -> str:
    """'' when every robot's replayed pose encodes to the recorded odometry bit for bit (its
    x, y and yaw quaternion as the recording encodes them), else which robot differs and
    by how much."""
    robots = getattr(sim, "robots", None)
    for name, rec in recorded.items():
        if robots is None or name not in robots.states:
            return f"odometry of robot {name} recorded, but the replay has no such robot"
        x, y, yaw = robots.states[name].pose
        mine = (float(x), float(y), *cdr.yaw_quaternion(float(yaw))[2:])
        if any(struct.pack("<d", a) != struct.pack("<d", b) for a, b in zip(rec, mine)):
            dist = math.hypot(rec[0] - mine[0], rec[1] - mine[1])
            return (f"robot {name}'s odometry differs: recorded ({rec[0]:.9g}, {rec[1]:.9g}), "
                    f"replayed ({mine[0]:.9g}, {mine[1]:.9g}) ({dist:.3g} m apart; yaw "
                    f"quaternion {'equal' if rec[2:] == mine[2:] else 'different'})")
    return ""


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
    robots.place(name, pose, sim.t, sim.positions, sim.radii, sim.ids)  # type: ignore
