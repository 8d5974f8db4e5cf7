"""The gallery's check against the experiments (``sweep verify --tests gallery``): its flow,
its windowed speed and its verdict, on trajectories whose answers are known exactly."""
import math

import numpy as np
import pytest

from sweep_core.analysis.pedpy_export import Trajectories
from sweep_core.verify import TESTS
from sweep_core.verify import gallery as g
from sweep_core.verify.base import Trace
from sweep_core.verify.diagrams import line_flow_at

RATE = 10.0  # frames per second


def crossing_trace(times: np.ndarray, seed: int = 0, speed: float = 1.25) -> Trace:
    """Agents walking east at ``speed`` m/s along y = 5 m, agent k at x = 10 m (room_door's
    door line) at times[k] s, recorded at RATE frames per second over 0-40 s."""
    frames = np.arange(int(40 * RATE) + 1)
    rows = []
    for f in frames:
        t = f / RATE
        x = 10.0 + speed * (t - np.asarray(times))
        rows.append((int(f), np.arange(len(times)), np.stack([x, np.full(len(x), 5.0)], 1)))
    return Trace("headway/room_door", seed, Trajectories.from_frames(rows, RATE))


def test_flow_counts_from_the_tenth_crossing_to_the_last() -> None:
    t = np.arange(50) / 2.0                    # 2 per second, first at 0 s
    assert g.flow(t) == pytest.approx(2.0, rel=1e-12)   # (50 - 10) / (24.5 - 4.5)
    early = np.concatenate([[0.0, 0.01, 0.02], 5.0 + np.arange(47) / 2.0])
    assert g.flow(early) == pytest.approx(2.0, rel=1e-12)   # a burst before it is not counted
    assert math.isnan(g.flow(t[:11]))


def test_windowed_speed_is_the_displacement_over_the_window() -> None:
    """The gallery test measures speed as sweep analyze does: over a window centred on each
    frame, one-sided at the ends of an agent's presence."""
    tr = crossing_trace(np.array([3.0, 4.0]), speed=1.25)
    v = g.windowed_speeds(tr, 1.0)
    # every frame of each agent has a window (one-sided at its first and last frames)
    assert len(v) == 2 * 401
    assert np.allclose(v, 1.25, rtol=1e-12)
    # an agent seen in spells: its speed is still the displacement over elapsed time
    keep = ~((tr.traj.ids == 0) & (tr.traj.frames % 20 >= 10))
    gappy = Trace(tr.case, 0, Trajectories(tr.traj.ids[keep], tr.traj.frames[keep],
                                           tr.traj.xy[keep], RATE))
    v = g.windowed_speeds(gappy, 1.0)
    assert np.allclose(v, 1.25, rtol=1e-12) and 401 < len(v) <= int(keep.sum())


def test_crossings_are_where_the_agents_cross_the_line() -> None:
    times = 2.0 + np.arange(30) / 2.2
    got = g.crossing_times(crossing_trace(times), g.LINES["room_door"][0])
    assert len(got) == 30
    # PedPy counts the first frame past the line: within one frame after the crossing
    assert np.all(got >= np.sort(times) - 1e-9) and np.all(got <= np.sort(times) + 1 / RATE)


def test_each_failing_condition_is_named() -> None:
    ref = line_flow_at(1.2)
    assert g.failures("room_door", ref * 1.1, 1.0, 40.0) == []
    high = g.failures("room_door", ref * 1.2, 1.0, 40.0)
    assert len(high) == 1 and "+20 %" in high[0] and f"{ref:.2f}" in high[0]
    low = g.failures("room_door", ref * 0.8, 1.0, 40.0)
    assert len(low) == 1 and "-20 %" in low[0]
    none = g.failures("room_door", math.nan, 1.0, 40.0)
    assert len(none) == 1 and "fewer than 12 crossings" in none[0]
    fast = g.failures("room_door", ref, 1.7, 40.0)
    assert len(fast) == 1 and "median speed 1.70 m/s" in fast[0]


def test_the_verdict_judges_each_seed_and_says_why() -> None:
    good = line_flow_at(1.2)
    bad = 1.3 * good
    traces = {"headway/room_door": [crossing_trace(2.0 + np.arange(60) / good, seed=3),
                                    crossing_trace(2.0 + np.arange(60) / bad, seed=4)]}
    verdict = g._judge(traces, False)
    assert verdict.passed == [True, False]
    assert verdict.values[0] < 0.05 and verdict.values[1] > g.TARGET
    assert "seed 4: room_door: flow" in verdict.notes and "seed 3:" not in verdict.notes
    assert TESTS["gallery"] is g.TEST_GALLERY and g.TEST_GALLERY.slow


def test_the_verdict_says_how_long_the_runs_were() -> None:
    """--quick runs the gallery for 25 s instead of 40 s: the verdict says which, and the
    measured quantity names both (it used to say 40 s for the quick runs too)."""
    good = line_flow_at(1.2)
    traces = {"headway/room_door": [crossing_trace(2.0 + np.arange(60) / good, seed=3)]}
    assert g._judge(traces, True).notes.startswith(f"runs of {g.QUICK_T_END:g} s: ")
    assert g._judge(traces, False).notes.startswith(f"runs of {g.T_END:g} s: ")
    assert f"in a {g.T_END:g} s run, {g.QUICK_T_END:g} s with --quick" in g.TEST_GALLERY.measures
