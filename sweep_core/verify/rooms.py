"""RiMEA tests 1 (walking speed in a corridor), 6 (round a corner), 10 (assigned exits),
11 (choice of exit) and 12 (bottleneck between two rooms): their runs, verdicts and figures.

Geometries and criteria: the RiMEA guideline 3.0 (tests 1, 6, 10, 11, 12) as JuPedSim's
RiMEA system tests read them (the corner test's forbidden square, test 10's assignment of
rooms to exits, test 12's flows at the corridor and at the exit); docs/validation.md cites
them.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from sweep_core.analysis.pedpy_export import classic_density, line_flow, rectangle
from sweep_core.verify.base import Case, Test, Trace, Verdict, all_left, ran
from sweep_core.verify.figures import figure, save, walls

# -- test 1 -------------------------------------------------------------------------------------


def _cases_1(quick: bool) -> list[Case]:
    return [Case("corridor", "rimea01_corridor", 40.0, record_every=2)]


def _judge_1(traces: dict[str, list[Trace]], quick: bool) -> Verdict:
    values, checks = [], []
    for tr in traces["corridor"]:
        t = tr.left_at.get(0, math.nan) if not tr.error else math.nan
        values.append(t)
        checks.append([ran(tr), all_left(tr),
                       (0 not in tr.left_at or 26.0 <= t <= 34.0,
                        f"travel time {t:.4g} s outside 26-34 s")])
    return Verdict.judged(values, checks, " s")


TEST_1 = Test(
    "rimea1", "RiMEA 1 walking speed in a corridor",
    "travel time over 40 m of a 2 m corridor at 1.33 m/s", "26-34 s",
    _cases_1, _judge_1, source="RiMEA 3.0 test 1")

# -- test 6 -------------------------------------------------------------------------------------


def corner_inside(xy: np.ndarray) -> np.ndarray:
    """Whether centres (K, 2) lie in the corner's two corridors: [0, 12] x [0, 2] (the first)
    and [10, 12] x [0, 14] (the second, with its exit)."""
    x, y = xy[:, 0], xy[:, 1]
    first = (x >= 0) & (x <= 12) & (y >= 0) & (y <= 2)
    second = (x >= 10) & (x <= 12) & (y >= 0) & (y <= 14)
    return first | second


def _cases_6(quick: bool) -> list[Case]:
    return [Case("corner", "rimea06_corner", 60.0, stop_when_empty=True)]


def _judge_6(traces: dict[str, list[Trace]], quick: bool) -> Verdict:
    values, checks, out_all = [], [], []
    for tr in traces["corner"]:
        outside = set(tr.traj.ids[~corner_inside(tr.traj.xy)].tolist())
        for i, xy in tr.left_xy.items():  # the last centre before leaving counts too
            if not corner_inside(np.asarray([xy]))[0]:
                outside.add(i)
        done = len(tr.left_at)
        values.append(float(len(outside)))
        out_all.append(done)
        checks.append([ran(tr), (tr.n0 == 20, f"{tr.n0} people, not 20"), all_left(tr),
                       (not outside, f"{len(outside)} people left the corridors (ids "
                        f"{sorted(outside)[:6]})")])
    notes = f"left by the exit: {min(out_all)}-{max(out_all)} of 20"
    return Verdict.judged(values, checks, " outside the corridors", notes)


def _plot_6(traces: dict[str, list[Trace]], verdict: Verdict, folder: Path) -> list[Path]:
    tr = traces["corner"][0]
    fig, ax = figure(5.0, 5.5)
    walls(ax, {"walls": tr.walls})
    for i in np.unique(tr.traj.ids):
        _, xy = tr.positions(int(i))
        ax.plot(xy[:, 0], xy[:, 1], lw=0.7)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"RiMEA 6: 20 trajectories round the corner (seed {tr.seed})")
    return [save(fig, folder / "rimea6_corner_trajectories.png")]


TEST_6 = Test(
    "rimea6", "RiMEA 6 round a left corner",
    "people whose centre ever leaves the two 2 m corridors (20 people)",
    "0 outside, all 20 out by the exit", _cases_6, _judge_6, _plot_6,
    source="RiMEA 3.0 test 6; JuPedSim's forbidden square [0, 10] x [2, 12]")

# -- test 10 ------------------------------------------------------------------------------------

#: the exits: main (north, up the 1.2 m passage) and secondary (east end of the corridor),
#: as the regions agents leave by (m)
MAIN_EXIT = ((6.0, 11.0), (7.2, 12.0))
SECONDARY_EXIT = ((18.0, 5.0), (19.0, 6.0))


def _in_box(xy: tuple[float, float], box: tuple[tuple[float, float], tuple[float, float]],
            pad: float = 0.5) -> bool:
    (x0, y0), (x1, y1) = box
    return x0 - pad <= xy[0] <= x1 + pad and y0 - pad <= xy[1] <= y1 + pad


def _cases_10(quick: bool) -> list[Case]:
    return [Case("rooms", "rimea10_rooms", 60.0, stop_when_empty=True)]


def _assigned(n: int) -> list[str]:
    """The exit assigned to each of the scene's 23 agents (its groups)."""
    from sweep_core.model.yaml_files import load_yaml
    from sweep_core.verify.base import scene_text

    spec = load_yaml(scene_text("rimea10_rooms"))
    out = ["?"] * n
    for g in spec["agents"]["groups"]:
        for i in g["agents"]:
            out[int(i)] = g["name"]
    return out


def _judge_10(traces: dict[str, list[Trace]], quick: bool) -> Verdict:
    values, checks = [], []
    for tr in traces["rooms"]:
        want = _assigned(tr.n0)
        right = 0
        for i in range(tr.n0):
            xy = tr.left_xy.get(i)
            box = MAIN_EXIT if want[i] == "main" else SECONDARY_EXIT
            right += int(xy is not None and _in_box(xy, box))
        values.append(float(right))
        checks.append([ran(tr), (tr.n0 == 23, f"{tr.n0} people, not 23"), all_left(tr),
                       (right == tr.n0, f"{tr.n0 - right} of {tr.n0} did not leave by their "
                        "assigned exit")])
    return Verdict.judged(values, checks, " of 23")


TEST_10 = Test(
    "rimea10", "RiMEA 10 assigned exits",
    "people who left by their assigned exit (23 people in 12 rooms)", "all 23",
    _cases_10, _judge_10, source="RiMEA 3.0 test 10; JuPedSim's assignment of rooms")

# -- test 11 ------------------------------------------------------------------------------------

EXIT_1 = ((21.0, 20.0), (22.0, 21.0))
EXIT_2 = ((27.0, 20.0), (28.0, 21.0))


def _cases_11(quick: bool) -> list[Case]:
    n = 150 if quick else 1000
    return [Case("hall", "rimea11_exits", 120.0 if quick else 900.0,
                 (("agents.spawn.count", n),), stop_when_empty=True)]


def _judge_11(traces: dict[str, list[Trace]], quick: bool) -> Verdict:
    values, checks, second = [], [], []
    for tr in traces["hall"]:
        one = sum(_in_box(xy, EXIT_1) for xy in tr.left_xy.values())
        two = sum(_in_box(xy, EXIT_2) for xy in tr.left_xy.values())
        share = one / max(one + two, 1)
        values.append(share)
        second.append(two)
        elsewhere = len(tr.left_xy) - one - two
        checks.append([ran(tr), all_left(tr), (share > 0.5, f"share by exit 1 {share:.3f}, not "
                                               "> 0.5"),
                       (two > 0, "exit 2 unused"),
                       (elsewhere <= 0, f"{elsewhere} of {tr.n0} left by neither exit")])
    notes = (f"exit 2 used by {min(second)}-{max(second)} people (each person takes the exit "
             "of least estimated time, walk plus queue: flows.exit_choice)")
    return Verdict.judged(values, checks, "", notes)


def _plot_11(traces: dict[str, list[Trace]], verdict: Verdict, folder: Path) -> list[Path]:
    fig, ax = figure()
    for tr in traces["hall"]:
        for box, name in ((EXIT_1, "exit 1"), (EXIT_2, "exit 2")):
            t = sorted(tr.left_at[i] for i, xy in tr.left_xy.items() if _in_box(xy, box))
            if t:
                ax.step(t, np.arange(1, len(t) + 1), where="post",
                        label=f"{name}, seed {tr.seed}")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("people out")
    ax.set_title("RiMEA 11: people out by each exit")
    ax.legend(fontsize=7)
    return [save(fig, folder / "rimea11_exit_use.png")]


TEST_11 = Test(
    "rimea11", "RiMEA 11 choice of exit",
    "share of the crowd leaving by the nearer exit 1", "> 0.5, and exit 2 used",
    _cases_11, _judge_11, _plot_11, source="RiMEA 3.0 test 11", slow=True)

# -- test 12 ------------------------------------------------------------------------------------

#: the corridor's end (into room 2) and a line 1 m before the exit, as JuPedSim measures them
CORRIDOR_END = ((15.0, 4.5), (15.0, 5.5))
BEFORE_EXIT = ((24.0, 4.0), (24.0, 6.0))
#: the 2 m x 2 m measurement areas before the corridor and before the exit (m)
AREA_CORRIDOR = rectangle((8.0, 4.0), (10.0, 6.0))
AREA_EXIT = rectangle((23.0, 4.0), (25.0, 6.0))
#: a jam: the classic density in a measurement area reaches this (1/m^2; Weidmann's speed
#: has fallen to about half the free speed there)
JAM_DENSITY = 2.0


def _cases_12(quick: bool) -> list[Case]:
    n = 60 if quick else 150
    t_end = 150.0 if quick else 300.0
    return [Case(label, "rimea12_bottleneck", t_end, (("agents.spawn.count", n),) + extra,
                 record_every=2, stop_when_empty=True)
            for label, extra in (("headway", (("flows.headway", {}),)),
                                 ("pure", (("flows.headway", None),)))]


def _jams(tr: Trace) -> tuple[float, float, float, float]:
    """Peak classic density before the corridor and before the exit (1/m^2, PedPy), flows
    out of the corridor and 1 m before the exit (1/s, PedPy's crossings)."""
    before = classic_density(tr.traj, AREA_CORRIDOR)
    after = classic_density(tr.traj, AREA_EXIT)
    return (float(before.max()) if len(before) else 0.0,
            float(after.max()) if len(after) else 0.0,
            line_flow(tr.traj, CORRIDOR_END)["flow"], line_flow(tr.traj, BEFORE_EXIT)["flow"])


def _judge_12(traces: dict[str, list[Trace]], quick: bool) -> Verdict:
    values, checks, flows = [], [], []
    for tr in traces["headway"]:
        before, after, j_corridor, j_exit = _jams(tr)
        values.append(after)
        flows.append((j_corridor, j_exit, before))
        checks.append([ran(tr), all_left(tr),
                       (before >= JAM_DENSITY, f"peak density before the corridor {before:.2f} "
                        f"/m^2, not >= {JAM_DENSITY:g}"),
                       (after < JAM_DENSITY, f"peak density before the exit {after:.2f} /m^2, "
                        f"not < {JAM_DENSITY:g}")])
    pure = [_jams(tr) for tr in traces["pure"]]
    notes = ("peak density before the corridor " + ", ".join(f"{b:.2f}" for _, _, b in flows)
             + "; flows corridor/exit " + ", ".join(f"{a:.2f}/{b:.2f}" for a, b, _ in flows)
             + " 1/s; without a speed law, peak densities corridor/exit "
             + ", ".join(f"{a:.2f}/{b:.2f}" for a, b, _, _ in pure) + " /m^2, flows "
             + ", ".join(f"{c:.2f}/{d:.2f}" for _, _, c, d in pure) + " 1/s")
    return Verdict.judged(values, checks, " /m^2", notes)


TEST_12 = Test(
    "rimea12", "RiMEA 12 bottleneck between two rooms",
    "peak classic density (PedPy) in 2 m x 2 m before the exit, with the speed law",
    f"< {JAM_DENSITY:g} /m^2, and >= {JAM_DENSITY:g} before the corridor",
    _cases_12, _judge_12, source="RiMEA 3.0 test 12 (documentation only in the guideline); "
    "JuPedSim's flows at the corridor's end and 1 m before the exit")
