"""RiMEA test 9's halls: their people walk with the default speed law (without it the disks
pushing at a 1 m door form arches that never break, and the hall is never emptied), and a run
that does not empty the hall is reported with who is still inside and when the last one left,
not as a bare missing value."""
from __future__ import annotations

import math

from sweep_core.analysis.pedpy_export import Trajectories
from sweep_core.model.scene import Scene
from sweep_core.model.speed_law import DEFAULT_TIME_GAP
from sweep_core.verify.base import Trace
from sweep_core.verify.crowds import TEST_9, evacuation_time


def test_the_halls_of_test_9_walk_with_the_default_speed_law():
    for case in TEST_9.cases(True):
        scene = Scene.from_dict(case.spec(0), name=case.scene)
        assert scene.flows is not None
        assert scene.flows.law == "csm" and scene.flows.time_gap == DEFAULT_TIME_GAP


def _trace(label: str, seed: int, left: int, n0: int, t_end: float, last: float) -> Trace:
    tr = Trace(label, seed, Trajectories.from_frames([], 5.0), n0=n0, t_end=t_end)
    tr.left_at = {i: last * (i + 1) / left for i in range(left)}
    return tr


def test_a_hall_not_emptied_says_who_is_inside_and_when_the_last_left():
    traces = {"four": [_trace("four", 1, 1000, 1000, 52.0, 51.9)],
              "two": [_trace("two", 1, 241, 1000, 600.0, 20.0)]}
    verdict = TEST_9.judge(traces, False)
    assert math.isnan(evacuation_time(traces["two"][0]))
    assert verdict.status == "FAIL"
    assert "2 doors, seed 1: 759 of 1000 still inside at 600 s, the last one out at 20.0 s" \
        in verdict.notes
    assert "4 doors, seed 1" not in verdict.notes
