"""What ``sweep run`` records for viewers (``/walls``, ``/markers``), decoded independently of
the project's reader and decoders: by Foxglove's own parser (mcap_ros2.decoder, the schema text
of the recording) and by rosbags (its typestore built from the same schema text)."""
from __future__ import annotations

from collections import defaultdict

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

import sweep_core as sc
from sweep_core.io.metadata import run_metadata
from sweep_core.io.recording import runs
from sweep_core.model.scene import load_scene

TOPICS = ("/walls", "/markers", "/agents")


def _record(tmp_path, scene, t_end, dt=0.05, **kw):
    sim = sc.Simulator(scene, dt=dt, seed=1)
    radii: dict[int, np.ndarray] = {}
    robots: dict[int, list] = {}

    def keep(s):
        ns = int(round(s.t * 1e9))
        radii[ns] = s.state.radii.copy()
        if s.robots is not None:
            robots[ns] = [s.robots.state(n).pose for n in s.robots.names]

    out = tmp_path / "run.mcap"
    done = runs.record_run(sim, t_end, out, run_metadata(scene, sim, t_end, 1), on_state=keep,
                           **kw)
    assert done.status == "completed", done.error
    return out, radii, robots


def _foxglove(path):
    """{topic: [(log_time_ns, message)]} by Foxglove's mcap_ros2 decoder."""
    got = defaultdict(list)
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _, channel, message, decoded in reader.iter_decoded_messages(topics=list(TOPICS)):
            got[channel.topic].append((message.log_time, decoded))
    return got


def _rosbags(path):
    """{topic: [message]} by rosbags, its types registered from the recording's schemas."""
    store = get_typestore(Stores.EMPTY)
    got = defaultdict(list)
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        for schema in summary.schemas.values():
            store.register(get_types_from_msg(schema.data.decode(), schema.name))
        for schema, channel, message in reader.iter_messages(topics=["/walls", "/markers"]):
            got[channel.topic].append(store.deserialize_cdr(message.data, schema.name))
    return got


def _wall_ends(m):
    """The segment a CUBE marker spans (its ends, m), from pose, yaw and length."""
    yaw = 2 * np.arctan2(m.pose.orientation.z, m.pose.orientation.w)
    half = 0.5 * m.scale.x * np.array([np.cos(yaw), np.sin(yaw)])
    mid = np.array([m.pose.position.x, m.pose.position.y])
    return mid - half, mid + half


def _check_walls(markers, scene):
    g = scene.geometry
    cubes = [m for m in markers if m.ns.startswith(("walls", "map", "obstacles["))]
    assert len(cubes) == len(g.segment_a) + len(g.halfplane_offset) > 0
    want = {tuple(np.round(np.r_[a, b], 6)) for a, b in zip(g.segment_a, g.segment_b)}
    for m in cubes[:len(g.segment_a)]:
        a, b = _wall_ends(m)
        assert (tuple(np.round(np.r_[a, b], 6)) in want
                or tuple(np.round(np.r_[b, a], 6)) in want)
        assert m.scale.y == pytest.approx(0.05)


def test_default_run_has_walls_and_disks_of_the_radii(tmp_path):
    scene = load_scene(None)  # room_door, as `sweep run` with no scene
    out, radii, _ = _record(tmp_path, scene, 0.5, dt=0.05, markers_every=2)
    fox = _foxglove(out)
    assert len(fox["/walls"]) == 1  # latched, once
    _check_walls(fox["/walls"][0][1].markers, scene)
    assert len(fox["/markers"]) == 6  # 11 recorded states, every other one
    for log_ns, msg in fox["/markers"]:
        disks = [m for m in msg.markers if m.ns == "agents"]
        assert len(disks) == scene.n_agents
        assert [m.id for m in disks] == list(range(scene.n_agents))
        assert np.allclose([m.scale.x for m in disks], 2 * radii[log_ns], rtol=0, atol=1e-12)
        assert np.allclose([m.scale.y for m in disks], 2 * radii[log_ns], rtol=0, atol=1e-12)
        assert all(m.type == 3 and m.header.frame_id == "map" for m in disks)
    # the disks stand where /agents says the agents are
    last_ns, last = fox["/markers"][-1]
    agents = dict(fox["/agents"])[last_ns]
    assert agents.width == len(last.markers)
    bag = _rosbags(out)
    assert len(bag["/walls"]) == 1 and len(bag["/markers"]) == 6
    again = bag["/markers"][-1].markers
    assert [(m.ns, m.id, m.scale.x) for m in again] == [(m.ns, m.id, m.scale.x)
                                                        for m in last.markers]
    _check_walls(bag["/walls"][0].markers, scene)


def test_robot_scene_has_footprint_and_heading(tmp_path):
    scene = load_scene("robot_crowd")
    robot = scene.robots[0]
    out, _, poses = _record(tmp_path, scene, 0.3, dt=0.05, markers_every=1)
    for source in (dict(_foxglove(out)["/markers"]), None):
        msgs = (list(source.items()) if source is not None
                else list(zip(sorted(poses), _rosbags(out)["/markers"])))
        assert len(msgs) == len(poses)
        for log_ns, msg in msgs:
            foot = [m for m in msg.markers if m.ns == "robots"]
            heading = [m for m in msg.markers if m.ns == "robot_headings"]
            assert len(foot) == len(heading) == len(scene.robots) == 1
            x, y, yaw = poses[log_ns][0]
            f, h = foot[0], heading[0]
            assert (f.pose.position.x, f.pose.position.y) == pytest.approx((x, y), abs=1e-12)
            assert f.scale.x == f.scale.y == pytest.approx(2 * robot.radius)
            assert h.type == 0 and h.scale.x == pytest.approx(2 * robot.radius)
            got_yaw = 2 * np.arctan2(h.pose.orientation.z, h.pose.orientation.w)
            assert np.cos(got_yaw - yaw) == pytest.approx(1.0, abs=1e-12)


def test_moving_obstacle_and_new_walls_are_recorded_again(tmp_path):
    scene = load_scene("moving_obstacle")
    out, _, _ = _record(tmp_path, scene, 0.2, dt=0.05, markers_every=1)
    walls = _foxglove(out)["/walls"]
    assert len(walls) == 5  # with every /markers while the obstacle moves
    centres = [[(m.pose.position.x, m.pose.position.y) for m in msg.markers
                if m.ns == "obstacles"] for _, msg in walls]
    assert centres[0] != centres[-1]
    pose = scene.geometry.at(0.2)
    assert np.allclose(centres[-1], pose.circle_center, atol=1e-12)
