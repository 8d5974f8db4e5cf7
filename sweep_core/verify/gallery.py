"""The gallery against the experiments: the bundled ``room_door`` and ``bottleneck`` run as
``sweep run NAME --seed S`` runs them (dt 0.01 s, the scene's own crowd), with their speed
law (``flows.headway``).

Flow: the crossings of a line across the door (``room_door``: x = 10 m, 1.2 m wide) or the
corridor's end (``bottleneck``: x = 10 m, 1 m wide), by PedPy's ``compute_n_t`` on the
recorded positions (every 0.1 s), counted from the 10th crossing to the last in a 40 s run
(the first ten are the crowd's front reaching the door): J = (n - 10) / (t_n - t_10), 1/s.
Target: with the speed law, J within 15 % of the experiments' line for the width (the
least-squares line through the points of Seyfried et al. 2009 and Kretz et al. 2006 at
0.8-1.2 m, :func:`sweep_core.verify.diagrams.line_flow_at`) on every seed, and the median
speed of the people within the walking speeds of the field (at most 1.6 m/s; free walking
1.34 m/s in Weidmann's data), each speed the displacement over 1 s between recorded
positions (not a one-step increment, which the noise dominates).
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sweep_core.analysis.speed import WindowSpeeds
from sweep_core.model.gallery import scenes_dir
from sweep_core.model.yaml_files import load_yaml
from sweep_core.verify.base import Case, Test, Trace, Verdict
from sweep_core.verify.diagrams import TARGET, line_flow_at, seyfried
from sweep_core.verify.figures import figure, save

#: scene -> (line across its door or corridor end (two points, m), its width (m))
LINES: dict[str, tuple[tuple[tuple[float, float], tuple[float, float]], float]] = {
    "room_door": (((10.0, 4.4), (10.0, 5.6)), 1.2),
    "bottleneck": (((10.0, 3.5), (10.0, 4.5)), 1.0),
}
LAWS = ("headway", "pure")
#: simulated time (s) of a run, and of a run of ``--quick``
T_END = 40.0
QUICK_T_END = 25.0
#: the time step of ``sweep run`` (s) and the recording interval (steps: frames 0.1 s apart)
DT = 0.01
RECORD_EVERY = 10
#: crossings skipped before the flow is counted (the crowd's front reaching the line)
SKIP = 10
#: the window (s) of a speed: displacement between recorded positions this far apart
WINDOW_S = 1.0
#: the largest median speed (m/s) of walking people (Weidmann: free walking 1.34 m/s)
MAX_MEDIAN_SPEED = 1.6


@dataclass(frozen=True)
class GalleryCase(Case):
    """A bundled gallery scene (``scenes/NAME.yaml``, or NAME.yaml in ``--scenes``) run as
    ``sweep run NAME --seed S`` runs it: its crowd as the file gives it (a spawned crowd keeps
    the file's seed); ``pure``: without ``flows.headway``."""

    pure: bool = False

    def spec(self, seed: int, folder: str | None = None) -> dict:
        path = Path(folder) / f"{self.scene}.yaml" if folder is not None else None
        if path is None or not path.is_file():
            path = scenes_dir() / f"{self.scene}.yaml"
        spec = copy.deepcopy(load_yaml(path.read_text()))
        if self.pure and isinstance(spec.get("flows"), dict):
            spec["flows"].pop("headway", None)
        return spec


def gallery_case(name: str, pure: bool = False, t_end: float = T_END) -> GalleryCase:
    """The run of bundled scene ``name`` the test judges (``pure``: without its speed law)."""
    return GalleryCase(f"{'pure' if pure else 'headway'}/{name}", name, t_end, dt=DT,
                       record_every=RECORD_EVERY, pure=pure)


def _cases(quick: bool) -> list[Case]:
    return [gallery_case(name, t_end=QUICK_T_END if quick else T_END) for name in LINES]


def crossing_times(tr: Trace, line: tuple[tuple[float, float], ...]) -> np.ndarray:
    """Sorted times (s) at which agents first crossed ``line``, by PedPy's ``compute_n_t``."""
    import pedpy

    if not len(tr.traj.frames):
        return np.zeros(0)
    _, crossing = pedpy.compute_n_t(traj_data=tr.traj.to_pedpy(),
                                    measurement_line=pedpy.MeasurementLine(list(line)))
    return np.sort(np.asarray(crossing["frame"], dtype=np.float64)) / tr.traj.frame_rate


def flow(times: np.ndarray) -> float:
    """Flow (1/s) from the ``SKIP``-th crossing to the last: (n - SKIP) / (t_n - t_SKIP);
    NaN with fewer than SKIP + 2 crossings."""
    if len(times) < SKIP + 2 or times[-1] <= times[SKIP - 1]:
        return math.nan
    return (len(times) - SKIP) / float(times[-1] - times[SKIP - 1])


def windowed_speeds(tr: Trace, window: float = WINDOW_S) -> np.ndarray:
    """Every agent's speed (m/s) at each of its frames, as ``sweep analyze`` measures it
    (:class:`~sweep_core.analysis.speed.WindowSpeeds`): its displacement over ``window`` s
    centred on the frame, one-sided at the ends of its presence; frames without a window are
    left out."""
    traj = tr.traj
    ws = WindowSpeeds(window)
    order = np.lexsort((traj.ids, traj.frames))
    frames, ids, xy = traj.frames[order], traj.ids[order], traj.xy[order]
    cuts = np.flatnonzero(np.diff(frames)) + 1
    ready = []
    for f, f_ids, f_xy in zip(frames[np.r_[0, cuts]] if len(frames) else (),
                              np.split(ids, cuts), np.split(xy, cuts)):
        ready += ws.push(float(f) / traj.frame_rate, f_ids, f_xy)
    ready += ws.finish()
    v = np.concatenate([r.speed for r in ready]) if ready else np.zeros(0)
    return v[np.isfinite(v)]


def measure(traces: dict[str, list[Trace]]) -> dict[str, dict[str, list[tuple[float, float]]]]:
    """law -> scene -> [(flow J (1/s), median speed (m/s)) per seed]; NaN for a failed run."""
    out: dict[str, dict[str, list[tuple[float, float]]]] = {law: {} for law in LAWS}
    for label, trs in traces.items():
        law, name = label.split("/", 1)
        row = []
        for tr in trs:
            if tr.error:
                row.append((math.nan, math.nan))
                continue
            v = windowed_speeds(tr)
            row.append((flow(crossing_times(tr, LINES[name][0])),
                        float(np.median(v)) if len(v) else math.nan))
        out[law][name] = row
    return out


def failures(name: str, j: float, median: float, t_end: float) -> list[str]:
    """What fails for one scene and seed (empty: it passes), each naming its condition."""
    width = LINES[name][1]
    ref = line_flow_at(width)
    out = []
    if math.isnan(j):
        out.append(f"{name}: fewer than {SKIP + 2} crossings in {t_end:g} s")
    elif abs(j / ref - 1.0) > TARGET:
        out.append(f"{name}: flow {j:.2f} /s is {100 * (j / ref - 1):+.0f} % from the line's "
                   f"{ref:.2f} /s (allowed {TARGET:.0%})")
    if not median <= MAX_MEDIAN_SPEED:
        out.append(f"{name}: median speed {median:.2f} m/s above {MAX_MEDIAN_SPEED:g} m/s")
    return out


def _judge(traces: dict[str, list[Trace]], quick: bool) -> Verdict:
    m = measure(traces)
    seeds = [tr.seed for tr in next(iter(traces.values()))]
    t_end = QUICK_T_END if quick else T_END
    values, ok, reasons = [], [], []
    for k, seed in enumerate(seeds):
        worst = 0.0
        fails = []
        for name, per_seed in m["headway"].items():
            j, med = per_seed[k]
            e = abs(j / line_flow_at(LINES[name][1]) - 1.0)
            worst = math.nan if math.isnan(e) or math.isnan(worst) else max(worst, e)
            fails += failures(name, j, med, t_end)
        values.append(worst)
        ok.append(not fails)
        reasons += [f"seed {seed}: {f}" for f in fails]

    def row(law: str) -> str:
        return ", ".join(
            f"{name} J {' '.join(f'{j:.2f}' for j, _ in s)} /s, median speed "
            f"{np.nanmedian([v for _, v in s]):.2f} m/s" for name, s in m[law].items())

    notes = (f"runs of {t_end:g} s: {row('headway')}; the experiments' line " + ", ".join(
        f"{name} ({w:g} m) {line_flow_at(w):.2f} /s (Seyfried 2009 {seyfried(w):.2f})"
        for name, (_, w) in LINES.items()))
    if reasons:
        notes += "; failing: " + "; ".join(reasons)
    verdict = Verdict(values, ok, "", notes)
    verdict.figures = {"measured": m}
    return verdict


def _plot(traces: dict[str, list[Trace]], verdict: Verdict, folder: Path) -> list[Path]:
    """Crossings against time per scene and seed, with the experiments' slope (and the
    target's band) through the first seed's 10th crossing."""
    fig, ax = figure(11.0, 4.4)
    ax.remove()
    axes = [fig.add_subplot(1, len(LINES), k + 1) for k in range(len(LINES))]
    for panel, (name, (line, width)) in zip(axes, LINES.items()):
        for law, colour in (("headway", "C0"), ("pure", "C1")):
            for k, tr in enumerate(traces.get(f"{law}/{name}", [])):
                t = crossing_times(tr, line)
                panel.step(t, np.arange(1, len(t) + 1), where="post", color=colour, lw=0.8,
                           label=("speed law, each seed" if law == "headway"
                                  else "pure model, each seed") if k == 0 else None)
                if law == "headway" and k == 0 and len(t) > SKIP:
                    ref = line_flow_at(width)
                    tt = np.linspace(t[SKIP - 1], t[-1], 2)
                    for f, style in ((1.0, "-"), (1 - TARGET, ":"), (1 + TARGET, ":")):
                        panel.plot(tt, SKIP + f * ref * (tt - tt[0]), color="black", ls=style,
                                   lw=1.0, label=(f"experiments' line {ref:.2f} /s, "
                                                  f"+-{TARGET:.0%}") if f == 1.0 else None)
        panel.set_xlabel("time (s)")
        panel.set_ylabel("people crossed")
        panel.set_title(f"{name}: crossings of the {width:g} m line")
        panel.legend(fontsize=8)
    return [save(fig, folder / "gallery_flows.png")]


TEST_GALLERY = Test(
    "gallery", "Gallery flows against the experiments",
    f"largest relative departure of the flow (speed law, {SKIP}th crossing to the last in a "
    f"{T_END:g} s run, {QUICK_T_END:g} s with --quick) through room_door's 1.2 m door and "
    "bottleneck's 1 m corridor from the experiments' line; median speed over 1 s windows",
    f"<= {TARGET:.0%} (target), median speed <= {MAX_MEDIAN_SPEED:g} m/s", _cases, _judge,
    _plot, source="the bundled room_door and bottleneck; Seyfried et al. 2009, Kretz et al. "
    "2006", slow=True)
