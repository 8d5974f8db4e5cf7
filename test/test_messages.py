"""sweep_ros.messages, sweep_ros.params and sweep_ros.msgdefs: pure functions, no DDS."""
from __future__ import annotations

import math

import numpy as np
import pytest
from geometry_msgs.msg import PointStamped, Twist
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import PointCloud2, PointField
from visualization_msgs.msg import Marker, MarkerArray

import sweep_core as sc
from sweep_core.io import cdr
from sweep_core.io.cdr.markers import MarkerBatch, encode_marker_array
from sweep_core.io.cdr.markers import delete_all as delete_all_batch
from sweep_core.io.markers import agent_batch
from sweep_core.model import fields
from sweep_core.model.scene import load_scene
from sweep_ros import clouds, diagnostics, markers, messages, msgdefs, params
from sweep_ros.messages import CommandError

# ---------------------------------------------------------------------------------------------
# commands
# ---------------------------------------------------------------------------------------------


def twist(vx=0.0, vy=0.0, wz=0.0):
    m = Twist()
    m.linear.x, m.linear.y, m.angular.z = vx, vy, wz
    return m


def test_twist_gives_uniform_field():
    f = messages.uniform_from_twist(twist(0.5, -0.25, wz=3.0), max_speed=2.0)
    assert isinstance(f, fields.Uniform)
    np.testing.assert_array_equal(f(0.0, np.zeros((3, 2))), [[0.5, -0.25]] * 3)


@pytest.mark.parametrize("bad", [twist(math.nan, 0.0), twist(0.0, math.inf),
                                 twist(0.0, 0.0, wz=-math.inf), twist(3.0, 4.0)])
def test_twist_refused(bad):
    with pytest.raises(CommandError, match="cmd_vel"):
        messages.uniform_from_twist(bad, max_speed=4.9)


def point(x, y, frame=""):
    m = PointStamped()
    m.header.frame_id = frame
    m.point.x, m.point.y = x, y
    return m


def test_goal_field_and_refusals():
    f = messages.goal_from_point(point(10.0, 0.0, "map"), speed=1.3, slow_radius=0.5,
                                 frame_id="map")
    assert isinstance(f, fields.Goal) and f.speed == 1.3 and f.slow_radius == 0.5
    np.testing.assert_allclose(f(0.0, np.array([[0.0, 0.0]])), [[1.3, 0.0]])
    assert messages.goal_from_point(point(1.0, 2.0), 1.0, 0.5, "map").goal.tolist() == [1, 2]
    for bad, match in [(point(math.nan, 0.0), "non-finite"), (point(0.0, math.inf), "non-finite"),
                       (point(1e9, 0.0), "away"), (point(1.0, 1.0, "odom"), "odom")]:
        with pytest.raises(CommandError, match=match):
            messages.goal_from_point(bad, 1.3, 0.5, "map")


def grid_cloud(x, y, vx, vy, dtype="<f4", names=("x", "y", "vx", "vy"), pad=0, bigendian=None):
    """An organised cloud: row r, column c = node (x[c], y[r]); is_bigendian follows dtype's
    byte order unless given."""
    h, w = len(y), len(x)
    X, Y = np.meshgrid(np.asarray(x, float), np.asarray(y, float))
    size = np.dtype(dtype).itemsize
    rec = np.zeros((h, w), dtype=[(n, dtype) for n in names] + ([("pad", "u1", pad)] if pad
                                                                    else []))
    for n, v in zip(names, (X, Y, np.asarray(vx, float), np.asarray(vy, float))):
        rec[n] = v
    if bigendian is None:
        bigendian = np.dtype(dtype).byteorder == ">"
    m = PointCloud2(height=h, width=w, is_bigendian=bigendian, point_step=rec.dtype.itemsize,
                    row_step=rec.dtype.itemsize * w, is_dense=True)
    code = PointField.FLOAT32 if size == 4 else PointField.FLOAT64
    m.fields = [PointField(name=n, offset=i * size, datatype=code, count=1)
                for i, n in enumerate(names)]
    m.data = rec.tobytes()
    return m


def test_grid_bilinear_inside_and_clamped_outside():
    x, y = np.array([0.0, 1.0, 2.0]), np.array([10.0, 10.5])
    vx = np.array([[0.0, 1.0, 2.0], [1.0, 2.0, 3.0]])  # vx = x + 2 (y - 10)
    vy = -vx
    for dtype in ("<f4", "<f8"):
        f = clouds.grid_from_cloud(grid_cloud(x, y, vx, vy, dtype), max_speed=10.0)
        q = np.array([[0.5, 10.25], [1.5, 10.0], [5.0, 20.0], [-1.0, 0.0]])
        want_vx = np.array([1.0, 1.5, 3.0, 0.0])  # last two: nearest grid point
        np.testing.assert_allclose(f(0.0, q), np.c_[want_vx, -want_vx], atol=1e-6)


def test_grid_float32_rounding_accepted_and_axes_sorted():
    x = np.arange(40) * 0.1 + 3.3  # float32 spacing errors ~1e-7 relative
    y = np.array([2.0, 1.0, 0.0])   # rows running down: sorted
    vx = np.tile(np.arange(40) * 0.01, (3, 1))
    vy = np.tile(np.array([[2.0], [1.0], [0.0]]), (1, 40)) * 0.1
    f = clouds.grid_from_cloud(grid_cloud(x, y, vx, vy), max_speed=10.0)
    np.testing.assert_allclose(f.y, [0.0, 1.0, 2.0])
    np.testing.assert_allclose(f(0.0, np.array([[3.3, 0.5]])), [[0.0, 0.05]], atol=1e-6)


def test_single_node_grid_is_uniform():
    f = clouds.grid_from_cloud(grid_cloud([1.0], [2.0], [[0.3]], [[0.4]]), max_speed=1.0)
    np.testing.assert_allclose(f(0.0, np.array([[9.0, -9.0]])), [[0.3, 0.4]], atol=1e-7)


def _grid_ok():
    return dict(x=[0.0, 1.0, 2.0], y=[0.0, 1.0], vx=np.ones((2, 3)), vy=np.zeros((2, 3)))


@pytest.mark.parametrize("case,match", [
    ("nan", "non-finite vx"), ("inf", "non-finite vy"), ("fast", "max_speed"),
    ("irregular", "irregular"), ("fields", "missing fields"), ("short", "too few"),
    ("datatype", "FLOAT32 or FLOAT64"), ("transposed", "depend on"), ("empty", "empty"),
    ("count", "FLOAT32 or FLOAT64"),
])
def test_grid_refused(case, match):
    g = _grid_ok()
    if case == "nan":
        g["vx"][1, 2] = np.nan
    if case == "inf":
        g["vy"][0, 0] = np.inf
    if case == "fast":
        g["vx"][0, 1] = 50.0
    if case == "irregular":
        g["x"] = [0.0, 1.0, 3.0]
    m = grid_cloud(**g)
    if case == "fields":
        m = grid_cloud(**g, names=("x", "y", "u", "v"))
    if case == "short":
        m.data = bytes(m.data)[:-4]
    if case == "datatype":
        m.fields[2].datatype = PointField.INT32
    if case == "count":
        m.fields[3].count = 2
    if case == "transposed":  # x changes along rows: not rows-along-y
        m = grid_cloud(**g)
        data = np.frombuffer(bytes(m.data), "<f4").reshape(2, 3, 4).copy()
        data[..., [0, 1]] = data[..., [1, 0]]
        m.data = data.tobytes()
    if case == "empty":
        m.height = 0
    with pytest.raises(CommandError, match=match) as info:
        clouds.grid_from_cloud(m, max_speed=10.0)
    assert info.value.topic == "velocity_field"
    msg = str(info.value)
    assert "(fix: " in msg and "np." not in msg and "array(" not in msg, msg


def test_twist_and_goal_refusals_name_value_and_fix():
    for call in (lambda: messages.uniform_from_twist(twist(math.nan, 0.5), 4.9),
                 lambda: messages.uniform_from_twist(twist(3.0, 4.0), 4.9),
                 lambda: messages.goal_from_point(point(math.inf, 0.0), 1.3, 0.5, "map"),
                 lambda: messages.goal_from_point(point(2e6, 0.0), 1.3, 0.5, "map"),
                 lambda: messages.goal_from_point(point(1.0, 1.0, "odom"), 1.3, 0.5, "map")):
        with pytest.raises(CommandError) as info:
            call()
        msg = str(info.value)
        assert "(fix: " in msg and "np." not in msg, msg
    with pytest.raises(CommandError, match=r"linear \[nan, 0.5, 0\]"):
        messages.uniform_from_twist(twist(math.nan, 0.5), 4.9)


@pytest.mark.parametrize("code", ["f4", "f8"])
def test_big_endian_cloud_gives_the_little_endian_field(code):
    x, y = np.array([-1.0, 0.5, 2.0, 3.5]), np.array([10.0, 10.25, 10.5])
    vx = np.arange(12.0).reshape(3, 4) / 10
    vy = -vx[::-1]
    little = clouds.grid_from_cloud(grid_cloud(x, y, vx, vy, "<" + code), max_speed=10.0)
    cloud = grid_cloud(x, y, vx, vy, ">" + code)
    assert cloud.is_bigendian and bytes(cloud.data) != bytes(grid_cloud(x, y, vx, vy,
                                                                       "<" + code).data)
    big = clouds.grid_from_cloud(cloud, max_speed=10.0)
    for name in ("x", "y", "vx", "vy"):
        np.testing.assert_array_equal(getattr(big, name), getattr(little, name))
    q = np.array([[0.0, 10.1], [3.0, 10.4], [9.0, 0.0]])
    np.testing.assert_array_equal(big(0.0, q), little(0.0, q))


@pytest.mark.parametrize("dtype, flag, words", [
    (">f4", False, "is_bigendian=false but the data is big-endian"),
    (">f8", False, "is_bigendian=false but the data is big-endian"),
    ("<f4", True, "is_bigendian=true but the data is little-endian"),
])
def test_cloud_flagged_in_the_wrong_byte_order_is_named(dtype, flag, words):
    """Data in one byte order flagged as the other used to be called 'an irregular grid'."""
    g = _grid_ok()
    with pytest.raises(CommandError) as info:
        clouds.grid_from_cloud(grid_cloud(**g, dtype=dtype, bigendian=flag), max_speed=10.0)
    msg = str(info.value)
    assert words in msg, msg
    assert msg.endswith(f"(fix: set is_bigendian={'false' if flag else 'true'} to match the "
                        "data's byte order)"), msg


# ---------------------------------------------------------------------------------------------
# markers, diagnostics
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("frame_id", ["map", "m", "odom_12", "a_longer_frame"])
def test_marker_array_encoder_matches_rclpy(frame_id):
    """sweep_core's vectorised MarkerArray bytes deserialise (rclpy) to the message rclpy
    serialises from the same batches, for namespaces of every length modulo 8 (the markers'
    alignment repeats after one marker or two)."""
    rng = np.random.default_rng(1)
    stamp = 12_345_678_901
    for n in (0, 1, 2, 3, 8, 41):
        batches = [MarkerBatch("ab"[:k] + "cdefghij"[:k], k % 4, rng.integers(0, 99, n),
                               rng.uniform(-5, 5, (n, 3)), rng.uniform(-3, 3, n),
                               rng.uniform(0.1, 2, (n, 3)), rng.uniform(0, 1, (n, 4)))
                   for k in range(9)]
        batches.insert(3, delete_all_batch("walls"))
        data = encode_marker_array(stamp, frame_id, batches)
        ref = serialize_message(markers.to_message(frame_id, stamp, batches))
        assert len(data) == len(ref)
        got = deserialize_message(data, MarkerArray)
        assert got == deserialize_message(ref, MarkerArray)
        assert len(got.markers) == 9 * n + 1
        for m in got.markers:
            assert m.header.frame_id == frame_id
            assert (m.header.stamp.sec, m.header.stamp.nanosec) == (12, 345_678_901)


def test_wall_markers_and_delete_all():
    scene = sc.Scene.from_dict({
        "agents": {"positions": [[1.0, 1.0]], "radius": 0.2},
        "walls": [{"kind": "segment", "a": [0, 0], "b": [4, 0]},
                  {"kind": "halfplane", "normal": [0, 1], "offset": -1.0, "velocity": 0.5}],
        "obstacles": [{"kind": "circle", "center": [3, 3], "radius": 0.5}]})
    arr = markers.wall_markers(scene.geometry, scene.positions, "map", 0, t=2.0, height=2.0)
    kinds = [(m.ns, m.id, m.type) for m in arr.markers]
    assert kinds == [("walls", 0, Marker.CUBE), ("walls", 1, Marker.CUBE),
                     ("obstacles", 0, Marker.CYLINDER)]
    seg, hp, circ = arr.markers
    assert (seg.pose.position.x, seg.pose.position.y, seg.scale.x) == (2.0, 0.0, 4.0)
    # half-plane y >= -1 + 0.5 t drawn just outside its boundary y = 0 at t = 2
    assert hp.pose.position.y == pytest.approx(-markers.WALL_THICKNESS / 2)
    assert abs(hp.pose.orientation.z) < 1e-12 and hp.scale.x > 5
    assert circ.scale.x == 1.0 and circ.pose.position.x == 3.0
    clear = markers.delete_all("map", 0)
    assert [m.action for m in clear.markers] == [Marker.DELETEALL]


def test_diagnostics_and_time():
    arr = diagnostics.diagnostics(1_500_000_000, "n", "room", "WARN", "slow",
                               {"a": 1.23456789, "b": True, "c": 3})
    st = arr.status[0]
    assert st.level == diagnostics.LEVELS["WARN"] and st.message == "slow"
    assert {kv.key: kv.value for kv in st.values} == {"a": "1.23457", "b": "true", "c": "3"}
    assert (arr.header.stamp.sec, arr.header.stamp.nanosec) == (1, 500_000_000)
    assert messages.stamp_ns_of(messages.time_msg(-1)) == -1


# ---------------------------------------------------------------------------------------------
# parameters
# ---------------------------------------------------------------------------------------------


def test_descriptors_cover_every_parameter():
    for spec in params.SPECS:
        d = params.descriptor(spec)
        assert d.description and d.name == spec.name
        if spec.type is float and spec.lo is not None:
            assert d.floating_point_range[0].from_value == spec.lo
        if not spec.live:
            assert "restart" in d.additional_constraints
    assert params.check_start(params.defaults()) == []


def test_config_file_lists_every_parameter_with_its_default():
    from pathlib import Path

    import yaml
    path = Path(__file__).resolve().parents[1] / "config" / "sweep_node.yaml"
    values = yaml.safe_load(path.read_text())["/**"]["ros__parameters"]
    assert values == params.defaults()


@pytest.mark.parametrize("name,value,match", [
    ("dt", 0.0, "dt: 0 is outside [1e-05, 1] (fix: set dt to a value in [1e-05, 1]"),
    ("dt", 1, None), ("rate_hz", -5.0, "rate_hz"),
    ("steps_per_tick", 2.5, "type int"), ("publish_markers", 1, "type bool"),
    ("frame_id", "/map", "frame_id"), ("frame_id", "", "frame_id"),
    ("noise_sigma", -0.5, "-1"), ("noise_sigma", -1.0, None), ("noise_sigma", 0.2, None),
    ("record", "/no/such/folder/x.mcap", "does not exist"), ("scene", "/no/scene.yaml", "scene"),
    ("marker_rate_hz", math.nan, "finite"), ("seed", -1, "seed"),
])
def test_check_value(name, value, match):
    problem = params.check_value(name, value)
    if match is None:
        assert problem is None
    else:
        assert problem is not None and problem.startswith(name) and match in problem
        assert "(fix: " in problem, problem


def test_check_start_reuses_solver_validation():
    values = dict(params.defaults(), solver_eps_abs=1e-9, solver_max_iter=0)
    problems = params.check_start(values)
    assert len(problems) == 1 and problems[0].startswith("solver_max_iter")
    values["solver_max_iter"] = 10
    assert params.check_start(values) == []


def test_check_live():
    cur = params.defaults()
    ok = params.check_live([("rate_hz", 5.0), ("noise_sigma", 0.0), ("use_sim_time", True)], cur)
    assert ok.successful, ok.reason
    same = params.check_live([("dt", cur["dt"])], cur)
    assert same.successful
    refused = params.check_live([("rate_hz", 5.0), ("dt", 0.02), ("seed", 3)], cur)
    assert not refused.successful
    assert "dt: cannot change while running" in refused.reason and "seed" in refused.reason
    bad = params.check_live([("marker_rate_hz", 0.0)], cur)
    assert not bad.successful and "marker_rate_hz" in bad.reason


# ---------------------------------------------------------------------------------------------
# message definitions
# ---------------------------------------------------------------------------------------------


def test_dependencies_parser():
    text = ("# comment Foo\nHeader h\nfloat64[] a\nstring<=5 s\nother_pkg/Bar b  # c\n"
            "Baz[3] z\nint32 K=3\nmy/msg/Qux[<=2] q\n")
    assert msgdefs.dependencies(text, "pkg") == ["my/Qux", "other_pkg/Bar", "pkg/Baz",
                                                 "std_msgs/Header"]


@pytest.mark.parametrize("msgtype", sorted(cdr.SCHEMAS))
def test_definition_order_matches_sweep_core(msgtype):
    try:
        full = msgdefs.definition(msgtype)
    except msgdefs.MsgDefError as err:  # tf2_msgs is not among the pip-installable packages
        pytest.skip(str(err))
    assert msgdefs.dependency_names(full) == msgdefs.dependency_names(cdr.SCHEMAS[msgtype])
    assert f"\n{'=' * 80}\nMSG: " in full


@pytest.mark.parametrize("msg_class", [MarkerArray, Twist, PointStamped, PointCloud2])
def test_definitions_decode_with_mcap_ros2_and_rosbags(msg_class):
    from mcap_ros2._dynamic import generate_dynamic
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    msgtype = msgdefs.msgtype_of(msg_class)
    full = msgdefs.definition(msgtype)
    msg = msg_class()
    if msg_class is MarkerArray:
        msg = markers.to_message("map", 7, [agent_batch(np.array([[1.5, 2.5]]), np.array([0.25]),
                                                        np.array([3]), np.array([-1]))])
    data = bytes(serialize_message(msg))
    decoded = generate_dynamic(msgtype, full)[msgtype](data)
    store = get_typestore(Stores.EMPTY)
    store.register(get_types_from_msg(full, msgtype))
    again = store.deserialize_cdr(data, msgtype)
    if msg_class is MarkerArray:
        for m in (decoded.markers[0], again.markers[0]):
            assert (m.id, m.pose.position.x, m.scale.y) == (3, 1.5, 0.5)


def test_unknown_type():
    with pytest.raises(msgdefs.MsgDefError, match="not found"):
        msgdefs.definition("no_such_pkg/msg/Thing")
    with pytest.raises(msgdefs.MsgDefError):
        msgdefs.split_type("Thing")


def test_bundled_scene_loads():
    assert load_scene("").n_agents == 200


def test_goal_cell_and_wall_buffer_checked_together():
    """The geodesic field of a goal command needs goal_wall_buffer >= 1.118 goal_cell, at
    start and live (the change of either)."""
    values = {**params.defaults(), "goal_cell": 0.5}
    assert params.check_start(values) == [
        "goal_cell: 0.5 m is too coarse for goal_wall_buffer 0.3 m (a grid step could cross a "
        "thin wall unseen) (fix: set goal_cell to at most 0.2683 m or goal_wall_buffer to at "
        "least 0.559 m)"]
    current = params.defaults()
    assert not params.check_live([("goal_wall_buffer", 0.1)], current).successful
    assert params.check_live([("goal_cell", 0.5), ("goal_wall_buffer", 0.6)],
                             current).successful


def test_navigation_refusal_names_parameters_and_scene_agents():
    err = sc.SceneError("goal", "agent 1 at [2, 1] has no way to the goal that keeps wall_buffer "
                     "0.3 m from walls", "open a passage at least 2 x goal.wall_buffer wide")
    got = messages.navigation_refusal("/goal/b", err, members=np.array([3, 4, 5]))
    assert str(got) == ("/goal/b: the geodesic field refused: agent 4 at [2, 1] has no way to "
                        "the goal that keeps wall_buffer 0.3 m from walls (fix: open a passage "
                        "at least 2 x parameter goal_wall_buffer wide)")
    err = sc.SceneError("goal.cell", "0.01 m makes a grid of too many nodes",
                     "set goal.cell to at least 0.02 m")
    assert str(messages.navigation_refusal("/goal", err)) == (
        "/goal: parameter goal_cell refused: 0.01 m makes a grid of too many nodes (fix: set "
        "parameter goal_cell to at least 0.02 m)")
