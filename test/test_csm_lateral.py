"""The csm law's lateral fraction (``flows.headway.lateral``, k): refused outside (0, 1] with
field and fix; a neighbour beside the path slows an agent exactly when its lateral offset is
within k l_ij; k = 1 is the published law; a recording whose scene does not name ``lateral``
(made before the key existed) replays with the full stripe, bit for bit."""
from __future__ import annotations

import numpy as np
import pytest

import sweep_core as sc
from sweep_core.analysis import replay
from sweep_core.analysis.run import load_run
from sweep_core.errors import SceneError
from sweep_core.io import topics
from sweep_core.io.metadata import run_metadata
from sweep_core.io.recording import Recorder
from sweep_core.model.speed_law import DEFAULT_LATERAL, RECORDED_LATERAL
from sweep_core.model.yaml_files import dump_yaml
from sweep_core.numerics.csm import csm

R = np.full(2, 0.2)


def stagger_scene(headway: dict) -> dict:
    """Eight agents in staggered pairs 0.3 m apart sideways (l = 0.4 m), walking along +x."""
    pts = [[0.5 + 0.45 * k, 1.0 + (0.3 if k % 2 else 0.0)] for k in range(8)]
    return {"name": "stagger", "agents": {"positions": pts, "radius": 0.2},
            "walls": [{"kind": "halfplane", "normal": [0, 1], "offset": 0.0}],
            "drift": {"kind": "uniform", "velocity": [1.2, 0.0]}, "noise": {"sigma": 0.05},
            "flows": {"headway": headway}}


@pytest.mark.parametrize("value", [0.0, -0.5, 1.5, "half", float("nan")])
def test_a_lateral_fraction_outside_zero_one_is_refused_with_field_and_fix(value):
    with pytest.raises(SceneError) as err:
        sc.Scene.from_dict(stagger_scene({"lateral": value}))
    assert err.value.field == "flows.headway.lateral"
    assert "(0, 1]" in err.value.fix


@pytest.mark.parametrize("offset", [0.0, 0.1, 0.25, 0.35, 0.39])
@pytest.mark.parametrize("k", [0.5, 0.7, 1.0])
def test_a_neighbour_beside_the_path_slows_exactly_within_k_times_the_two_radii(offset, k):
    # j is 1 m ahead of i and `offset` m beside its line of motion; no repulsion, T = 0.5 s
    q = np.array([[0.0, 0.0], [1.0, offset]])
    u = np.array([[1.2, 0.0], [0.0, 0.0]])
    out = csm(q, R, u, 0.5, 0.0, 0.1, k)
    gap = np.hypot(1.0, offset) - 0.4
    want = min(1.2, gap / 0.5) if offset <= k * 0.4 else 1.2
    assert out[0, 0] == pytest.approx(want, rel=1e-12) and out[0, 1] == 0.0


def test_k_one_is_the_published_law_and_the_default_fills_the_spec():
    q = np.random.default_rng(4).uniform(0, 3, (30, 2))
    u = np.tile([1.0, 0.3], (30, 1))
    r = np.full(30, 0.2)
    assert np.array_equal(csm(q, r, u, 0.8, 2.0, 0.1), csm(q, r, u, 0.8, 2.0, 0.1, 1.0))
    spec = sc.Scene.from_dict(stagger_scene({})).flows.spec["headway"]
    assert spec["lateral"] == DEFAULT_LATERAL


def record_headway(path, headway: dict, drop: tuple[str, ...], steps: int = 40) -> None:
    """A run of ``stagger_scene(headway)`` recorded as ``sweep run`` records it, its recorded
    scene's headway without the keys ``drop`` (as a recording made before they existed)."""
    scene = sc.Scene.from_dict(stagger_scene(headway))
    sim = sc.Simulator(scene, dt=0.05, seed=5)
    meta = run_metadata(scene, sim, None, 1)
    spec = dict(scene.spec)
    spec["flows"] = {**spec["flows"], "headway": {
        k: v for k, v in spec["flows"]["headway"].items() if k not in drop}}
    meta["scene"] = dump_yaml(spec)
    with Recorder(path, metadata=meta, flush_interval_s=None) as rec:
        for name, msgtype in topics.TYPES.items():
            rec.add_channel("/" + name, msgtype)
        for k in range(steps + 1):
            if k:
                sim.step()
            for name, data in topics.encode_state(sim.state).items():
                rec.write("/" + name, topics.stamp_ns(sim.t), data)


def test_a_recording_made_before_lateral_existed_replays_identically(tmp_path):
    f = tmp_path / "old.mcap"
    # run with the full stripe, recorded without lateral (and the keys added after it)
    record_headway(f, {"time_gap": 0.8, "lateral": RECORDED_LATERAL, "follow": 0.0},
                   ("lateral", "fade", "length", "follow"))
    assert "lateral" not in load_run(f).raw["scene"]
    assert load_run(f).scene.flows.lateral == RECORDED_LATERAL
    res = replay.replay(f)
    assert res.identical and res.steps_simulated == 40
