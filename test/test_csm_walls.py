"""The csm law's wall term (``flows.headway.wall_repulsion`` a_w, ``wall_range`` D_w): refused
on bad values with field and fix; the term is a_w exp(-g / D_w) along the wall's normal, added
to the direction rule's sum exactly; a_w = 0 (the default) is the law without it, bit for bit;
a run with it replays bit for bit."""
from __future__ import annotations

import math

import numpy as np
import pytest
from test_csm_lateral import record_headway, stagger_scene

import sweep_core as sc
from sweep_core.analysis import replay
from sweep_core.errors import SceneError
from sweep_core.model.geometry import single_rows
from sweep_core.model.speed_law import DEFAULT_WALL_RANGE, DEFAULT_WALL_REPULSION
from sweep_core.numerics.csm import CUT, csm, wall_terms


def along_wall(headway: dict, gap: float = 0.01) -> dict:
    """Three agents in a file beside the wall y = 0 (their disks `gap` m from it), walking
    along +x, no noise."""
    pts = [[0.5 + 0.6 * k, 0.2 + gap] for k in range(3)]
    return {"name": "along_wall", "agents": {"positions": pts, "radius": 0.2},
            "walls": [{"kind": "halfplane", "normal": [0, 1], "offset": 0.0}],
            "drift": {"kind": "uniform", "velocity": [1.2, 0.0]},
            "flows": {"headway": headway}}


@pytest.mark.parametrize("key,value", [("wall_repulsion", -1.0), ("wall_repulsion", "strong"),
                                       ("wall_repulsion", float("nan")), ("wall_range", 0.0),
                                       ("wall_range", -0.02)])
def test_bad_wall_parameters_are_refused_with_field_and_fix(key, value):
    with pytest.raises(SceneError) as err:
        sc.Scene.from_dict(along_wall({key: value}))
    assert err.value.field == f"flows.headway.{key}"
    assert err.value.fix


def test_the_wall_term_is_not_a_parameter_of_the_lanes_law():
    with pytest.raises(SceneError) as err:
        sc.Scene.from_dict(along_wall({"law": "lanes", "wall_repulsion": 5}))
    assert err.value.field == "flows.headway.wall_repulsion"


def test_the_defaults_fill_the_spec():
    hw = sc.Scene.from_dict(along_wall({})).flows.spec["headway"]
    assert hw["wall_repulsion"] == DEFAULT_WALL_REPULSION == 0.0
    assert hw["wall_range"] == DEFAULT_WALL_RANGE


@pytest.mark.parametrize("gap", [0.0, 0.01, 0.05])
@pytest.mark.parametrize("a_w,d_w", [(5.0, 0.02), (1.0, 0.1)])
def test_the_wall_term_turns_a_lone_agent_exactly_as_the_formula(gap, a_w, d_w):
    scene = sc.Scene.from_dict(along_wall({}, gap))
    q, r = scene.positions[:1], scene.radius[:1]
    rows = single_rows(scene.geometry, 0.0, q, r, CUT * d_w)
    w = wall_terms(rows, 1, a_w, d_w)
    push = a_w * math.exp(-gap / d_w)
    assert w[0, 0] == 0.0 and w[0, 1] == pytest.approx(push, rel=1e-12)
    # one agent, no neighbour: the speed is its wished 1.2 m/s along (e0 + term) / |...|
    out = csm(q, r, np.array([[1.2, 0.0]]), 2.1, 2.0, 0.1, walls=w)
    norm = math.hypot(1.0, push)
    assert out[0] == pytest.approx([1.2 / norm, 1.2 * push / norm], rel=1e-12)


def test_a_wall_beyond_the_cut_adds_nothing():
    scene = sc.Scene.from_dict(along_wall({}, 0.5))
    q, r = scene.positions, scene.radius
    assert not wall_terms(single_rows(scene.geometry, 0.0, q, r, CUT * 0.02), 3, 5.0, 0.02).any()


def positions(headway: dict, steps: int = 20) -> np.ndarray:
    sim = sc.Simulator(sc.Scene.from_dict(along_wall(headway)), dt=0.05, seed=2)
    for _ in range(steps):
        sim.step()
    return sim.positions


def test_no_wall_term_is_the_law_without_it_bit_for_bit_and_the_term_moves_off_the_wall():
    plain = positions({})
    assert np.array_equal(plain, positions({"wall_repulsion": 0.0, "wall_range": 0.5}))
    y0 = 0.2 + 0.01
    assert np.all(plain[:, 1] == y0)  # nothing turns a file walking along the wall
    pushed = positions({"wall_repulsion": 5.0})
    assert np.all(pushed[:, 1] > y0 + 1e-3)  # turned away from the wall
    assert np.all(pushed[:, 0] > 0.5)


def test_a_run_with_the_wall_term_replays_identically(tmp_path):
    f = tmp_path / "walls.mcap"
    scene = stagger_scene({"time_gap": 0.8, "wall_repulsion": 5.0, "wall_range": 0.4})
    assert sc.Scene.from_dict(scene).flows.wall_repulsion == 5.0
    record_headway(f, {"time_gap": 0.8, "wall_repulsion": 5.0, "wall_range": 0.4}, ())
    res = replay.replay(f)
    assert res.identical and res.steps_simulated == 40
