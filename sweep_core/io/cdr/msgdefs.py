"""Type names and ros2msg definitions (comments stripped) of the messages sweep_ros records,
as rosbag2 stores them in MCAP schema records: ``SCHEMAS`` maps a type to its text."""
from __future__ import annotations

POSE_ARRAY = "geometry_msgs/msg/PoseArray"
POINT_CLOUD2 = "sensor_msgs/msg/PointCloud2"
CLOCK = "rosgraph_msgs/msg/Clock"
ODOMETRY = "nav_msgs/msg/Odometry"
TWIST_STAMPED = "geometry_msgs/msg/TwistStamped"
LASER_SCAN = "sensor_msgs/msg/LaserScan"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
POSE_WITH_COVARIANCE_STAMPED = "geometry_msgs/msg/PoseWithCovarianceStamped"
MARKER_ARRAY = "visualization_msgs/msg/MarkerArray"

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


# The robot's messages (odometry, velocity commands, laser scans, transforms, initial pose).
_VECTOR3_MSG = "float64 x\nfloat64 y\nfloat64 z\n"
_TWIST_MSG = "Vector3  linear\nVector3  angular\n"
_TRANSFORM_MSG = "Vector3 translation\nQuaternion rotation\n"
_LOCAL_DEFS: dict[str, str] = {
    "builtin_interfaces/Time": _TIME_MSG,
    "std_msgs/Header": _HEADER_MSG,
    "geometry_msgs/Point": _POINT_MSG,
    "geometry_msgs/Quaternion": _QUATERNION_MSG,
    "geometry_msgs/Pose": _POSE_MSG,
    "geometry_msgs/Vector3": _VECTOR3_MSG,
    "geometry_msgs/Twist": _TWIST_MSG,
    "geometry_msgs/PoseWithCovariance": "Pose pose\nfloat64[36] covariance\n",
    "geometry_msgs/TwistWithCovariance": "Twist twist\nfloat64[36] covariance\n",
    "geometry_msgs/TwistStamped": "std_msgs/Header header\nTwist twist\n",
    "geometry_msgs/PoseWithCovarianceStamped":
        "std_msgs/Header header\nPoseWithCovariance pose\n",
    "geometry_msgs/Transform": _TRANSFORM_MSG,
    "geometry_msgs/TransformStamped":
        "std_msgs/Header header\nstring child_frame_id\nTransform transform\n",
    "nav_msgs/Odometry": (
        "std_msgs/Header header\n"
        "string child_frame_id\n"
        "geometry_msgs/PoseWithCovariance pose\n"
        "geometry_msgs/TwistWithCovariance twist\n"
    ),
    "sensor_msgs/LaserScan": (
        "std_msgs/Header header\n"
        "float32 angle_min\n"
        "float32 angle_max\n"
        "float32 angle_increment\n"
        "float32 time_increment\n"
        "float32 scan_time\n"
        "float32 range_min\n"
        "float32 range_max\n"
        "float32[] ranges\n"
        "float32[] intensities\n"
    ),
    "tf2_msgs/TFMessage": "geometry_msgs/TransformStamped[] transforms\n",
    # visualization_msgs/MarkerArray as ROS 2 Kilted defines it (visualization_msgs 5.5)
    "visualization_msgs/MarkerArray": "Marker[] markers\n",
    "visualization_msgs/Marker": (
        "".join(f"int32 {name}={value}\n" for name, value in (
            ("ARROW", 0), ("CUBE", 1), ("SPHERE", 2), ("CYLINDER", 3), ("LINE_STRIP", 4),
            ("LINE_LIST", 5), ("CUBE_LIST", 6), ("SPHERE_LIST", 7), ("POINTS", 8),
            ("TEXT_VIEW_FACING", 9), ("MESH_RESOURCE", 10), ("TRIANGLE_LIST", 11),
            ("ARROW_STRIP", 12), ("ADD", 0), ("MODIFY", 0), ("DELETE", 2), ("DELETEALL", 3)))
        + "std_msgs/Header header\n"
        "string ns\n"
        "int32 id\n"
        "int32 type\n"
        "int32 action\n"
        "geometry_msgs/Pose pose\n"
        "geometry_msgs/Vector3 scale\n"
        "std_msgs/ColorRGBA color\n"
        "builtin_interfaces/Duration lifetime\n"
        "bool frame_locked\n"
        "geometry_msgs/Point[] points\n"
        "std_msgs/ColorRGBA[] colors\n"
        "string texture_resource\n"
        "sensor_msgs/CompressedImage texture\n"
        "UVCoordinate[] uv_coordinates\n"
        "string text\n"
        "string mesh_resource\n"
        "MeshFile mesh_file\n"
        "bool mesh_use_embedded_materials\n"
    ),
    "visualization_msgs/MeshFile": "string filename\nuint8[] data\n",
    "visualization_msgs/UVCoordinate": "float32 u\nfloat32 v\n",
    "sensor_msgs/CompressedImage": "std_msgs/Header header\nstring format\nuint8[] data\n",
    "std_msgs/ColorRGBA": "float32 r\nfloat32 g\nfloat32 b\nfloat32 a\n",
    "builtin_interfaces/Duration": "int32 sec\nuint32 nanosec\n",
}
_PRIMITIVES = frozenset({"bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16",
                         "uint16", "int32", "uint32", "int64", "uint64", "string", "wstring"})


def _direct_dependencies(name: str) -> list[str]:
    """The ``pkg/Type`` names a local definition uses, sorted (``Header`` is std_msgs')."""
    pkg = name.split("/")[0]
    deps = set()
    for line in _LOCAL_DEFS[name].splitlines():
        words = line.split()
        if len(words) < 2 or "=" in line:
            continue
        typ = words[0].split("[")[0].split("<")[0]
        if typ in _PRIMITIVES:
            continue
        if "/" not in typ:
            typ = "std_msgs/Header" if typ == "Header" else f"{pkg}/{typ}"
        deps.add(typ)
    return sorted(deps)


def _local_definition(msgtype: str) -> str:
    """rosbag2's text of a local type: depth first, each type's direct dependencies in sorted
    order, each type once."""
    top = msgtype.replace("/msg/", "/")
    seen: list[str] = []

    def visit(name: str) -> None:
        for dep in _direct_dependencies(name):
            if dep not in seen:
                seen.append(dep)
                visit(dep)

    visit(top)
    return _compose(_LOCAL_DEFS[top], [(name, _LOCAL_DEFS[name]) for name in seen])


ODOMETRY_MSGDEF = _local_definition(ODOMETRY)
TWIST_STAMPED_MSGDEF = _local_definition(TWIST_STAMPED)
LASER_SCAN_MSGDEF = _local_definition(LASER_SCAN)
TF_MESSAGE_MSGDEF = _local_definition(TF_MESSAGE)
POSE_WITH_COVARIANCE_STAMPED_MSGDEF = _local_definition(POSE_WITH_COVARIANCE_STAMPED)
MARKER_ARRAY_MSGDEF = _local_definition(MARKER_ARRAY)

SCHEMAS: dict[str, str] = {
    POSE_ARRAY: POSE_ARRAY_MSGDEF,
    POINT_CLOUD2: POINT_CLOUD2_MSGDEF,
    CLOCK: CLOCK_MSGDEF,
    ODOMETRY: ODOMETRY_MSGDEF,
    TWIST_STAMPED: TWIST_STAMPED_MSGDEF,
    LASER_SCAN: LASER_SCAN_MSGDEF,
    TF_MESSAGE: TF_MESSAGE_MSGDEF,
    POSE_WITH_COVARIANCE_STAMPED: POSE_WITH_COVARIANCE_STAMPED_MSGDEF,
    MARKER_ARRAY: MARKER_ARRAY_MSGDEF,
}
