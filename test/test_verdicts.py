"""Every FAIL of ``sweep verify`` names, per seed, the condition that failed (agents that did
not leave in time with their count, a run error and its message, a value outside the
criterion), and a run's outcome depends on its case and seed, never on a clock."""
from __future__ import annotations

import time

import numpy as np

from sweep_core.analysis.pedpy_export import Trajectories
from sweep_core.verify import TESTS
from sweep_core.verify.base import Case, Trace, Verdict, simulate
from sweep_core.verify.rooms import EXIT_1, EXIT_2
from sweep_core.verify.runner import judge, line


def _hall(seed: int, by_one: int, by_two: int, n0: int, error: str = "") -> Trace:
    """A trace of test 11's hall: ``by_one`` people left by exit 1, ``by_two`` by exit 2."""
    tr = Trace("hall", seed, Trajectories.from_frames([], 5.0), n0=n0, t_end=900.0,
               t_limit=900.0, error=error)
    centre = [np.mean(EXIT_1, axis=0), np.mean(EXIT_2, axis=0)]
    for i in range(by_one + by_two):
        x, y = centre[0] if i < by_one else centre[1]
        tr.left_xy[i] = (float(x), float(y))
        tr.left_at[i] = 10.0 + i
    return tr


def test_a_fail_whose_values_meet_the_criterion_names_the_condition():
    """The reported case: every seed's share > 0.5 and exit 2 used, yet FAIL: before, the line
    showed only those values; now it names the seeds and what failed."""
    test = TESTS["rimea11"]
    traces = {"hall": [_hall(0, 600, 400, 1000), _hall(1, 590, 398, 1000),
                       _hall(2, 500, 300, 1000, error="InfeasibleError: no feasible step")]}
    verdict = judge(test, traces, [0, 1, 2], quick=False)
    text = line(test, verdict, [0, 1, 2])
    assert verdict.status == "FAIL" and verdict.passed == [True, False, False]
    assert "seed 0:" not in text
    assert "seed 1: 12 of 1000 agents had not left when case hall ended at t = 900 s (its " \
           "limit 900 s of simulated time)" in text, text
    assert "seed 2: " in text and "run error in case hall: InfeasibleError: no feasible " \
           "step" in text, text
    assert text.count("run error") == 1, text


def test_a_value_outside_the_criterion_is_named_with_its_value():
    traces = {"hall": [_hall(4, 300, 700, 1000), _hall(5, 1000, 0, 1000)]}
    verdict = judge(TESTS["rimea11"], traces, [4, 5], quick=False)
    text = line(TESTS["rimea11"], verdict, [4, 5])
    assert "seed 4: share by exit 1 0.300, not > 0.5" in text, text
    assert "seed 5: exit 2 unused" in text, text


def test_a_judge_that_raises_fails_every_seed_with_its_error():
    broken = TESTS["rimea1"].__class__(**{**TESTS["rimea1"].__dict__,
                                         "judge": lambda traces, quick: 1 / 0})
    traces = {"corridor": [_hall(0, 1, 0, 1), _hall(1, 1, 0, 1)]}
    verdict = judge(broken, traces, [0, 1], quick=True)
    assert verdict.passed == [False, False]
    assert verdict.failures([0, 1]).count("the measurement failed: ZeroDivisionError") == 2


def test_verdict_builder():
    v = Verdict.judged([1.0, 2.0], [[(True, "a")], [(False, "b"), (True, "c"), (False, "d")]])
    assert v.passed == [True, False] and v.reasons == ["", "b; d"]
    assert v.failures([7, 8]) == "seed 8: b; d"
    v.fail(0, "e")
    assert v.status == "FAIL" and v.failures([7, 8]) == "seed 7: e | seed 8: b; d"


def test_a_run_does_not_depend_on_the_clock(monkeypatch):
    """simulate with a clock that jumps an hour at every reading (a machine under any load)
    gives the same trace as with the real clock: no limit in wall time decides a run."""
    case = Case("corridor", "rimea01_corridor", 3.0, record_every=2)
    plain = simulate(case, 0)
    hour = iter(range(0, 10 ** 9, 3600))
    for name in ("perf_counter", "monotonic", "time"):
        monkeypatch.setattr(time, name, lambda: float(next(hour)))
    slow = simulate(case, 0)
    assert slow.wall_s >= 3600  # the jumping clock was read
    assert not plain.error and not slow.error
    assert slow.t_end == plain.t_end == 3.0
    assert np.array_equal(slow.traj.xy, plain.traj.xy) and slow.left_at == plain.left_at
