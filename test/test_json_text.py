"""A recording carries its scene as JSON: every scene reads back equal, within the bounds a
YAML scene is held to, counted from the text before it is decoded; the simple-outline test
examines only pairs whose boxes overlap and finds the same first crossing."""
from __future__ import annotations

import json

import numpy as np
import pytest

import sweep_core as sc
from sweep_core.errors import CostError
from sweep_core.io.metadata import run_metadata
from sweep_core.model import outlines, yaml_files
from sweep_core.model.gallery import scenes_dir
from sweep_core.model.json_text import JSONLimitError, load_json, nesting, node_bound
from sweep_core.model.outlines import first_crossing, segments_meet
from sweep_core.model.scene import Scene, scene_data

SCENES = sorted(p for p in scenes_dir().rglob("*.yaml")
                if p.name != "gallery.yaml" and p.parent.name != "maps")


def _nodes(x) -> int:
    if isinstance(x, list):
        return 1 + sum(_nodes(v) for v in x)
    if isinstance(x, dict):
        return 1 + sum(1 + _nodes(v) for v in x.values())
    return 1


def _depth(x) -> int:
    if isinstance(x, dict):
        x = list(x.values())
    return 1 + max((_depth(v) for v in x), default=0) if isinstance(x, list) else 0


def _random_doc(rng: np.random.Generator, depth: int = 0):
    kind = rng.integers(0, 5 if depth < 6 else 3)
    if kind == 0:
        return float(rng.normal())
    if kind == 1:
        return int(rng.integers(-5, 5))
    if kind == 2:  # strings holding the punctuation the bounds count, and escapes
        return "".join(rng.choice(list('ab[]{},:"\\ '), size=int(rng.integers(0, 8))))
    if kind == 3:
        return [_random_doc(rng, depth + 1) for _ in range(int(rng.integers(0, 4)))]
    return {f"k{j}": _random_doc(rng, depth + 1) for j in range(int(rng.integers(0, 4)))}


@pytest.mark.parametrize("path", SCENES, ids=[p.stem for p in SCENES])
def test_every_bundled_scene_reads_back_from_its_json_equal(path):
    scene = Scene.from_yaml(path)
    text = scene.to_json()
    assert text.startswith("{") and json.loads(text) == scene.spec
    again = Scene.from_yaml_text(text, name=scene.name, files=False)
    assert again.spec == scene.spec and again.to_json() == text


def test_a_recording_carries_its_scene_as_json():
    scene = Scene.from_yaml(SCENES[0])
    meta = run_metadata(scene, sc.Simulator(scene, dt=0.05, seed=1), 1.0)
    assert json.loads(meta["scene"]) == scene.spec


def test_the_bounds_hold_on_random_documents():
    """node_bound is never below the true count (equal when no string holds punctuation and no
    list or mapping is empty); nesting is the true depth whatever the strings hold."""
    rng = np.random.default_rng(7)
    for _ in range(400):
        doc = {"top": _random_doc(rng)}
        text = json.dumps(doc)
        assert nesting(text) == _depth(doc)
        assert node_bound(text) >= _nodes(doc)
        assert load_json(text) == doc
    plain = {"a": [[1.5, 2], [3, 4]], "b": {"c": "text", "d": [True, None]}}
    assert node_bound(json.dumps(plain)) == _nodes(plain)


def test_json_limits_are_refused_before_decoding(monkeypatch):
    monkeypatch.setattr(yaml_files, "MAX_NODES", 1000)
    at_limit = json.dumps({"x": [0] * 997})  # 1 + 1 + 1 + 997 nodes
    assert len(load_json(at_limit)["x"]) == 997
    with pytest.raises(CostError) as err:
        Scene.from_yaml_text(json.dumps({"x": [0] * 998}), source="big.json")
    assert "big.json (JSON) holds up to 1001 values" in str(err.value)
    assert "the limit MAX_NODES" in str(err.value)
    with pytest.raises(JSONLimitError, match="deeper than 64 levels"):
        load_json('{"a": ' + "[" * 64 + "]" * 64 + "}")
    assert load_json('{"a": ' + "[" * 63 + "]" * 63 + "}")
    with pytest.raises(sc.SceneError, match="key 'agents' is given twice"):
        Scene.from_yaml_text('{"agents": {}, "agents": {}}')
    with pytest.raises(sc.SceneError, match="4300 digits"):
        Scene.from_yaml_text('{"name": ' + "9" * 5000 + "}")


def test_json_reads_infinities_and_yaml_flow_mappings_stay_yaml():
    assert load_json('{"a": Infinity, "b": -Infinity}') == {"a": np.inf, "b": -np.inf}
    flow = "{agents: {positions: [[0, 0], [1, 0]], radius: 0.2}}"  # YAML, not JSON
    assert scene_data(flow) == {"agents": {"positions": [[0, 0], [1, 0]], "radius": 0.2}}
    assert Scene.from_yaml_text(flow).n_agents == 2


def _first_crossing_of_every_pair(points: np.ndarray):
    """The reference: every non-adjacent pair tested exactly, in order (i, then j)."""
    m = len(points)
    a, b = points, np.roll(points, -1, axis=0)
    for i in range(m - 2):
        for j in range(i + 2, m if i > 0 else m - 1):
            if segments_meet(a[i], b[i], a[j], b[j]):
                return i, j
    return None


def test_the_first_crossing_is_the_reference_s_on_random_outlines():
    rng = np.random.default_rng(3)
    found = 0
    for _ in range(300):
        m = int(rng.integers(4, 40))
        pts = np.round(rng.uniform(0, 10, (m, 2)), int(rng.integers(0, 3)))
        if np.any(np.hypot(*(np.roll(pts, -1, axis=0) - pts).T) < 1e-12):
            continue
        turn = outlines.orientation(pts, np.roll(pts, -1, axis=0), np.roll(pts, -2, axis=0))
        u = np.roll(pts, -1, axis=0) - pts
        v = np.roll(u, -1, axis=0)
        if np.any((turn == 0) & (np.sum(u * v, axis=1) < 0)):
            continue  # a fold back is reported before any pair (not this loop's job)
        got = first_crossing(pts)
        assert got == _first_crossing_of_every_pair(pts), pts.tolist()
        found += got is not None
    assert found > 100


def test_a_scene_s_outlines_are_held_to_the_pair_budget(monkeypatch):
    monkeypatch.setattr(outlines, "MAX_OUTLINE_PAIRS", 1000)
    t = 2 * np.pi * np.arange(40) / 40
    ring = {"kind": "polyline", "closed": True,
            "points": np.c_[5 + 4 * np.cos(t), 5 + 4 * np.sin(t)].tolist()}
    scene = {"agents": {"positions": [[5.0, 5.0]], "radius": 0.2}, "walls": [ring]}
    Scene.from_dict(scene)  # 40^2 / 2 = 800 pairs
    s = 2 * np.pi * np.arange(21) / 21  # 21^2 / 2 = 220 more
    pillar = np.c_[12 + 0.3 * np.cos(s), 5 + 0.3 * np.sin(s)].tolist()
    with pytest.raises(CostError) as err:
        Scene.from_dict({**scene, "obstacles": [{"kind": "polygon", "points": pillar}]})
    assert str(err.value).startswith("obstacles[0].points: brings the pairs of edges")
    assert "MAX_OUTLINE_PAIRS" in str(err.value)
    first_crossing(np.array(ring["points"]))  # outside a scene's build nothing is counted
