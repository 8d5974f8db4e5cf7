"""``flows.exit_choice``: refused on bad input with field and fix; the assignment's rule
(nearest agents first, each to the exit of least walk + queue / capacity) on exact cases; in
a hall the nearer exit is preferred and the other one used, and a run is the same bit for bit
when run again (what `sweep replay` relies on)."""
from __future__ import annotations

import numpy as np
import pytest

from sweep_core import Scene, Simulator
from sweep_core.errors import SceneError
from sweep_core.numerics.exit_choice import assign

EXIT_1 = {"region": {"kind": "rectangle", "min": [4.0, 6.2], "max": [5.0, 7.0]}}
EXIT_2 = {"region": {"kind": "rectangle", "min": [9.0, 6.2], "max": [10.0, 7.0]}}


def hall(choice, n=24, groups=None):
    """A 10 m x 6 m hall, two 1 m doors in its north wall (x 4-5 m and 9-10 m), n people
    in its west part."""
    spec = {
        "agents": {"spawn": {"region": {"kind": "rectangle", "min": [0.5, 0.5],
                                        "max": [5.0, 5.5]}, "count": n, "radius": 0.2,
                             "seed": 0}, "speed": 1.3},
        "walls": [{"kind": "polyline", "points": [[4.0, 6.0], [0.0, 6.0], [0.0, 0.0],
                                                  [10.5, 0.0], [10.5, 6.0], [10.0, 6.0]]},
                  {"kind": "segment", "a": [5.0, 6.0], "b": [9.0, 6.0]}],
        "drift": {"kind": "geodesic", "region": EXIT_1["region"], "speed": 1.3},
        "noise": {"sigma": 0.05},
        "flows": {"sinks": [{"kind": "rectangle", "min": [4.0, 6.0], "max": [5.0, 7.0]},
                            {"kind": "rectangle", "min": [9.0, 6.0], "max": [10.0, 7.0]}]},
    }
    if groups:
        spec["agents"]["groups"] = groups
    if choice is not None:
        spec["flows"]["exit_choice"] = choice
    return spec


@pytest.mark.parametrize("choice, field", [
    ([{"exits": [EXIT_1]}], "flows.exit_choice[0].exits"),
    ([{"exits": EXIT_1}], "flows.exit_choice[0].exits"),
    ([{"exits": [EXIT_1, EXIT_2], "capacity": 0}], "flows.exit_choice[0].capacity"),
    ([{"exits": [EXIT_1, EXIT_2], "capacity": [1.0]}], "flows.exit_choice[0].capacity"),
    ([{"exits": [EXIT_1, {**EXIT_2, "goal": [9.5, 6.5]}]}], "flows.exit_choice[0].exits[1]"),
    ([{"exits": [EXIT_1, EXIT_2], "group": "nobody"}], "flows.exit_choice[0].group"),
    ([{"exits": [EXIT_1, EXIT_2]}, {"exits": [EXIT_2, EXIT_1]}], "flows.exit_choice[1].group"),
    ([{"exits": [EXIT_1, EXIT_2], "speed": 2}], "flows.exit_choice[0]"),
    ({"exits": [EXIT_1, EXIT_2]}, "flows.exit_choice"),
])
def test_bad_exit_choices_are_refused_with_field_and_fix(choice, field):
    with pytest.raises(SceneError) as err:
        Scene.from_dict(hall(choice))
    assert err.value.field == field
    assert err.value.problem and err.value.fix


def test_a_group_with_a_journey_cannot_also_choose_exits():
    spec = hall([{"exits": [EXIT_1, EXIT_2]}])
    spec["flows"]["journeys"] = [{"legs": [{"goal": [2.0, 2.0]}]}]
    with pytest.raises(SceneError) as err:
        Scene.from_dict(spec)
    assert err.value.field == "flows.exit_choice[0].group"


def test_the_nearest_agents_choose_first_and_the_queue_turns_the_others():
    walk = np.array([[1.0, 3.0], [2.0, 4.0], [3.0, 5.0]])
    # without queues worth the name everyone takes the nearer exit 0
    assert assign(walk, np.array([1e9, 1e9])).tolist() == [0, 0, 0]
    # capacity 1/s: agent 1 waits 1 s (3 < 4), agent 2 waits 2 s (5 = 5: the lower index)
    assert assign(walk, np.array([1.0, 1.0])).tolist() == [0, 0, 0]
    # capacity 0.5/s: agent 1 ties (4 = 4), agent 2 would wait 4 s (7 > 5): exit 1
    assert assign(walk, np.array([0.5, 0.5])).tolist() == [0, 0, 1]
    # the order is by least walking time, not by row
    assert assign(walk[::-1].copy(), np.array([0.5, 0.5])).tolist() == [1, 0, 0]
    # an exit nobody can reach (inf) is never chosen
    assert assign(np.array([[np.inf, 2.0], [np.inf, 1.0]]), np.ones(2)).tolist() == [1, 1]


def _out_by_exit(spec, seed=0, t_end=40.0):
    sim = Simulator(Scene.from_dict(spec), dt=0.05, seed=seed)
    last = {}

    def keep(s):
        last.update({int(i): float(x) for i, (x, _) in zip(s.ids, s.positions)})

    sim.run(t_end, callback=keep)
    pop = sim.flows
    one = sum(1 for i in pop.left_at if last[i] < 7.0)
    return one, len(pop.left_at) - one, sim


def test_the_nearer_exit_is_preferred_and_the_other_used():
    spec = hall([{"exits": [EXIT_1, EXIT_2], "capacity": 1.2}])
    one, two, sim = _out_by_exit(spec)
    assert one + two == 24  # everyone out
    assert one > two > 0
    # without the choice (the geodesic drift to exit 1) nobody takes exit 2
    plain_one, plain_two, _ = _out_by_exit(hall(None))
    assert plain_two == 0 and plain_one > 0


def test_a_run_with_an_exit_choice_is_the_same_bit_for_bit_when_run_again():
    spec = hall([{"exits": [EXIT_1, EXIT_2], "capacity": 1.2}], n=12)
    a = Simulator(Scene.from_dict(spec), dt=0.05, seed=4)
    b = Simulator(Scene.from_dict(spec), dt=0.05, seed=4)
    a.run(6.0)
    b.run(6.0)
    assert np.array_equal(a.ids, b.ids) and np.array_equal(a.positions, b.positions)
