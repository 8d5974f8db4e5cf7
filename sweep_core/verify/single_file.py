"""RiMEA 4.x test 16 (documented, no threshold): the single-file fundamental diagram.

A ring corridor 0.5 m wide (inner radius 2.8 m, outer 3.3 m: disks of 0.2 m cannot pass one
another) holds N people walking round it, at line densities N / L of 0.5, 1 and 1.5 per
metre (L = 19.16 m, the circumference at the corridor's middle), with the default speed law
and without it (the pure model). The mean speed along the ring after a 10 s transient is
compared with the single-file experiments of Seyfried et al. (2005), whose data follow
d = a + b v: a person moving at speed v needs the length d = 1 / (line density), a = 0.36 m,
b = 1.06 s, so v = (1 / rho - a) / b, capped by the free speed 1.34 m/s.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from sweep_core.model.ring import ring_corridor
from sweep_core.verify.base import Case, Test, Trace, Verdict
from sweep_core.verify.figures import figure, save

INNER, OUTER = 2.8, 3.3
#: the circumference at the corridor's middle (m)
LENGTH = math.pi * (INNER + OUTER)
LINE_DENSITIES = (0.5, 1.0, 1.5)
QUICK_DENSITIES = (1.0,)
#: Seyfried et al. 2005: the length a person needs at speed v, d = A + B v
A, B = 0.36, 1.06
FREE_SPEED = 1.34
LAWS = ("headway", "pure")


def seyfried_single_file(line_density: np.ndarray | float) -> np.ndarray:
    """Speed (m/s) at a line density (1/m): (1 / rho - A) / B, in [0, FREE_SPEED]."""
    rho = np.asarray(line_density, dtype=np.float64)
    return np.clip((1.0 / rho - A) / B, 0.0, FREE_SPEED)


def _cases(quick: bool) -> list[Case]:
    out = []
    for lam in QUICK_DENSITIES if quick else LINE_DENSITIES:
        # the ring's area is width x LENGTH, so the area density is lam / width
        spec = ring_corridor(lam / (OUTER - INNER), inner=INNER, outer=OUTER)
        spec["noise"] = {"sigma": 0.05}
        for law in LAWS:
            one = dict(spec, flows={"headway": {}}) if law == "headway" else dict(spec)
            out.append(Case(f"{law}/{lam:g}", "single_file", 30.0 if quick else 60.0,
                            inline=one, record_every=5))
    return out


def ring_speed(tr: Trace, since_s: float = 10.0) -> float:
    """Mean speed (m/s) along the ring of every agent after ``since_s``: its angle's advance
    (unwrapped) times its mean radius, over the time."""
    speeds = []
    for agent in np.unique(tr.traj.ids):
        t, xy = tr.positions(int(agent))
        keep = t >= since_s
        if keep.sum() < 2:
            continue
        t, xy = t[keep], xy[keep]
        angle = np.unwrap(np.arctan2(xy[:, 1], xy[:, 0]))
        radius = float(np.hypot(xy[:, 0], xy[:, 1]).mean())
        speeds.append((angle[-1] - angle[0]) * radius / (t[-1] - t[0]))
    return float(np.mean(speeds)) if speeds else math.nan


def _judge(traces: dict[str, list[Trace]], quick: bool) -> Verdict:
    table: dict[str, dict[float, list[float]]] = {law: {} for law in LAWS}
    for label, trs in traces.items():
        law, lam = label.split("/")
        table[law][float(lam)] = [ring_speed(tr) if not tr.error else math.nan for tr in trs]
    n_seeds = len(next(iter(traces.values())))
    values = [max(abs(table["headway"][lam][k] / float(seyfried_single_file(lam)) - 1.0)
                  for lam in table["headway"]) for k in range(n_seeds)]

    def row(law: str) -> str:
        return ", ".join(f"{lam:g}: {np.nanmean(v):.2f}" for lam, v in sorted(table[law].items()))

    notes = (f"speeds (m/s) at line densities (1/m) with the speed law {row('headway')}; pure "
             f"model {row('pure')}; Seyfried 2005 " + ", ".join(
                 f"{lam:g}: {float(seyfried_single_file(lam)):.2f}" for lam in
                 sorted(table["headway"])))
    verdict = Verdict(values, None, "", notes)
    verdict.figures = table
    return verdict


def _plot(traces: dict[str, list[Trace]], verdict: Verdict, folder: Path) -> list[Path]:
    fig, ax = figure()
    lam = np.linspace(0.3, 2.5, 200)
    ax.plot(lam, seyfried_single_file(lam), color="black", label="Seyfried et al. 2005")
    for law, marker in (("headway", "o"), ("pure", "s")):
        pts = [(x, v) for x, vs in verdict.figures[law].items() for v in vs]
        ax.scatter([p[0] for p in pts], [p[1] for p in pts], marker=marker, s=18,
                   label="speed law (csm, defaults)" if law == "headway" else "pure model")
    ax.set_xlabel("line density (1/m)")
    ax.set_ylabel("speed (m/s)")
    ax.set_title("RiMEA 16: single-file fundamental diagram")
    ax.legend(fontsize=8)
    return [save(fig, folder / "rimea16_single_file.png")]


TEST_16 = Test(
    "rimea16", "RiMEA 16 single-file fundamental diagram",
    "largest relative departure of the mean speed (speed law) from Seyfried et al. 2005's "
    "single-file data at 0.5, 1, 1.5 /m (ring corridor 0.5 m wide)",
    "documented (RiMEA sets none)", _cases, _judge, _plot,
    source="RiMEA 4.x test 16; Seyfried, Steffen, Klingsch, Boltes 2005", slow=True)
