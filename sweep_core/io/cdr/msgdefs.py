"""Type names and ros2msg definitions (comments stripped) of the messages sweep_ros records,
as rosbag2 stores them in MCAP schema records: ``SCHEMAS`` maps a type to its text."""
from __future__ import annotations

POSE_ARRAY = "geometry_msgs/msg/PoseArray"
POINT_CLOUD2 = "sensor_msgs/msg/PointCloud2"
CLOCK = "rosgraph_msgs/msg/Clock"

# ---------------------------------------------------------------------------------------------
# Message definitions (ros2msg), comments stripped.
# ---------------------------------------------------------------------------------------------

_TIME_MSG = "int32 sec\nuint32 nanosec\n"
_HEADER_MSG = "builtin_interfaces/Time stamp\nstring frame_id\n"
_POINT_MSG = "float64 x\nfloat64 y\nfloat64 z\n"
_QUATERNION_MSG = "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n"
_POSE_MSG = "Point position\nQuaternion orientation\n"
_POSE_ARRAY_MSG = "std_msgs/Header header\nPose[] poses\n"
_POINT_FIELD_MSG = (
    "uint8 INT8    = 1\n"
    "uint8 UINT8   = 2\n"
    "uint8 INT16   = 3\n"
    "uint8 UINT16  = 4\n"
    "uint8 INT32   = 5\n"
    "uint8 UINT32  = 6\n"
    "uint8 FLOAT32 = 7\n"
    "uint8 FLOAT64 = 8\n"
    "string name\n"
    "uint32 offset\n"
    "uint8  datatype\n"
    "uint32 count\n"
)
_POINT_CLOUD2_MSG = (
    "std_msgs/Header header\n"
    "uint32 height\n"
    "uint32 width\n"
    "PointField[] fields\n"
    "bool    is_bigendian\n"
    "uint32  point_step\n"
    "uint32  row_step\n"
    "uint8[] data\n"
    "bool is_dense\n"
)
_CLOCK_MSG = "builtin_interfaces/Time clock\n"

_SEPARATOR = "=" * 80


def _compose(top: str, deps: list[tuple[str, str]]) -> str:
    """Top-level definition, then each dependency as rosbag2 concatenates them."""
    return top + "".join(f"\n{_SEPARATOR}\nMSG: {name}\n{text}" for name, text in deps)


# Dependency order follows rosbag2 (sorted names, depth first).
POSE_ARRAY_MSGDEF = _compose(
    _POSE_ARRAY_MSG,
    [
        ("geometry_msgs/Pose", _POSE_MSG),
        ("geometry_msgs/Point", _POINT_MSG),
        ("geometry_msgs/Quaternion", _QUATERNION_MSG),
        ("std_msgs/Header", _HEADER_MSG),
        ("builtin_interfaces/Time", _TIME_MSG),
    ],
)
POINT_CLOUD2_MSGDEF = _compose(
    _POINT_CLOUD2_MSG,
    [
        ("sensor_msgs/PointField", _POINT_FIELD_MSG),
        ("std_msgs/Header", _HEADER_MSG),
        ("builtin_interfaces/Time", _TIME_MSG),
    ],
)
CLOCK_MSGDEF = _compose(_CLOCK_MSG, [("builtin_interfaces/Time", _TIME_MSG)])

SCHEMAS: dict[str, str] = {
    POSE_ARRAY: POSE_ARRAY_MSGDEF,
    POINT_CLOUD2: POINT_CLOUD2_MSGDEF,
    CLOCK: CLOCK_MSGDEF,
}
