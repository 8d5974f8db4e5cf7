"""The csm law's options beyond the published rule (``flows.headway.follow`` beta, ``length``
f, ``fade`` k2): refused out of range with field and fix; each at its neutral value is the law
as it was, bit for bit; each changes the speed exactly as its rule says (single file and one
neighbour beside the path, where the speeds are known in closed form); a recording whose scene
names none of them (made before they existed) replays identically, and so does a run with
them."""
from __future__ import annotations

import math

import numpy as np
import pytest
from test_csm_lateral import record_headway, stagger_scene

import sweep_core as sc
from sweep_core.analysis import replay
from sweep_core.analysis.run import load_run
from sweep_core.errors import SceneError
from sweep_core.model.speed_law import DEFAULT_FOLLOW
from sweep_core.numerics.csm import csm

NEW = ("fade", "length", "follow")


@pytest.mark.parametrize("key, value, words", [
    ("follow", -0.1, "[0, 1)"), ("follow", 1.0, "[0, 1)"), ("follow", "x", "[0, 1)"),
    ("length", 0.0, "(0, 1]"), ("length", 1.2, "(0, 1]"),
    ("fade", 0.5, "[0.7, 1]"), ("fade", 1.1, "[0.7, 1]"),
])
def test_options_out_of_range_are_refused_with_field_and_fix(key, value, words):
    with pytest.raises(SceneError) as err:
        sc.Scene.from_dict(stagger_scene({"lateral": 0.7, key: value}))
    assert err.value.field == f"flows.headway.{key}"
    assert words in err.value.fix


def test_the_options_are_csm_parameters_only():
    with pytest.raises(SceneError) as err:
        sc.Scene.from_dict(stagger_scene({"law": "lanes", "follow": 0.5}))
    assert err.value.field == "flows.headway.follow"


def test_neutral_values_are_the_law_as_it_was_bit_for_bit():
    rng = np.random.default_rng(11)
    q = rng.uniform(0.0, 4.0, (60, 2))
    u = rng.normal(0.0, 1.0, (60, 2))
    r = np.full(60, 0.2)
    for k in (0.7, 1.0):
        plain = csm(q, r, u, 1.1, 2.0, 0.1, k)
        assert np.array_equal(plain, csm(q, r, u, 1.1, 2.0, 0.1, k, k, 1.0, 0.0))
        assert not np.array_equal(plain, csm(q, r, u, 1.1, 2.0, 0.1, k, k, 1.0, 0.5))
    spec = sc.Scene.from_dict(stagger_scene({"lateral": 0.6})).flows.spec["headway"]
    assert (spec["fade"], spec["length"], spec["follow"]) == (0.6, 1.0, DEFAULT_FOLLOW)


def _file(n: int, spacing: float, v0: float = 1.3) -> tuple[np.ndarray, np.ndarray]:
    q = np.column_stack([spacing * np.arange(n), np.zeros(n)])
    return q, np.tile([v0, 0.0], (n, 1))


@pytest.mark.parametrize("beta", [0.0, 0.3, 0.5, 0.9])
@pytest.mark.parametrize("spacing", [0.45, 0.7, 1.2])
def test_single_file_moves_at_the_gap_speed_plus_beta_of_the_leaders(beta, spacing):
    # agents along +x, equal gaps s = spacing - 0.4; the front one has nobody ahead (v0); the
    # second follows it (s/T + beta v0), every other one a leader at s/T: (1 + beta) s/T
    T, v0, n = 1.6, 1.3, 7
    q, u = _file(n, spacing, v0)
    v = csm(q, np.full(n, 0.2), u, T, 0.0, 0.1, 1.0, -1.0, 1.0, beta)[:, 0]
    s = spacing - 0.4
    assert v[-1] == v0
    assert v[-2] == pytest.approx(min(v0, s / T + beta * v0), rel=1e-12)
    assert v[:-2] == pytest.approx(np.full(n - 2, min(v0, (1.0 + beta) * s / T)), rel=1e-12)
    # the flow of a uniform file is that of the published law with time gap T / (1 + beta)
    ref = csm(q, np.full(n, 0.2), u, T / (1.0 + beta), 0.0, 0.1)[:-2, 0]
    assert v[:-2] == pytest.approx(ref, rel=1e-12)


def test_a_leader_coming_towards_the_agent_or_standing_adds_nothing():
    q = np.array([[0.0, 0.0], [1.0, 0.0]])
    for uj in ([-1.0, 0.0], [0.0, 0.0], [0.0, 1.0]):
        u = np.array([[1.3, 0.0], uj])
        v = csm(q, np.full(2, 0.2), u, 1.6, 0.0, 0.1, 1.0, -1.0, 1.0, 0.8)
        assert v[0, 0] == pytest.approx(0.6 / 1.6, rel=1e-12)


@pytest.mark.parametrize("f", [0.5, 0.75, 1.0])
def test_the_body_length_fraction_sets_the_gap(f):
    q = np.array([[0.0, 0.0], [0.7, 0.0]])
    u = np.array([[1.3, 0.0], [0.0, 0.0]])
    v = csm(q, np.full(2, 0.2), u, 1.1, 0.0, 0.1, 1.0, -1.0, f)
    assert v[0, 0] == pytest.approx(min(1.3, (0.7 - f * 0.4) / 1.1), rel=1e-12)


@pytest.mark.parametrize("offset", [0.1, 0.28, 0.3, 0.32, 0.35, 0.355, 0.37, 0.39])
def test_a_fade_divides_the_gap_by_the_cosine_weight_between_k_and_k2(offset):
    k, k2, T = 0.7, 0.9, 0.5
    q = np.array([[0.0, 0.0], [1.0, offset]])
    u = np.array([[1.2, 0.0], [0.0, 0.0]])
    v = csm(q, np.full(2, 0.2), u, T, 0.0, 0.1, k, k2)[0, 0]
    gap = math.hypot(1.0, offset) - 0.4
    if offset <= k * 0.4:
        want = min(1.2, gap / T)
    elif offset >= k2 * 0.4:
        want = 1.2
    else:
        w = 0.5 * (1.0 + math.cos(math.pi * (offset - k * 0.4) / ((k2 - k) * 0.4)))
        want = min(1.2, gap / w / T)
    assert v == pytest.approx(want, rel=1e-12)


def test_a_recording_made_before_the_options_existed_replays_identically(tmp_path):
    f = tmp_path / "old.mcap"
    # run as the law ran before the options existed (follow 0), recorded without them
    record_headway(f, {"time_gap": 0.8, "lateral": 0.7, "follow": 0.0}, NEW)
    assert not any(key in load_run(f).raw["scene"] for key in NEW)
    law = load_run(f).scene.flows
    assert (law.follow, law.length, law.fade, law.lateral) == (0.0, 1.0, 0.7, 0.7)
    res = replay.replay(f)
    assert res.identical and res.steps_simulated == 40


def test_a_run_with_the_options_replays_identically(tmp_path):
    f = tmp_path / "new.mcap"
    record_headway(f, {"time_gap": 1.6, "lateral": 0.7, "fade": 0.8, "length": 0.9,
                "follow": 0.5}, ())
    assert load_run(f).scene.flows.follow == 0.5
    res = replay.replay(f)
    assert res.identical and res.steps_simulated == 40
