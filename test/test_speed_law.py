"""The collision-free speed model's law (``flows.headway``, law csm, numerics/csm.py): its
parameters refused on bad input, and the properties it is built on: the speed is the gap to
the nearest agent ahead in the corridor over the time gap, never above the wished speed,
non-decreasing in that gap; the direction rule turns agents apart symmetrically and leaves a
lone agent alone; a ``margin`` without a law is the lanes law (scenes and recordings that
give it keep their meaning)."""
from __future__ import annotations

import numpy as np
import pytest

from sweep_core import Scene, Simulator
from sweep_core.errors import SceneError
from sweep_core.model.ring import ring_corridor
from sweep_core.numerics.csm import csm, directions, gaps_ahead
from sweep_core.numerics.headway import headway

R = np.full(2, 0.2)


def _ring(headway_spec):
    spec = ring_corridor(1.0)
    spec["flows"] = {"headway": headway_spec}
    return spec


@pytest.mark.parametrize("spec, field", [
    ({"law": "social_force"}, "flows.headway.law"),
    ({"law": "csm", "margin": 0.3}, "flows.headway.margin"),
    ({"law": "lanes", "repulsion": 1.0}, "flows.headway.repulsion"),
    ({"repulsion": -1.0}, "flows.headway.repulsion"),
    ({"repulsion_range": 0.0}, "flows.headway.repulsion_range"),
    ({"repulsion_range": "far"}, "flows.headway.repulsion_range"),
    ({"time_gap": -0.5}, "flows.headway.time_gap"),
])
def test_bad_speed_law_parameters_are_refused_with_field_and_fix(spec, field):
    with pytest.raises(SceneError) as err:
        Scene.from_dict(_ring(spec))
    assert err.value.field == field
    assert err.value.problem and err.value.fix


def test_the_default_law_is_csm_and_a_margin_alone_keeps_the_lanes_law():
    assert Scene.from_dict(_ring({})).flows.spec["headway"]["law"] == "csm"
    old = Scene.from_dict(_ring({"time_gap": 0.35, "margin": 0.3}))
    assert old.flows.law == "lanes"
    assert old.flows.spec["headway"] == {"law": "lanes", "time_gap": 0.35, "margin": 0.3}
    # the lanes law is what the population applies to such a scene's wished velocities
    sim = Simulator(old, dt=0.05, seed=3)
    pop, q, base = sim.flows, sim.positions, old.drift
    assert np.array_equal(pop.wished(0.0, q, base),
                          headway(q, pop.radius[pop.ids], base(0.0, q), 0.35, 0.3))


@pytest.mark.parametrize("gap", [0.0, 0.05, 0.3, 0.8, 2.0])
def test_speed_is_the_gap_ahead_over_the_time_gap_capped_by_the_wished_speed(gap):
    # two agents on a line, both wishing 1.2 m/s along +x, no repulsion
    q = np.array([[0.0, 0.0], [0.4 + gap, 0.0]])
    u = np.array([[1.2, 0.0], [1.2, 0.0]])
    out = csm(q, R, u, 0.5, 0.0, 0.1)
    assert out[0, 0] == pytest.approx(min(1.2, gap / 0.5), abs=1e-12)
    assert out[0, 1] == 0.0
    assert np.array_equal(out[1], u[1])  # nobody ahead of the front agent


def test_speed_is_non_decreasing_in_the_gap_and_never_above_the_wished_speed():
    rng = np.random.default_rng(7)
    gaps = np.linspace(0.0, 3.0, 61)
    v = [csm(np.array([[0.0, 0.0], [0.4 + g, 0.05]]), R, np.array([[1.3, 0.0], [0.0, 0.0]]),
             0.8, 0.0, 0.1)[0, 0] for g in gaps]
    assert np.all(np.diff(v) >= 0.0) and v[-1] == pytest.approx(1.3)
    assert v[0] == pytest.approx((np.hypot(0.4, 0.05) - 0.4) / 0.8, abs=1e-12)
    # a random crowd with repulsion: no agent is faster than it wishes
    q = rng.uniform(0.0, 6.0, (80, 2))
    u = rng.normal(0.0, 1.0, (80, 2))
    out = csm(q, np.full(80, 0.15), u, 1.0, 5.0, 0.1)
    assert np.all(np.hypot(*out.T) <= np.hypot(*u.T) * (1.0 + 1e-12))


def test_only_agents_ahead_within_the_corridor_slow_an_agent():
    e = np.array([[1.0, 0.0], [0.0, 0.0]])
    pi, pj = np.array([0]), np.array([1])
    # ahead, centre 0.39 m off the line of motion (within l = 0.4): counts with d - l
    s = gaps_ahead(np.array([[0.0, 0.0], [1.0, 0.39]]), R, e, pi, pj)
    assert s[0] == pytest.approx(np.hypot(1.0, 0.39) - 0.4)
    # 0.41 m off the line, or behind: does not count
    assert gaps_ahead(np.array([[0.0, 0.0], [1.0, 0.41]]), R, e, pi, pj)[0] == np.inf
    assert gaps_ahead(np.array([[0.0, 0.0], [-1.0, 0.0]]), R, e, pi, pj)[0] == np.inf


def test_the_direction_rule_turns_two_agents_apart_symmetrically():
    q = np.array([[0.0, -0.25], [0.0, 0.25]])
    u = np.array([[1.0, 0.0], [1.0, 0.0]])
    pi, pj = np.array([0]), np.array([1])
    none = np.zeros((0, 2))  # no wall terms
    e = directions(q, R, u, pi, pj, 5.0, 0.1, none)
    push = 5.0 * np.exp((0.4 - 0.5) / 0.1)
    want = np.array([1.0, push]) / np.hypot(1.0, push)
    assert e[1] == pytest.approx(want, abs=1e-12)
    assert e[0] == pytest.approx(want * [1.0, -1.0], abs=1e-12)
    # no repulsion, or a lone agent: the wished direction
    assert np.array_equal(directions(q, R, u, pi, pj, 0.0, 0.1, none), u)
    lone = csm(q[:1], R[:1], u[:1], 1.0, 5.0, 0.1)
    assert np.array_equal(lone, u[:1])


def test_the_law_slows_a_dense_ring_and_without_it_the_step_is_the_pure_model():
    from sweep_core.model.ring import tangential_speed

    def speed(spec):
        sim = Simulator(Scene.from_dict(spec), dt=0.05, seed=1)
        sim.run(3.0)
        return float(tangential_speed(sim.positions, sim.velocities).mean())

    dense = ring_corridor(2.5, seed=1)
    law = dict(dense, flows={"headway": {}})
    # free speed 1.34 m/s: the pure model keeps it, the law slows the crowd (the gaps at
    # 2.5 per m^2 are below 0.6 m, so T = 1 s allows at most 0.6 m/s to most agents)
    assert speed(dense) > 1.2 and speed(law) < 0.9


def test_the_laws_velocities_do_not_depend_on_the_room_its_search_makes_first():
    """The compiled call searches the pairs with room for a hint first and again with room
    for all when more are found: a room of one pair or of thousands gives the same bits as
    the pairs and rules called one by one."""
    from sweep_core.model.neighbours import pairs_within
    from sweep_core.numerics.csm import CUT, law, searched_law

    rng = np.random.default_rng(4)
    q = rng.uniform(0.0, 6.0, (60, 2))
    r = np.full(60, 0.2)
    u = rng.normal(0.0, 1.0, (60, 2))
    walls = np.zeros((0, 2))
    args = (1.0, 2.0, 0.1, walls, 0.7, 0.9, 0.9, 0.5)
    top = float(np.sqrt(np.max(np.einsum("ij,ij->i", u, u))))
    pi, pj = pairs_within(q, 0.4 + max(top * 1.0, CUT * 0.1))
    want = law(q, r, u, pi, pj, 2.0, 0.1, walls, 0.7, 0.9, 0.9, 1.0, 0.5)
    for room in (1, 4 * 60, 100_000):
        v, found = searched_law(q, r, u, *args, room)
        assert found == len(pi) > 4 * 60
        assert v.tobytes() == want.tobytes()
    still, none = searched_law(q, r, np.zeros((60, 2)), *args, 1)
    assert none == 0 and not still.any()
