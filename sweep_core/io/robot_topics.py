"""What the robots publish and record, per robot NAME: ``/NAME/odom`` (nav_msgs/Odometry),
``/NAME/cmd_vel`` (geometry_msgs/TwistStamped, the command applied at that step after
clipping), ``/NAME/scan`` (sensor_msgs/LaserScan, at the scan's rate), ``/NAME/contacts``
(sensor_msgs/PointCloud2, float32 fields id, x, y, impulse_x, impulse_y: one point per person
in contact, impulse in m/s as :mod:`sweep_core.numerics.robots.fleet` defines it),
``/NAME/status`` (PointCloud2, one point: commands clipped and steps blocked so far, whether
the last step was blocked, whether the goal is reached), ``/tf``
(odom -> base_link of every robot) and ``/tf_static`` (map -> odom, identity: odometry is
exact). Frames: ``odom`` / ``base_link`` with one robot, ``NAME/odom`` / ``NAME/base_link``
with several. Shared by ``sweep run`` and the node."""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from sweep_core.io import cdr
from sweep_core.io.cdr.wire import header_prefix
from sweep_core.model.scene import Scene
from sweep_core.numerics.robots.fleet import Fleet
from sweep_core.numerics.robots.scan import Scan
from sweep_core.numerics.robots.state import RobotState

#: float32 fields of ``/NAME/contacts``, in order
CONTACT_FIELDS = ("id", "x", "y", "impulse_x", "impulse_y")
#: float32 fields of ``/NAME/status`` (one point per recorded step): commands clipped so far,
#: steps blocked so far (a prescribed command refused, the robot stopped), whether the last
#: step was blocked (1) or not (0), whether the robot is within its goal radius (1) or not
STATUS_FIELDS = ("clipped", "blocked", "stopped", "goal_reached")
TF, TF_STATIC = "/tf", "/tf_static"


def frames(scene: Scene, name: str) -> tuple[str, str]:
    """(odom, base_link) frame names of robot ``name``."""
    if len(scene.robots) == 1:
        return "odom", "base_link"
    return f"{name}/odom", f"{name}/base_link"


def topic(name: str, kind: str) -> str:
    """``/NAME/kind`` (kind: odom, cmd_vel, scan, contacts)."""
    return f"/{name}/{kind}"


def channels(scene: Scene) -> dict[str, str]:
    """Topic -> message type of every robot channel of the scene (empty without robots)."""
    out: dict[str, str] = {}
    for r in scene.robots:
        out[topic(r.name, "odom")] = cdr.ODOMETRY
        out[topic(r.name, "cmd_vel")] = cdr.TWIST_STAMPED
        if r.scan is not None:
            out[topic(r.name, "scan")] = cdr.LASER_SCAN
        out[topic(r.name, "contacts")] = cdr.POINT_CLOUD2
        out[topic(r.name, "status")] = cdr.POINT_CLOUD2
    if scene.robots:
        out[TF] = cdr.TF_MESSAGE
        out[TF_STATIC] = cdr.TF_MESSAGE
    return out


def encode_static(scene: Scene, stamp_ns: int, map_frame: str = "map") -> bytes:
    """``/tf_static``: map -> odom (identity) for every robot."""
    return cdr.encode_tf_message([cdr.Transform.planar(stamp_ns, map_frame,
                                                       frames(scene, r.name)[0], 0.0, 0.0, 0.0)
                                  for r in scene.robots])


def encode_scan(stamp_ns: int, frame_id: str, scan: Scan) -> bytes:
    """A scan as ``sensor_msgs/LaserScan`` (ranges float32, no intensities; time_increment 0:
    every beam at the scan's instant; scan_time 1 / rate)."""
    spec = scan.spec
    return cdr.encode_laser_scan(cdr.LaserScan(
        stamp_ns, frame_id, spec.angle_min, spec.angle_min + (spec.beams - 1) * spec.increment,
        spec.increment, 0.0, 1.0 / spec.rate, spec.range_min, spec.range_max, scan.ranges))


@lru_cache(maxsize=64)
def _cloud_body(frame_id: str, values: tuple[tuple[str, tuple[float, ...]], ...]) -> bytes:
    """A PointCloud2 of float32 columns ``values`` ((name, column) each) in ``frame_id``, from
    the byte after its header on (the same whatever its stamp): kept for the few clouds that
    recur (no contacts, a status that does not change)."""
    data = cdr.encode_point_cloud2(0, frame_id, {name: np.array(column, dtype=np.float32)
                                                 for name, column in values})
    return data[len(header_prefix(0, frame_id)):]


def _no_contacts(st: RobotState) -> bool:
    return (len(st.contact_ids) == 0 and st.contact_xy.shape == (0, 2)
            and st.contact_impulse.shape == (0, 2))


def encode_contacts(stamp_ns: int, frame_id: str, st: RobotState) -> bytes:
    """``/NAME/contacts`` of a robot's last step (frame: the map's)."""
    if type(frame_id) is str and _no_contacts(st):  # the empty cloud's body kept
        return header_prefix(stamp_ns, frame_id) + _cloud_body(
            frame_id, tuple((name, ()) for name in CONTACT_FIELDS))
    return cdr.encode_point_cloud2(stamp_ns, frame_id, {
        "id": st.contact_ids.astype(np.float32), "x": st.contact_xy[:, 0],
        "y": st.contact_xy[:, 1], "impulse_x": st.contact_impulse[:, 0],
        "impulse_y": st.contact_impulse[:, 1]})


def encode_status(stamp_ns: int, frame_id: str, st: RobotState) -> bytes:
    """``/NAME/status``: one point of :data:`STATUS_FIELDS`."""
    values = (st.clipped, st.blocked, int(st.stopped), int(st.goal_reached))
    if type(frame_id) is str and all(type(v) is int for v in values):  # its body kept
        return header_prefix(stamp_ns, frame_id) + _cloud_body(
            frame_id, tuple((name, (v,)) for name, v in zip(STATUS_FIELDS, values)))
    return cdr.encode_point_cloud2(stamp_ns, frame_id, {
        name: np.array([v], dtype=np.float32) for name, v in zip(STATUS_FIELDS, values)})


def encode_commands(fleet: Fleet, stamp_ns: int) -> list[tuple[str, bytes]]:
    """``/NAME/cmd_vel`` of every robot: the commands applied in the step ending now (written
    every step, recorded or not, so a replay has them all)."""
    return [(topic(name, "cmd_vel"), cdr.encode_twist_stamped(
        stamp_ns, frames(fleet.scene, name)[1], fleet.state(name).command))
        for name in fleet.names]


def encode_step(fleet: Fleet, stamp_ns: int, map_frame: str = "map") -> list[tuple[str, bytes]]:
    """The robot messages of one recorded step: odom, cmd_vel, contacts (and scan when one was
    taken at this step) of each robot, then ``/tf``."""
    out: list[tuple[str, bytes]] = []
    transforms = []
    for name in fleet.names:
        st = fleet.state(name)
        odom, base = frames(fleet.scene, name)
        out.append((topic(name, "odom"),
                    cdr.encode_odometry(stamp_ns, odom, base, st.pose, st.twist)))
        out.append((topic(name, "cmd_vel"), cdr.encode_twist_stamped(stamp_ns, base, st.command)))
        out.append((topic(name, "contacts"), encode_contacts(stamp_ns, map_frame, st)))
        out.append((topic(name, "status"), encode_status(stamp_ns, base, st)))
        if st.scan is not None and fleet.scanned(name):
            out.append((topic(name, "scan"), encode_scan(stamp_ns, base, st.scan)))
        transforms.append(cdr.Transform.planar(stamp_ns, odom, base, *st.pose))
    out.append((TF, cdr.encode_tf_message(transforms)))
    return out
