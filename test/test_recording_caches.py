"""What the recording keeps from step to step (marker plans and constant columns, header tails,
the empty contacts and status clouds) never goes stale: messages made through the kept values
equal those made from fresh arrays written run by run, when the radii change in time, agents
enter and leave, robots differ, and two simulators alternate through the same encoders."""
from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

import sweep_core as sc
from sweep_core.io import cdr, markers, robot_topics, topics
from sweep_core.io.cdr import markers as cdr_markers
from sweep_core.io.cdr.markers import MarkerBatch, encode_marker_array
from sweep_core.model.scene import load_scene

SINE = {"name": "breathing",
        "agents": {"positions": [[x, y] for x in (0.0, 0.6) for y in (0.0, 0.6, 1.2)],
                   "radius": 0.2,
                   "radius_law": {"kind": "sine", "amplitude": 0.05, "period": 1.0}},
        "drift": {"kind": "goal", "goal": [3.0, 0.6], "speed": 1.0},
        "noise": {"sigma": 0.05}}
#: agents entering (a source, groups 0 and 1) and leaving (a sink) a walled corridor
FLOWS = {"name": "through",
         "agents": {"positions": [[1.0, 1.0], [1.0, 2.0], [2.0, 1.5]], "radius": 0.2},
         "walls": [{"kind": "segment", "a": [0.0, 0.0], "b": [10.0, 0.0]},
                   {"kind": "segment", "a": [0.0, 4.0], "b": [10.0, 4.0]}],
         "drift": {"kind": "goal", "goal": [9.5, 2.0], "speed": 1.3},
         "noise": {"sigma": 0.0},
         "flows": {"sinks": [{"kind": "rectangle", "min": [8.5, 0.0], "max": [10.0, 4.0]}],
                   "sources": [{"region": {"kind": "rectangle", "min": [0.3, 0.3],
                                           "max": [1.5, 3.7]}, "rate": 2.0, "count": 6}]}}


def _fresh(batches: list[MarkerBatch]) -> list[MarkerBatch]:
    """The batches with every column a fresh writable copy (nothing kept)."""
    return [MarkerBatch(b.ns, b.type, np.array(b.ids), np.array(b.position), np.array(b.yaw),
                        np.array(b.scale), np.array(b.color), b.action) for b in batches]


def _reference(stamp_ns: int, batches: list[MarkerBatch], monkeypatch) -> bytes:
    """The message written run by run (no kept plan), from fresh arrays."""
    with monkeypatch.context() as m:
        m.setattr(cdr_markers, "_SMALL_MESSAGE", 0)
        return encode_marker_array(stamp_ns, "map", _fresh(batches))


def _checked_batches(sim: sc.Simulator, monkeypatch) -> list[MarkerBatch]:
    """The simulator's marker batches, checked: the people's scales (N, 3) and colours (N, 4)
    those computed afresh, the message's bytes those written without a kept plan."""
    batches = markers.state_batches(sim)
    d = 2.0 * sim.state.radii
    np.testing.assert_array_equal(batches[0].scale, np.stack([d, d, np.ones(len(d))], axis=1))
    np.testing.assert_array_equal(batches[0].color,
                                  markers.group_colors(markers.agent_groups(sim)))
    ns = int(round(sim.t * 1e9))
    assert encode_marker_array(ns, "map", batches) == _reference(ns, batches, monkeypatch)
    return batches


def test_markers_follow_radii_that_change_in_time(monkeypatch):
    sim = sc.Simulator(sc.Scene.from_dict(SINE), dt=0.05, seed=0)
    seen = set()
    for _ in range(12):
        sim.step(1)
        _checked_batches(sim, monkeypatch)
        seen.add(float(sim.state.radii[0]))
    assert len(seen) > 5  # the radii did change


def test_markers_follow_agents_entering_and_leaving(monkeypatch):
    sim = sc.Simulator(sc.Scene.from_dict(FLOWS), dt=0.05, seed=0)
    counts = set()
    for _ in range(60):
        sim.step(4)
        batches = _checked_batches(sim, monkeypatch)
        np.testing.assert_array_equal(batches[0].ids, sim.state.ids)
        counts.add(len(sim.state.positions))
    assert len(counts) > 3 and 0 in counts  # agents did enter and leave


def test_two_simulators_alternating_get_their_own_markers(monkeypatch):
    names = ("crowdnav", "robot_crowd", "corridor_groups")
    alone = {}
    for name in names:  # each simulator's messages on its own
        sim = sc.Simulator(load_scene(name), dt=0.05, seed=0)
        out = []
        for _ in range(6):
            sim.step(1)
            ns = int(round(sim.t * 1e9))
            out.append(encode_marker_array(ns, "map", markers.state_batches(sim)))
            if sim.robots is not None:
                out.extend(data for _, data in robot_topics.encode_step(sim.robots, ns))
        alone[name] = out
    sims = {name: sc.Simulator(load_scene(name), dt=0.05, seed=0) for name in names}
    mixed: dict[str, list[bytes]] = {name: [] for name in names}
    for _ in range(6):  # the same steps, the simulators taking turns
        for name, sim in sims.items():
            sim.step(1)
            ns = int(round(sim.t * 1e9))
            batches = markers.state_batches(sim)
            data = encode_marker_array(ns, "map", batches)
            assert data == _reference(ns, batches, monkeypatch)
            mixed[name].append(data)
            if sim.robots is not None:
                mixed[name].extend(d for _, d in robot_topics.encode_step(sim.robots, ns))
    assert mixed == alone


def test_robot_columns_follow_their_radii():
    a = sc.Simulator(load_scene("crowdnav"), dt=0.05, seed=0)
    b = sc.Simulator(load_scene("robot_crowd"), dt=0.05, seed=0)
    for sim in (a, b, a, b):
        feet, heads = markers.robot_batches(sim.robots, height=1.5)
        r = np.array([sim.robots.state(n).robot.radius for n in sim.robots.names])
        np.testing.assert_array_equal(feet.scale, np.stack([2 * r, 2 * r, 1.5 + 0 * r], 1))
        np.testing.assert_array_equal(heads.scale, np.stack([2 * r, 0.2 * r, 0.2 * r], 1))
        np.testing.assert_array_equal(feet.position[:, 2], 0.75)
        poses = np.array([sim.robots.state(n).pose for n in sim.robots.names])
        np.testing.assert_array_equal(feet.yaw, poses[:, 2])
        np.testing.assert_array_equal(heads.position[:, :2], poses[:, :2])


def test_kept_columns_are_read_only():
    batch = markers.agent_batch(np.zeros((3, 2)), np.full(3, 0.2), np.arange(3),
                                np.array([0, -1, 1]))
    for column in (batch.scale, batch.color, batch.yaw):
        with pytest.raises(ValueError):
            column[0] = 1.0
    batch.position[0, 0] = 1.0  # the positions are the caller's, every time
    again = markers.agent_batch(np.zeros((3, 2)), np.full(3, 0.2), np.arange(3),
                                np.array([0, -1, 1]))
    assert again.position[0, 0] == 0.0


def test_small_marker_arrays_equal_run_by_run(monkeypatch):
    rng = np.random.default_rng(4)
    for _ in range(200):
        batches = []
        for _ in range(int(rng.integers(1, 5))):
            n = int(rng.integers(0, 9))
            batches.append(MarkerBatch("n" * int(rng.integers(0, 11)), int(rng.integers(0, 4)),
                                       rng.integers(-9, 2**33, n), rng.normal(size=(n, 3)),
                                       rng.normal(size=n), rng.random((n, 3)),
                                       rng.random((n, 4)), int(rng.choice([0, 2, 3]))))
        frame = "f" * int(rng.integers(0, 9))
        stamp = int(rng.integers(-2**40, 2**50))
        with monkeypatch.context() as m:
            m.setattr(cdr_markers, "_SMALL_MESSAGE", 0)
            expected = encode_marker_array(stamp, frame, batches)
        assert encode_marker_array(stamp, frame, batches) == expected


def test_status_and_contacts_follow_their_values():
    sim = sc.Simulator(load_scene("crowdnav"), dt=0.1, seed=0)
    real = sim.robots.state(sim.robots.names[0])
    for clipped, blocked, stopped, goal in [(0, 0, False, False), (3, 1, True, False),
                                            (0, 0, False, False), (7, 2, False, True)]:
        st = SimpleNamespace(clipped=clipped, blocked=blocked, stopped=stopped,
                             goal_reached=goal, contact_ids=real.contact_ids,
                             contact_xy=real.contact_xy, contact_impulse=real.contact_impulse)
        for frame in ("base_link", "r/base_link"):
            expected = cdr.encode_point_cloud2(5, frame, {
                name: np.array([v], dtype=np.float32) for name, v in zip(
                    robot_topics.STATUS_FIELDS, (clipped, blocked, int(stopped), int(goal)))})
            assert robot_topics.encode_status(5, frame, st) == expected
            cloud = cdr.decode_point_cloud2(robot_topics.encode_contacts(9, frame, st))
            assert cloud.stamp_ns == 9 and cloud.frame_id == frame


@pytest.mark.parametrize("n", [0, 1, 10, 300])
def test_agents_cloud_block_equals_its_columns(n):
    rng = np.random.default_rng(n)
    sim = sc.Simulator(load_scene("crowdnav"), dt=0.1, seed=0)
    state = dataclasses.replace(
        sim.state, positions=rng.normal(size=(n, 2)) * 1e39, radii=rng.random(n),
        velocities=np.where(rng.random((n, 2)) < 0.1, np.nan, rng.normal(size=(n, 2))),
        reaction=rng.normal(size=(n, 2)), ids=rng.integers(0, 2**30, n) if n % 2 == 0 else None)
    ns = topics.stamp_ns(state.t)
    expected = cdr.encode_point_cloud2(ns, "map", topics.agent_fields(state))
    assert topics.encode_state(state)[topics.AGENTS] == expected
    with pytest.raises(ValueError, match="block"):
        cdr.encode_float32_cloud(ns, "map", topics.AGENT_FIELDS, np.zeros((n, 8)))
