"""RiMEA tests 7 (demographic speeds), 9 (a hall left by four doors, then by two) and 15 (a
large crowd round a corner): their runs, verdicts and figures.

Test 7's age groups and speed ranges are the RiMEA guideline's figure of Weidmann's walking
speed against age, read as JuPedSim's RiMEA test 7 reads it (the range of the mean speed over
each age span; people with impairments 0.46-0.76 m/s); its 20-30 years range starts at the
mean at 30 years (1.54 m/s) where JuPedSim's table has 0.58. A measured speed counts as in its
range within 5 %, the speed tolerance of RiMEA test 1.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from sweep_core.verify.base import Case, Test, Trace, Verdict, all_left, ran
from sweep_core.verify.figures import figure, save

# -- test 7 -------------------------------------------------------------------------------------

#: age group -> (min, max) walking speed (m/s)
AGE_GROUPS = {"20-30 years": (1.54, 1.61), "30-50 years": (1.41, 1.54),
              "50-80 years": (0.68, 1.41), "impaired": (0.46, 0.76)}
#: the speed tolerance of RiMEA test 1
TOLERANCE = 0.05


def _cases_7(quick: bool) -> list[Case]:
    return [Case(name, "rimea07_speeds", 60.0,
                 (("flows.speeds", {"distribution": "uniform", "min": lo, "max": hi}),),
                 stop_when_empty=True)
            for name, (lo, hi) in AGE_GROUPS.items()]


def measured_speeds(tr: Trace) -> dict[int, float]:
    """Each agent's speed (m/s): the distance between its first and last recorded centres
    over the time between them (JuPedSim's test 7 does the same)."""
    out = {}
    for i in np.unique(tr.traj.ids):
        t, xy = tr.positions(int(i))
        if len(t) > 1 and t[-1] > t[0]:
            out[int(i)] = float(np.hypot(*(xy[-1] - xy[0])) / (t[-1] - t[0]))
    return out


def _judge_7(traces: dict[str, list[Trace]], quick: bool) -> Verdict:
    n_seeds = len(next(iter(traces.values())))
    values, checks, worst, drawn = [], [], [], []
    for k in range(n_seeds):
        inside = total = 0
        why: list[tuple[bool, str]] = []
        for name, (lo, hi) in AGE_GROUPS.items():
            tr = traces[name][k]
            speeds = measured_speeds(tr)
            v = np.asarray(list(speeds.values()))
            drawn += [abs(s / tr.speeds[i] - 1.0) for i, s in speeds.items() if i in tr.speeds]
            good = (v >= lo * (1 - TOLERANCE)) & (v <= hi * (1 + TOLERANCE))
            inside += int(good.sum())
            total += tr.n0
            why.append(ran(tr))
            why.append((len(v) >= tr.n0, f"{name}: {tr.n0 - len(v)} of {tr.n0} people without "
                        "a measured speed"))
            if len(v):
                out = v[~good]
                why.append((not len(out), f"{name}: {len(out)} speeds outside "
                            f"{lo * (1 - TOLERANCE):.3g}-{hi * (1 + TOLERANCE):.3g} m/s "
                            f"(from {out.min() if len(out) else 0:.3g} to "
                            f"{out.max() if len(out) else 0:.3g})"))
            if len(v):
                worst.append(max(lo - v.min(), v.max() - hi, 0.0) / lo)
        values.append(inside / max(total, 1))
        checks.append(why)  # all hold exactly when every person's speed is in range
    notes = (f"largest departure from a range {max(worst, default=math.nan):.1%}; measured "
             f"against drawn speed: largest difference {max(drawn, default=math.nan):.1%}")
    return Verdict.judged(values, checks, "", notes)


def _plot_7(traces: dict[str, list[Trace]], verdict: Verdict, folder: Path) -> list[Path]:
    fig, ax = figure()
    for j, (name, (lo, hi)) in enumerate(AGE_GROUPS.items()):
        v = np.concatenate([list(measured_speeds(tr).values()) for tr in traces[name]])
        ax.scatter(v, j + 0.3 * (np.random.default_rng(j).random(len(v)) - 0.5), s=6)
        ax.plot([lo, lo], [j - 0.35, j + 0.35], color="red")
        ax.plot([hi, hi], [j - 0.35, j + 0.35], color="red")
    ax.set_yticks(range(len(AGE_GROUPS)), list(AGE_GROUPS))
    ax.set_xlabel("measured walking speed (m/s)")
    ax.set_title("RiMEA 7: measured speeds and the prescribed ranges (red)")
    return [save(fig, folder / "rimea7_speeds.png")]


TEST_7 = Test(
    "rimea7", "RiMEA 7 demographic walking speeds",
    "share of people (4 age groups x 50) whose measured speed lies in their group's range",
    "all (within 5 %)", _cases_7, _judge_7, _plot_7,
    source="RiMEA 3.0 test 7 (Weidmann's speeds against age); JuPedSim's ranges")

# -- test 9 -------------------------------------------------------------------------------------


def _cases_9(quick: bool) -> list[Case]:
    n = 200 if quick else 1000
    t_end = 150.0 if quick else 600.0
    return [Case(label, scene, t_end, (("agents.spawn.count", n),), stop_when_empty=True)
            for label, scene in (("four", "rimea09_hall4"), ("two", "rimea09_hall2"))]


def evacuation_time(tr: Trace) -> float:
    """When the last agent left (s); NaN if some never did."""
    if tr.error or len(tr.left_at) < tr.n0 or not tr.left_at:
        return math.nan
    return max(tr.left_at.values())


def _judge_9(traces: dict[str, list[Trace]], quick: bool) -> Verdict:
    values, checks, times = [], [], []
    for four, two in zip(traces["four"], traces["two"]):
        t4, t2 = evacuation_time(four), evacuation_time(two)
        ratio = t2 / t4 if t4 > 0 else math.nan
        values.append(ratio)
        times.append((t4, t2))
        emptied = [ran(four), ran(two), all_left(four), all_left(two)]
        checks.append(emptied + [(not all(c for c, _ in emptied) or 1.6 <= ratio <= 2.4,
                                  f"ratio {ratio:.3g} outside 1.6-2.4")])
    notes = "evacuation times 4 doors / 2 doors " + ", ".join(
        f"{a:.1f}/{b:.1f} s" for a, b in times)
    stuck = [f"{label} doors, seed {tr.seed}: {remaining(tr)}" for four, two in
             zip(traces["four"], traces["two"]) for label, tr in (("4", four), ("2", two))
             if remaining(tr)]
    if stuck:
        notes += "; not emptied: " + "; ".join(stuck)
    return Verdict.judged(values, checks, "", notes)


def remaining(tr: Trace) -> str:
    """Who never left a run, said plainly ("" if everyone did): the count still inside when
    the run ended, the time of the last departure, and the error if the run failed."""
    if not tr.error and tr.n0 and len(tr.left_at) >= tr.n0:
        return ""
    last = max(tr.left_at.values(), default=0.0)
    out = (f"{tr.n0 - len(tr.left_at)} of {tr.n0} still inside at {tr.t_end:.0f} s, "
           f"the last one out at {last:.1f} s")
    return out + (f" ({tr.error})" if tr.error else "")


def _plot_9(traces: dict[str, list[Trace]], verdict: Verdict, folder: Path) -> list[Path]:
    fig, ax = figure()
    for label, style in (("four", "-"), ("two", "--")):
        for tr in traces[label]:
            t = np.sort(np.asarray(list(tr.left_at.values())))
            ax.step(t, tr.n0 - np.arange(1, len(t) + 1), where="post", ls=style,
                    label=f"{label} doors, seed {tr.seed}")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("people in the hall")
    ax.set_title("RiMEA 9: evacuation curves")
    ax.legend(fontsize=7)
    return [save(fig, folder / "rimea9_evacuation.png")]


TEST_9 = Test(
    "rimea9", "RiMEA 9 hall left by 4 doors, then 2",
    "evacuation time with 2 doors over that with 4 (30 m x 20 m hall, 1000 people)",
    "1.6-2.4", _cases_9, _judge_9, _plot_9,
    source="RiMEA 3.0 test 9; JuPedSim's ratio 1.6-2.4", slow=True)

# -- test 15 ------------------------------------------------------------------------------------


def _cases_15(quick: bool) -> list[Case]:
    n = 100 if quick else 500
    return [Case(label, f"rimea15_{label}", 200.0 if quick else 400.0,
                 (("agents.spawn.count", n),), stop_when_empty=True)
            for label in ("short", "corner", "long")]


def _judge_15(traces: dict[str, list[Trace]], quick: bool) -> Verdict:
    values, checks, times = [], [], []
    for short, corner, long_ in zip(traces["short"], traces["corner"], traces["long"]):
        ts, tc, tl = (evacuation_time(tr) for tr in (short, corner, long_))
        # where the corner lies between the short (0) and the long (1) way
        values.append((tc - ts) / (tl - ts) if tl > ts else math.nan)
        times.append((ts, tc, tl))
        runs = (short, corner, long_)
        emptied = [ran(tr) for tr in runs] + [all_left(tr) for tr in runs]
        checks.append(emptied + [(not all(c for c, _ in emptied) or ts <= tc <= tl,
                                  f"evacuation times short/corner/long {ts:.1f}/{tc:.1f}/"
                                  f"{tl:.1f} s not in that order")])
    notes = "evacuation times short/corner/long " + ", ".join(
        f"{a:.1f}/{b:.1f}/{c:.1f} s" for a, b, c in times)
    return Verdict.judged(values, checks, "", notes)


def _plot_15(traces: dict[str, list[Trace]], verdict: Verdict, folder: Path) -> list[Path]:
    fig, ax = figure()
    for label in ("short", "corner", "long"):
        tr = traces[label][0]
        t = np.sort(np.asarray(list(tr.left_at.values())))
        ax.step(t, np.arange(1, len(t) + 1), where="post", label=label)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("people at the target")
    ax.set_title(f"RiMEA 15: arrivals (seed {traces['short'][0].seed})")
    ax.legend()
    return [save(fig, folder / "rimea15_arrivals.png")]


TEST_15 = Test(
    "rimea15", "RiMEA 15 large crowd round a corner",
    "evacuation time round the corner, as a fraction between the short (0) and the long (1) "
    "straight corridor", "0-1 (between them)", _cases_15, _judge_15, _plot_15,
    source="RiMEA 3.0 test 15; JuPedSim's order short <= corner <= long", slow=True)
